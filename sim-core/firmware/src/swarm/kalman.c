/* The position Kalman filter of seed 003 §6.8: see kalman.h. */
#include "kalman.h"

#include <math.h>

#define N SWARM_KF_DIM

void swarm_kf_init(swarm_kf_t *kf, const swarm_vec3_t *pos, float pos_std, float vel_std,
                   uint32_t now_us)
{
    for (int i = 0; i < N; i++) {
        kf->x[i] = 0.0f;
        for (int j = 0; j < N; j++)
            kf->P[i][j] = 0.0f;
    }
    kf->x[0] = pos->x;
    kf->x[1] = pos->y;
    kf->x[2] = pos->z;
    for (int i = 0; i < 3; i++) {
        kf->P[i][i] = pos_std * pos_std;
        kf->P[i + 3][i + 3] = vel_std * vel_std;
    }
    kf->last_us = now_us;
    kf->updates = 0;
    kf->coupled = 0;
    kf->provisional = 0;
    kf->init = 1;
}

static float clampf(float v, float lim)
{
    return v > lim ? lim : v < -lim ? -lim : v;
}

/* Bounds of the state and a non-negative variance diagonal (rounding). */
static void bound(swarm_kf_t *kf, int n, const swarm_kf_settings_t *s)
{
    for (int i = 0; i < n; i++) {
        kf->x[i] = clampf(kf->x[i], i < 3 ? s->max_position : s->max_velocity);
        if (kf->P[i][i] < 0.0f)
            kf->P[i][i] = 0.0f;
    }
}

void swarm_kf_advance(swarm_kf_t *kf, uint32_t now_us, const swarm_kf_settings_t *s)
{
    float dt = (float)(uint32_t)(now_us - kf->last_us) * 1e-6f;
    kf->last_us = now_us;
    if (!(dt > 0.0f))
        return;
    if (s->prediction) {
        /* x = F x with F = [I dt·I; 0 I]; P = F P Fᵀ. */
        for (int i = 0; i < 3; i++)
            kf->x[i] += kf->x[i + 3] * dt;
        /* P ← F P: rows of position gain dt·(velocity rows). */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < N; j++)
                kf->P[i][j] += dt * kf->P[i + 3][j];
        /* P ← P Fᵀ: columns likewise. */
        for (int i = 0; i < N; i++)
            for (int j = 0; j < 3; j++)
                kf->P[i][j] += dt * kf->P[i][j + 3];
        /* Position and velocity are now correlated. */
        kf->coupled = 1;
    }
    /* Covariance correction: process noise, a random walk of both. */
    for (int i = 0; i < 3; i++) {
        kf->P[i][i] += s->process_noise_pos * dt;
        kf->P[i + 3][i + 3] += s->process_noise_vel * dt;
    }
    bound(kf, N, s);
}

/* Scalar update with measurement row h (non-zero on the position only),
 * innovation `inn` and variance r. Until a prediction step has correlated
 * them, the velocity states have no covariance with the position, so the
 * update touches the 3x3 position block only (exactly the same result, a
 * quarter of the soft-float work). */
static int update(swarm_kf_t *kf, const float h[3], float inn, float r,
                  const swarm_kf_settings_t *s)
{
    int n = kf->coupled ? N : 3;
    float ph[N];
    for (int i = 0; i < n; i++)
        ph[i] = kf->P[i][0] * h[0] + kf->P[i][1] * h[1] + kf->P[i][2] * h[2];
    float hph = h[0] * ph[0] + h[1] * ph[1] + h[2] * ph[2];
    float sv = hph + r;
    if (!(sv > 1e-12f))
        return 0;
    float inv = 1.0f / sv;
    float k[N];
    for (int i = 0; i < n; i++) {
        k[i] = ph[i] * inv;
        kf->x[i] += k[i] * inn;
    }
    /* P ← P - K (P h)ᵀ = P - (P h)(P h)ᵀ / S: symmetric, so compute one
     * triangle and mirror it. */
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++)
            kf->P[j][i] = kf->P[i][j] = kf->P[i][j] - k[i] * ph[j];
    if (kf->updates < UINT16_MAX)
        kf->updates++;
    bound(kf, n, s);
    return 1;
}

int swarm_kf_update_distance(swarm_kf_t *kf, const swarm_vec3_t *from, float dist, float std,
                             const swarm_kf_settings_t *s)
{
    float d[3] = {kf->x[0] - from->x, kf->x[1] - from->y, kf->x[2] - from->z};
    float pred = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    float h[3];
    if (pred > 1e-4f) {
        for (int i = 0; i < 3; i++)
            h[i] = d[i] / pred;
    } else {
        /* On top of the other point the direction is undefined (the
         * §6.8.3 start at (0, 0, 0) next to a reference at the origin):
         * take the one of largest uncertainty. */
        int a = 0;
        for (int i = 1; i < 3; i++)
            if (kf->P[i][i] > kf->P[a][a])
                a = i;
        h[0] = h[1] = h[2] = 0.0f;
        h[a] = 1.0f;
    }
    return update(kf, h, dist - pred, std * std, s);
}

int swarm_kf_update_axis(swarm_kf_t *kf, int axis, float value, float std,
                         const swarm_kf_settings_t *s)
{
    float h[3] = {0.0f, 0.0f, 0.0f};
    h[axis] = 1.0f;
    return update(kf, h, value - kf->x[axis], std * std, s);
}

void swarm_kf_mirror(swarm_kf_t *kf, int axis)
{
    /* x' = M x with M = diag(..., -1 on the axis and its velocity, ...):
     * P' = M P M flips the sign of the cross terms of those two states. */
    int flip[2] = {axis, axis + 3};
    for (int f = 0; f < 2; f++) {
        int a = flip[f];
        kf->x[a] = -kf->x[a];
        for (int j = 0; j < N; j++) {
            kf->P[a][j] = -kf->P[a][j];
            kf->P[j][a] = -kf->P[j][a];
        }
    }
}

swarm_vec3_t swarm_kf_position(const swarm_kf_t *kf)
{
    return (swarm_vec3_t){kf->x[0], kf->x[1], kf->x[2]};
}

float swarm_kf_position_std(const swarm_kf_t *kf)
{
    float m = kf->P[0][0];
    if (kf->P[1][1] > m)
        m = kf->P[1][1];
    if (kf->P[2][2] > m)
        m = kf->P[2][2];
    return sqrtf(m);
}

int swarm_kf_is_stable(const swarm_kf_t *kf, float max_std)
{
    /* On the variances: no square root (350 cycles in soft-float), and it
     * is asked for every node at every packet. */
    float v = max_std * max_std;
    return kf->init && kf->P[0][0] < v && kf->P[1][1] < v && kf->P[2][2] < v;
}
