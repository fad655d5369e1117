/* The coordinate system of seed 003 §5.3.2: see coords.h. */
#include "coords.h"

#include <math.h>

/* Relative tolerance of the triangle inequality before we call the input
 * inconsistent (a clamped square root of a small negative number is only
 * measurement noise). */
#define SLACK 1e-3f

float swarm_vec3_dist(const swarm_vec3_t *a, const swarm_vec3_t *b)
{
    float dx = a->x - b->x, dy = a->y - b->y, dz = a->z - b->z;
    return sqrtf(dx * dx + dy * dy + dz * dz);
}

int swarm_frame_p2(float d12, swarm_vec3_t *p2)
{
    if (!(d12 > 0.0f))
        return SWARM_COORDS_DEGENERATE;
    *p2 = (swarm_vec3_t){d12, 0.0f, 0.0f};
    return SWARM_COORDS_OK;
}

/* sqrt of a square that noise may have pushed below zero. */
static float clamped_sqrt(float sq, float scale2, int *status)
{
    if (sq >= 0.0f)
        return sqrtf(sq);
    if (sq < -SLACK * scale2)
        *status = SWARM_COORDS_INCONSISTENT;
    return 0.0f;
}

int swarm_frame_p3(float d12, float d13, float d23, swarm_vec3_t *p3)
{
    if (!(d12 > 0.0f))
        return SWARM_COORDS_DEGENERATE;
    int status = SWARM_COORDS_OK;
    float x = (d12 * d12 + d13 * d13 - d23 * d23) / (2.0f * d12);
    float y = clamped_sqrt(d13 * d13 - x * x, d13 * d13 + d12 * d12, &status);
    *p3 = (swarm_vec3_t){x, y, 0.0f};
    return status;
}

int swarm_frame_p4(float d12, const swarm_vec3_t *p3, float d14, float d24, float d34,
                   swarm_vec3_t *p4)
{
    /* P3 on the X axis leaves the plane (and so +Z) undefined. */
    if (!(d12 > 0.0f) || !(p3->y > SLACK * d12))
        return SWARM_COORDS_DEGENERATE;
    int status = SWARM_COORDS_OK;
    float x = (d12 * d12 + d14 * d14 - d24 * d24) / (2.0f * d12);
    /* |P4 - P3|² = d34² with P4 = (x, y, z), |P4|² = d14². */
    float y = (d14 * d14 - d34 * d34 + p3->x * p3->x + p3->y * p3->y - 2.0f * p3->x * x) /
              (2.0f * p3->y);
    float z = clamped_sqrt(d14 * d14 - x * x - y * y, d14 * d14 + d12 * d12, &status);
    *p4 = (swarm_vec3_t){x, y, z};
    return status;
}

int swarm_trilaterate(const swarm_vec3_t *ref, const float *dist, int n, int planar,
                      swarm_vec3_t *out)
{
    int dims = planar ? 2 : 3;
    if (n < dims + 1)
        return SWARM_COORDS_DEGENERATE;
    /* Rows: 2(r_i - r_0)·p = d0² - di² + |r_i|² - |r_0|². Accumulate
     * AᵀA and Aᵀb relative to r_0 (better conditioned: p' = p - r_0). */
    float ata[3][3] = {{0}}, atb[3] = {0};
    for (int i = 1; i < n; i++) {
        float a[3] = {ref[i].x - ref[0].x, ref[i].y - ref[0].y, ref[i].z - ref[0].z};
        float r2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        float b = 0.5f * (dist[0] * dist[0] - dist[i] * dist[i] + r2);
        for (int j = 0; j < dims; j++) {
            for (int k = 0; k < dims; k++)
                ata[j][k] += a[j] * a[k];
            atb[j] += a[j] * b;
        }
    }
    float p[3] = {0};
    if (planar) {
        float det = ata[0][0] * ata[1][1] - ata[0][1] * ata[1][0];
        float scale = ata[0][0] * ata[1][1];
        if (!(det > 1e-6f * scale) || scale <= 0.0f)
            return SWARM_COORDS_DEGENERATE;
        p[0] = (atb[0] * ata[1][1] - atb[1] * ata[0][1]) / det;
        p[1] = (ata[0][0] * atb[1] - ata[1][0] * atb[0]) / det;
        p[2] = -ref[0].z;
    } else {
        /* Cramer's rule on the symmetric 3x3 system. */
        float c00 = ata[1][1] * ata[2][2] - ata[1][2] * ata[2][1];
        float c01 = ata[1][2] * ata[2][0] - ata[1][0] * ata[2][2];
        float c02 = ata[1][0] * ata[2][1] - ata[1][1] * ata[2][0];
        float det = ata[0][0] * c00 + ata[0][1] * c01 + ata[0][2] * c02;
        float scale = ata[0][0] * ata[1][1] * ata[2][2];
        if (!(det > 1e-6f * scale) || scale <= 0.0f)
            return SWARM_COORDS_DEGENERATE;
        float c10 = ata[0][2] * ata[2][1] - ata[0][1] * ata[2][2];
        float c11 = ata[0][0] * ata[2][2] - ata[0][2] * ata[2][0];
        float c12 = ata[0][1] * ata[2][0] - ata[0][0] * ata[2][1];
        float c20 = ata[0][1] * ata[1][2] - ata[0][2] * ata[1][1];
        float c21 = ata[0][2] * ata[1][0] - ata[0][0] * ata[1][2];
        float c22 = ata[0][0] * ata[1][1] - ata[0][1] * ata[1][0];
        p[0] = (c00 * atb[0] + c10 * atb[1] + c20 * atb[2]) / det;
        p[1] = (c01 * atb[0] + c11 * atb[1] + c21 * atb[2]) / det;
        p[2] = (c02 * atb[0] + c12 * atb[1] + c22 * atb[2]) / det;
    }
    *out = (swarm_vec3_t){p[0] + ref[0].x, p[1] + ref[0].y, p[2] + ref[0].z};
    if (planar)
        out->z = 0.0f;
    return SWARM_COORDS_OK;
}
