/*
 * The guidance vision_race.c and nn_race.c share (guidance.h; docs/VISION.md
 * "Flying", docs/NN.md "nn-race"). Moved here from vision_race.c unchanged
 * in its order of operations, so the vision race flies as it did.
 */
#include "guidance.h"

#include <stdio.h>

#include "../cosim_regs.h"
#include "../stm32.h"
#include "../vision/gate_detect.h"

/* Nearer than this to its target the drone does not look (mm): the gate
 * fills the view, and the STM32 holds the target for TARGET_CYCLES there. */
#define LOOK_MIN_MM 800
/* The target moves only when the seen gate is this far from it (mm): each
 * SET_TARGET restarts the STM32's TARGET_CYCLES count. */
#define RETARGET_MM 60
/* The turn toward the next waypoint is done within this (mrad), and given
 * up after this many frames (the race controller then turns on the way). */
#define TURN_DONE_MRAD 100
#define TURN_FRAMES_MAX 150
/* A leg that climbs or descends more than LEVEL_DZ_MM first flies to a
 * standoff point on the leg, STANDOFF_MM before the waypoint (at most
 * STANDOFF_PCT % of the leg), at the waypoint's height: from there the
 * gate is approached level, at the camera's height, and seen whole from
 * afar (a climbing approach sees it cut at the top until close, and the
 * pitch of a climbing drone tilts the view). The climb to the standoff
 * keeps at least SLOPE_RUN_PCT % of the height change horizontally (at
 * 25 MHz, a 1.5 m descent over 1.5 m with 38 ms detector frames crashed;
 * docs/VISION.md); a leg too short for that has no standoff. The standoff
 * counts as passed within STANDOFF_DONE_MM, without stopping there. */
#define LEVEL_DZ_MM 500
#define STANDOFF_MM 2500
#define STANDOFF_PCT 60
#define STANDOFF_DONE_MM 300
#define SLOPE_RUN_PCT 150
/* The camera's capture (ms): the platform file's camera read delay,
 * DESIGN.md §5; the clock is calibrated against it. */
#define CAPTURE_MS 16
/* The longest ITER_ADVANCE the STM32 extension takes (ms). */
#define ADVANCE_MAX_MS 240

#define camera_control REG8(CAMERA_CTRL_REG_OFFSET)
#define camera_status REG8(CAMERA_STAT_REG_OFFSET)

#ifdef SHORT_COURSE
const int32_t guidance_waypoint[GUIDANCE_WAYPOINTS][3] = {{-2600, 2000, 1000}, {-2600, 3000, 1000}};
#else
const int32_t guidance_waypoint[GUIDANCE_WAYPOINTS][3] = {
    {-800, 1500, 1000},  {2000, -400, 1000},  {4700, 1700, 1000}, {7700, 3100, 1000},
    {9800, 2000, 1000},  {11300, -3500, 1000}, {9400, -6400, 2150}, {5300, -6500, 3150},
    {1600, -5800, 1650}, {-300, -4700, 1350}, {-2600, 0, 1000},
};
#endif
#define waypoint guidance_waypoint
#define WAYPOINTS GUIDANCE_WAYPOINTS

guidance_stats_t guidance_stats;
#define st guidance_stats

/* Running mean of the accepted sightings of the current gate (mm). */
static int64_t seen_sum[3];
static uint32_t seen_n;
/* Where the approach to the current gate began (mm). */
static int32_t leg_start[3];

static inline uint32_t now(const guidance_config_t *cfg)
{
    uint32_t c;
    if (cfg->time_csr)
        __asm__ volatile("csrr %0, time" : "=r"(c));
    else
        __asm__ volatile("csrr %0, mcycle" : "=r"(c));
    return c;
}

static void get_image(void)
{
    camera_control = GET_IMAGE;
    while (camera_status != GET_IMAGE)
        ;
    camera_status = 0;
    camera_control = 0;
}

static int32_t to_mm(double v) { return (int32_t)(v * 1000.0 + (v < 0 ? -0.5 : 0.5)); }

/* sin and cos of an angle in mrad, Q14 (16384 = 1): the angle folded into
 * [-pi/2, pi/2] and a 7th-order Taylor polynomial (error < 2e-4). */
#define PI_MRAD 3142
int32_t guidance_sin_q14(int32_t a)
{
    while (a > PI_MRAD)
        a -= 2 * PI_MRAD;
    while (a < -PI_MRAD)
        a += 2 * PI_MRAD;
    if (a > PI_MRAD / 2)
        a = PI_MRAD - a;
    else if (a < -PI_MRAD / 2)
        a = -PI_MRAD - a;
    int64_t x = ((int64_t)a << 14) / 1000; /* Q14 rad */
    int64_t x2 = (x * x) >> 14;
    /* x (1 - x^2/6 (1 - x^2/20 (1 - x^2/42))) */
    int64_t t = (1 << 14) - x2 / 42;
    t = (1 << 14) - ((x2 * t) >> 14) / 20;
    t = (1 << 14) - ((x2 * t) >> 14) / 6;
    return (int32_t)((x * t) >> 14);
}
int32_t guidance_cos_q14(int32_t a) { return guidance_sin_q14(a + PI_MRAD / 2); }

/* atan2 in mrad over the whole circle, from the detector's CORDIC (x > 0). */
int32_t guidance_atan2_mrad(int32_t y, int32_t x)
{
    if (x > 0)
        return gate_atan2_mrad(y, x);
    if (y > 0)
        return PI_MRAD / 2 + gate_atan2_mrad(-x, y);
    if (y < 0)
        return gate_atan2_mrad(x, -y) - PI_MRAD / 2;
    return PI_MRAD;
}

/* The estimate (mm, mrad). */
static void estimate(int32_t p[3], int32_t *yaw)
{
    p[0] = to_mm(REGF64(STM32_EST_X_OFFSET));
    p[1] = to_mm(REGF64(STM32_EST_Y_OFFSET));
    p[2] = to_mm(REGF64(STM32_EST_Z_OFFSET));
    *yaw = to_mm(REGF64(STM32_EST_YAW_OFFSET));
}

static void set_target(const int32_t t[3])
{
    stm32_x = t[0] / 1000.0;
    stm32_y = t[1] / 1000.0;
    stm32_z = t[2] / 1000.0;
    stm32_perform(SET_TARGET);
}

static void set_heading(int32_t yaw_mrad)
{
    REGF64(STM32_CMD_YAW_OFFSET) = yaw_mrad / 1000.0;
    (void)stm32_ext(EXT_SET_HEADING);
}

static int64_t dist2(const int32_t a[3], const int32_t b[3])
{
    int64_t dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* The body-frame sighting in the world (mm): R = Rz(yaw) Ry(pitch) Rx(roll),
 * the InertialUnit's angles. Level the camera's view first (a pitched drone
 * sees the gate higher or lower than it is), then rotate by the yaw. */
static void body_to_world(const int32_t body[3], int32_t seen[3])
{
    int32_t p[3], yaw;
    estimate(p, &yaw);
    int32_t roll = to_mm(REGF64(STM32_EST_ROLL_OFFSET));
    int32_t pitch = to_mm(REGF64(STM32_EST_PITCH_OFFSET));
    int64_t sr = guidance_sin_q14(roll), cr = guidance_cos_q14(roll);
    int64_t sp = guidance_sin_q14(pitch), cp = guidance_cos_q14(pitch);
    int64_t bx = body[0], by = body[1], bz = body[2];
    int64_t y1 = (cr * by - sr * bz) >> 14, z1 = (sr * by + cr * bz) >> 14;
    int64_t x2 = (cp * bx + sp * z1) >> 14, z2 = (-sp * bx + cp * z1) >> 14;
    int64_t s = guidance_sin_q14(yaw), co = guidance_cos_q14(yaw);
    seen[0] = p[0] + (int32_t)((x2 * co - y1 * s) >> 14);
    seen[1] = p[1] + (int32_t)((x2 * s + y1 * co) >> 14);
    seen[2] = p[2] + (int32_t)z2;
}

/* The target for a mean sighting: through_mm beyond it, horizontally away
 * from where the approach began (so that the drone's centre crosses the
 * gate's plane even when the sightings place the gate short of it). */
static void through(const guidance_config_t *cfg, const int32_t mean[3], int32_t t[3])
{
    t[0] = mean[0];
    t[1] = mean[1];
    t[2] = mean[2];
    if (cfg->through_mm <= 0)
        return;
    int64_t dx = mean[0] - leg_start[0], dy = mean[1] - leg_start[1];
    int64_t d = gate_isqrt64((uint64_t)(dx * dx + dy * dy));
    if (d <= 0)
        return;
    t[0] += (int32_t)(dx * cfg->through_mm / d);
    t[1] += (int32_t)(dy * cfg->through_mm / d);
}

/* One frame: capture, maybe look, maybe move the target; returns 1 when the
 * STM32 reports the target reached. With steer == 0 (on the way to a
 * standoff point), sightings of gate wp are collected but the target is
 * left alone. */
static int frame_step(const guidance_config_t *cfg, int wp, int32_t target[3], int steer)
{
    uint32_t t0 = now(cfg);
    get_image();
    uint32_t t1 = now(cfg);
    if (st.cycles_per_ms == 0) /* the first capture calibrates the clock */
        st.cycles_per_ms = (t1 - t0) / CAPTURE_MS;
    st.captured++;
    /* Look only while approaching a gate: not while turning toward it
     * (wp < 0), nor within LOOK_MIN_MM of the target. */
    guidance_sighting_t s = {0};
    uint32_t c = 0;
    int look = wp >= 0 && wp < WAYPOINTS - 1 && st.captured % cfg->look_every == 0;
    if (look) {
        int32_t here[3], here_yaw;
        estimate(here, &here_yaw);
        look = dist2(here, target) > (int64_t)LOOK_MIN_MM * LOOK_MIN_MM;
    }
    if (look) {
        cfg->look(wp, &s);
        c = now(cfg) - t1;
        st.looks++;
        st.cycles_sum += c;
        if (c > st.cycles_max)
            st.cycles_max = c;
    }

    int retarget = 0;
    if (s.found) {
        st.found++;
        if (s.usable) {
            int32_t seen[3];
            body_to_world(s.body_mm, seen);
            int32_t dz = seen[2] - waypoint[wp][2];
            int accept = dist2(seen, waypoint[wp]) <= (int64_t)cfg->accept_mm * cfg->accept_mm &&
                         dz < cfg->accept_dz_mm && dz > -cfg->accept_dz_mm;
            /* Temporal gating: a sighting far from the gate tracked so far
             * is a false detection (or another gate), not the gate moving. */
            if (accept && cfg->track_mm > 0 && seen_n >= cfg->track_min) {
                int32_t mean[3];
                for (int k = 0; k < 3; k++)
                    mean[k] = (int32_t)(seen_sum[k] / (int32_t)seen_n);
                if (dist2(seen, mean) > (int64_t)cfg->track_mm * cfg->track_mm) {
                    accept = 0;
                    st.rejected++;
                }
            }
            if (accept) {
                st.used++;
                /* The mean of every accepted sighting of this gate: single
                 * frames carry the attitude of the moment (a tilted camera
                 * moves the gate) and the detector's noise; the mean does
                 * not drift with them. */
                int32_t mean[3], t[3];
                seen_n++;
                for (int k = 0; k < 3; k++) {
                    seen_sum[k] += seen[k];
                    mean[k] = (int32_t)(seen_sum[k] / (int32_t)seen_n);
                }
                through(cfg, mean, t);
                if (steer && dist2(t, target) > (int64_t)RETARGET_MM * RETARGET_MM) {
                    target[0] = t[0];
                    target[1] = t[1];
                    target[2] = t[2];
                    retarget = 1;
                }
            }
        }
    }

    /* The inference time: the detector's cycles at the measured clock,
     * rounded up to whole ms, advance the world (ITER_ADVANCE, in place of
     * race.c's fixed INFERENCE_MS), then the PID step, as in race.c. */
    uint32_t infer_ms = c ? (c + st.cycles_per_ms - 1) / st.cycles_per_ms : 0;
    if (infer_ms > ADVANCE_MAX_MS)
        infer_ms = ADVANCE_MAX_MS;
    st.infer_ms_sum += infer_ms;
    if (infer_ms > 0) {
        stm32_control = (uint8_t)(ITER_ADVANCE + infer_ms);
        while (stm32_status != ITER_ADVANCE)
            ;
        stm32_status = 0;
        stm32_control = 0;
    }
    stm32_control = RUN_SINGLE_STEP_PID;
    uint8_t status;
    while ((status = stm32_status) == 0)
        ;
    stm32_status = 0;
    stm32_control = 0;
    if (status == BATTERY_LOW)
        st.low_battery = 1;
    /* The new target between two frames, as race.c sets its targets: a
     * SET_TARGET inside a frame would split the frame's delays (camera,
     * PID) so that the world may not step between two PID iterations. */
    if (retarget && status != TARGET_REACHED) {
        set_target(target);
        st.retargets++;
#ifdef VISION_TRACE
        printf("%s wp %d target %d %d %d (n %u)\n", cfg->tag, wp + 1, (int)target[0],
               (int)target[1], (int)target[2], (unsigned)seen_n);
#endif
    }
    return status == TARGET_REACHED;
}

void guidance_fly(const guidance_config_t *cfg)
{
    stm32_perform(INIT_PID);
    stm32_perform(GET_STABLE);
    for (int wp = 0; wp < WAYPOINTS && !st.low_battery; wp++) {
        int32_t p[3], yaw, target[3] = {waypoint[wp][0], waypoint[wp][1], waypoint[wp][2]};
        estimate(p, &yaw);
        /* Face the next waypoint (the camera looks along body x): turn on
         * the spot first (holding the last target), then fly. Turning while
         * the race controller accelerates tilts the drone far more than the
         * race does (and a tilted camera misplaces the gate). */
        int32_t heading = guidance_atan2_mrad(target[1] - p[1], target[0] - p[0]);
        set_heading(heading);
        for (int n = 0; n < TURN_FRAMES_MAX && !st.low_battery; n++) {
            int32_t err = heading - yaw;
            while (err > PI_MRAD)
                err -= 2 * PI_MRAD;
            while (err < -PI_MRAD)
                err += 2 * PI_MRAD;
            if (err < TURN_DONE_MRAD && err > -TURN_DONE_MRAD)
                break;
            frame_step(cfg, -1, target, 0);
            estimate(p, &yaw);
        }
        seen_sum[0] = seen_sum[1] = seen_sum[2] = 0;
        seen_n = 0;
        leg_start[0] = p[0];
        leg_start[1] = p[1];
        leg_start[2] = p[2];
        int32_t dz = target[2] - p[2];
        if (dz > LEVEL_DZ_MM || dz < -LEVEL_DZ_MM) {
            int64_t dx = target[0] - p[0], dy = target[1] - p[1];
            int64_t leg = gate_isqrt64((uint64_t)(dx * dx + dy * dy));
            int64_t back = leg * STANDOFF_PCT / 100;
            if (back > STANDOFF_MM)
                back = STANDOFF_MM;
            if (back > leg - (int64_t)(dz < 0 ? -dz : dz) * SLOPE_RUN_PCT / 100)
                back = leg - (int64_t)(dz < 0 ? -dz : dz) * SLOPE_RUN_PCT / 100;
            if (back > 0) {
                int32_t standoff[3] = {target[0] - (int32_t)(dx * back / leg),
                                       target[1] - (int32_t)(dy * back / leg), target[2]};
                set_target(standoff);
                st.standoffs++;
                while (!st.low_battery && !frame_step(cfg, wp, target, 0)) {
                    estimate(p, &yaw);
                    if (dist2(p, standoff) <= (int64_t)STANDOFF_DONE_MM * STANDOFF_DONE_MM)
                        break;
                }
            }
            /* The sightings on the way to the standoff point are the
             * target's first estimate. */
            if (seen_n > 0) {
                int32_t mean[3];
                for (int k = 0; k < 3; k++)
                    mean[k] = (int32_t)(seen_sum[k] / (int32_t)seen_n);
                through(cfg, mean, target);
            }
        }
        set_target(target);
        while (!frame_step(cfg, wp, target, 1) && !st.low_battery)
            ;
        printf("%s waypoint %d reached at %d %d %d mm\n", cfg->tag, wp + 1, (int)target[0],
               (int)target[1], (int)target[2]);
    }
    stm32_perform(GO_DOWN);
}

void guidance_print_simul_time(void)
{
    stm32_control = PRINT_SIMUL_TIME;
    while (stm32_status != PRINT_SIMUL_TIME)
        ;
}
