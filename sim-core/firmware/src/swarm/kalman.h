/*
 * The position Kalman filter of seed 003 §6.8, one instance per node
 * ("non-static": the storage is passed to every function, §6.8.1).
 *
 * State: position and velocity (the X, Y, Z, PX, PY, PZ of the
 * Crazyflie's estimator, Code Block B.2); the attitude errors D0-D2 and the
 * IMU inputs are left out as §6.8.1 does for the non-static filter (the
 * own-position "static" filter of the thesis is coupled to the IMU; here
 * it is one more instance of this engine, see swarm.h).
 *
 *  - covariance correction (§6.8.2): P grows by process noise with the
 *    time since the last update, the only step run by default;
 *  - prediction (§6.8.2): x += v·dt, P = F P Fᵀ; optional, off by default,
 *    since the seed shows it makes the swarm drift;
 *  - update: a scalar EKF update with a measured distance to a point, or
 *    with one coordinate (the "arbitrary values" of §6.8.4 that hold a
 *    coordinate system under construction);
 *  - stabilisation (§6.8.3): started at a given point with a large σ, a
 *    filter's position is used only once its σ is below a threshold.
 *
 * Single precision, soft-float on RV32IMC (the Crazyflie's filter is
 * single precision too); its cost is measured in docs/SWARM_FIRMWARE.md.
 */
#ifndef SWARM_KALMAN_H
#define SWARM_KALMAN_H

#include <stdint.h>

#include "coords.h"

#define SWARM_KF_DIM 6

typedef struct {
    float x[SWARM_KF_DIM];                /* x y z vx vy vz (m, m/s) */
    float P[SWARM_KF_DIM][SWARM_KF_DIM];  /* covariance */
    uint32_t last_us;                     /* time of the last covariance correction */
    uint16_t updates;                     /* measurement updates since init */
    uint8_t init;
    uint8_t coupled; /* a prediction step has correlated position and velocity */
    uint8_t provisional; /* started from nodes not yet placed (swarm.c) */
} swarm_kf_t;

typedef struct {
    float process_noise_pos; /* m²/s added to each position variance */
    float process_noise_vel; /* (m/s)²/s added to each velocity variance */
    float max_position;      /* |x|, |y|, |z| are clamped to this (m) */
    float max_velocity;      /* |v| clamped (m/s) */
    uint8_t prediction;      /* run the prediction step */
} swarm_kf_settings_t;

void swarm_kf_init(swarm_kf_t *kf, const swarm_vec3_t *pos, float pos_std, float vel_std,
                   uint32_t now_us);
/* Covariance correction (and prediction when enabled) up to now_us. */
void swarm_kf_advance(swarm_kf_t *kf, uint32_t now_us, const swarm_kf_settings_t *s);
/* Distance update; returns 1 if applied (0 when σ and the variance along
 * the measurement are both zero). */
int swarm_kf_update_distance(swarm_kf_t *kf, const swarm_vec3_t *from, float dist, float std,
                             const swarm_kf_settings_t *s);
/* One coordinate (axis 0, 1, 2) measured as `value`. */
int swarm_kf_update_axis(swarm_kf_t *kf, int axis, float value, float std,
                         const swarm_kf_settings_t *s);
/* Mirror one coordinate of the state (x → -x on that axis), used to keep a
 * reference on the positive side of its axis (§5.3.2). */
void swarm_kf_mirror(swarm_kf_t *kf, int axis);
swarm_vec3_t swarm_kf_position(const swarm_kf_t *kf);
/* The largest of the three position standard deviations. */
float swarm_kf_position_std(const swarm_kf_t *kf);
/* §6.8.3: initialised and every position σ below max_std. */
int swarm_kf_is_stable(const swarm_kf_t *kf, float max_std);

#endif
