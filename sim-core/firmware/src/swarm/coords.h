/*
 * The coordinate system of seed 003 §5.3.2, built from distances alone:
 *   P1 = (0, 0, 0)                the first detected neighbour (origin)
 *   P2 = (d12, 0, 0)              the second: the X axis and its direction
 *   P3 = (dx, dy, 0), dy > 0      the third: the XY plane and +Y
 *   P4 = (dx, dy, dz), dz > 0     the fourth: +Z
 * and the trilateration of any further point from the points already
 * placed (eq. 5.2: N + 1 points in N dimensions).
 *
 * Single precision (soft-float on RV32IMC): centimetre-level inputs need
 * nothing more; the squares of distances up to 10 m keep 7 digits.
 */
#ifndef SWARM_COORDS_H
#define SWARM_COORDS_H

typedef struct {
    float x, y, z;
} swarm_vec3_t;

enum {
    SWARM_COORDS_OK = 0,
    SWARM_COORDS_DEGENERATE = -1, /* coincident / collinear / coplanar references */
    SWARM_COORDS_INCONSISTENT = -2, /* distances violate the triangle inequality
                                      beyond rounding: the result was clamped */
};

/* P2 from d12 (> 0). */
int swarm_frame_p2(float d12, swarm_vec3_t *p2);
/* P3 from d12, d13, d23: the 2D trilateration from P1 and P2 with dy ≥ 0. */
int swarm_frame_p3(float d12, float d13, float d23, swarm_vec3_t *p3);
/* P4 from P3 (as computed above) and d12, d14, d24, d34: the 3D
 * trilateration from P1, P2, P3 with dz ≥ 0. */
int swarm_frame_p4(float d12, const swarm_vec3_t *p3, float d14, float d24, float d34,
                   swarm_vec3_t *p4);

/* Least-squares trilateration of a point from n ≥ 4 references (n ≥ 3 and
 * z = 0 when `planar`), by the usual linearisation (subtracting the first
 * sphere's equation from the others) and the normal equations. */
int swarm_trilaterate(const swarm_vec3_t *ref, const float *dist, int n, int planar,
                      swarm_vec3_t *out);

float swarm_vec3_dist(const swarm_vec3_t *a, const swarm_vec3_t *b);

#endif
