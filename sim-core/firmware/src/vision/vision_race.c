/*
 * The race with vision in the loop (issue 13, DESIGN.md §10, docs/VISION.md):
 * race.c's course, but the GAP8 looks. For every frame it copies the image
 * into L2, runs the gate detector (gate_detect.c, integer arithmetic) and
 * steers: the drone turns to face the next waypoint (EXT_SET_HEADING; the
 * thesis's race holds +y and never sees most gates), and the STM32's target
 * moves to the gate it sees when the gate is where the course says one
 * should be (within ACCEPT_MM of the nominal waypoint), the nominal waypoint
 * otherwise.
 *
 * No fixed inference delay: the detector's cycles (mcycle around the copy
 * and gate_detect) at the platform clock, rounded up to whole ms, are the
 * inference time that ITER_ADVANCE gives the world, where race.c advances a
 * fixed INFERENCE_MS = 10. The clock is measured against the camera's 16 ms
 * capture (cycles per ms), as firmware calibrates against a timer, so the
 * same ELF runs at any core frequency of the platform file.
 *
 * Integer arithmetic throughout the vision and steering code (mm, mrad);
 * only the STM32's registers are doubles (converted at the boundary).
 */
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../stm32.h"
#include "gate_detect.h"

/* A detection is the next gate when it lies within this of its nominal
 * waypoint (perturbed courses move gates by up to 0.4 m sideways and
 * 0.2 m vertically: 0.45 m; plus the detector's error at 4 m, 6 cm). */
#ifndef ACCEPT_MM
#define ACCEPT_MM 700
#endif
/* Detections are trusted from this range in (mm): farther the depth error
 * grows as Z^2 (docs/VISION.md, Accuracy). */
#define MAX_RANGE_MM 4500
/* Nearer than this the opening fills the view: keep the last target. */
#define MIN_RANGE_MM 700
/* The detector runs only while the drone is farther than this from its
 * target (mm). */
#define LOOK_MIN_MM 800
/* ... and on every LOOK_EVERY-th frame (about 100 ms apart at 3: the
 * target moves by centimetres between looks; it keeps the ISS's work, and
 * the run's wall time, within twice the race's). */
#ifndef LOOK_EVERY
#define LOOK_EVERY 5
#endif
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
/* A seen gate is accepted only this far above or below its waypoint (mm):
 * a pitched camera moves the gate vertically first. */
#define ACCEPT_DZ_MM 300

#define camera_control REG8(CAMERA_CTRL_REG_OFFSET)
#define camera_status REG8(CAMERA_STAT_REG_OFFSET)

/* Appendix D's waypoints (race.c), mm; the last one is the start (no gate).
 * -DSHORT_COURSE (tests): one gate's waypoint 2 m ahead of the start, then
 * a point 1 m beyond it. */
#ifdef SHORT_COURSE
#define WAYPOINTS 2
static const int32_t waypoint[WAYPOINTS][3] = {{-2600, 2000, 1000}, {-2600, 3000, 1000}};
#else
#define WAYPOINTS 11
static const int32_t waypoint[WAYPOINTS][3] = {
    {-800, 1500, 1000},  {2000, -400, 1000},  {4700, 1700, 1000}, {7700, 3100, 1000},
    {9800, 2000, 1000},  {11300, -3500, 1000}, {9400, -6400, 2150}, {5300, -6500, 3150},
    {1600, -5800, 1650}, {-300, -4700, 1350}, {-2600, 0, 1000},
};
#endif

static uint8_t frame[GATE_IMAGE_WIDTH * GATE_IMAGE_HEIGHT] __attribute__((aligned(4)));
static const gate_config_t cfg = GATE_CONFIG_DEFAULT;

static int low_battery;
/* Running mean of the accepted detections of the current gate (mm). */
static int64_t seen_sum[3];
static uint32_t seen_n;
static uint32_t cycles_per_ms;

/* Per-frame figures. */
static uint32_t captured, frames, frames_found, frames_used, retargets, standoffs, infer_ms_sum;
static uint64_t cycles_sum;
static uint32_t cycles_max;

static inline uint32_t mcycle(void)
{
    uint32_t c;
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

/* The image into L2, a word at a time (the window composes unaligned words
 * from bytes, docs/VISION.md "What the flight integration needs" 1). */
static void copy_frame(void)
{
    const volatile uint8_t *src = &REG8(CAMERA_IMAGE_OFFSET);
    uint32_t *dst = (uint32_t *)frame;
    for (int i = 0; i < GATE_IMAGE_WIDTH * GATE_IMAGE_HEIGHT / 4; i++)
        dst[i] = *(const volatile uint32_t *)(src + 4 * i);
}

static int32_t to_mm(double v) { return (int32_t)(v * 1000.0 + (v < 0 ? -0.5 : 0.5)); }

/* sin and cos of an angle in mrad, Q14 (16384 = 1): the angle folded into
 * [-pi/2, pi/2] and a 7th-order Taylor polynomial (error < 2e-4). */
#define PI_MRAD 3142
static int32_t sin_q14(int32_t a)
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
static int32_t cos_q14(int32_t a) { return sin_q14(a + PI_MRAD / 2); }

/* atan2 in mrad over the whole circle, from the detector's CORDIC (x > 0). */
static int32_t atan2_mrad(int32_t y, int32_t x)
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

/* One frame: capture, detect, maybe move the target; returns 1 when the
 * STM32 reports the target reached. With steer == 0 (on the way to a
 * standoff point), sightings of gate wp are collected but the target is
 * left alone. */
static int frame_step(int wp, int32_t target[3], int steer)
{
    uint32_t t0 = mcycle();
    get_image();
    uint32_t t1 = mcycle();
    if (cycles_per_ms == 0) /* the first capture calibrates the clock */
        cycles_per_ms = (t1 - t0) / 16;
    captured++;
    /* Look only while approaching a gate: not while turning toward it
     * (wp < 0), nor within LOOK_MIN_MM of the target (the gate fills the
     * view, and the STM32 holds the target for TARGET_CYCLES there). */
    gate_result_t r = {0};
    uint32_t c = 0;
    int look = wp >= 0 && wp < WAYPOINTS - 1 && captured % LOOK_EVERY == 0;
    if (look) {
        int32_t here[3], here_yaw;
        estimate(here, &here_yaw);
        look = dist2(here, target) > (int64_t)LOOK_MIN_MM * LOOK_MIN_MM;
    }
    if (look) {
        copy_frame();
        gate_detect(frame, &cfg, &r);
        c = mcycle() - t1;
        frames++;
        cycles_sum += c;
        if (c > cycles_max)
            cycles_max = c;
    }

    int retarget = 0;
    if (r.found) {
        frames_found++;
        /* Only openings seen whole: a cut edge is estimated assuming the
         * gate faces the camera, which drifts on an oblique gate. */
        int usable = wp >= 0 && wp < WAYPOINTS - 1 && r.flags == 0 && r.confidence >= 50 &&
                     r.range_mm >= MIN_RANGE_MM && r.range_mm <= MAX_RANGE_MM;
        if (usable) {
            int32_t p[3], yaw;
            estimate(p, &yaw);
            /* Body to world (R = Rz(yaw) Ry(pitch) Rx(roll), the
             * InertialUnit's angles): level the camera's view first (a
             * pitched drone sees the gate higher or lower than it is), then
             * rotate by the yaw. */
            int32_t roll = to_mm(REGF64(STM32_EST_ROLL_OFFSET));
            int32_t pitch = to_mm(REGF64(STM32_EST_PITCH_OFFSET));
            int64_t sr = sin_q14(roll), cr = cos_q14(roll);
            int64_t sp = sin_q14(pitch), cp = cos_q14(pitch);
            int64_t bx = r.body_x_mm, by = r.body_y_mm, bz = r.body_z_mm;
            int64_t y1 = (cr * by - sr * bz) >> 14, z1 = (sr * by + cr * bz) >> 14;
            int64_t x2 = (cp * bx + sp * z1) >> 14, z2 = (-sp * bx + cp * z1) >> 14;
            int64_t s = sin_q14(yaw), co = cos_q14(yaw);
            int32_t seen[3] = {
                p[0] + (int32_t)((x2 * co - y1 * s) >> 14),
                p[1] + (int32_t)((x2 * s + y1 * co) >> 14),
                p[2] + (int32_t)z2,
            };
            int32_t dz = seen[2] - waypoint[wp][2];
            if (dist2(seen, waypoint[wp]) <= (int64_t)ACCEPT_MM * ACCEPT_MM &&
                dz < ACCEPT_DZ_MM && dz > -ACCEPT_DZ_MM) {
                frames_used++;
                /* The mean of every accepted sighting of this gate: single
                 * frames carry the attitude of the moment (a tilted camera
                 * moves the gate), the mean does not drift with it. */
                int32_t mean[3];
                seen_n++;
                for (int k = 0; k < 3; k++) {
                    seen_sum[k] += seen[k];
                    mean[k] = (int32_t)(seen_sum[k] / (int32_t)seen_n);
                }
                if (steer && dist2(mean, target) > (int64_t)RETARGET_MM * RETARGET_MM) {
                    target[0] = mean[0];
                    target[1] = mean[1];
                    target[2] = mean[2];
                    retarget = 1;
                }
            }
        }
    }

    /* The inference time: the detector's cycles at the platform clock,
     * rounded up to whole ms, advance the world (ITER_ADVANCE, in place of
     * race.c's fixed INFERENCE_MS), then the PID step, as in race.c. */
    uint32_t infer_ms = c ? (c + cycles_per_ms - 1) / cycles_per_ms : 0;
    if (infer_ms > 240)
        infer_ms = 240;
    infer_ms_sum += infer_ms;
    if (infer_ms > 0) {
        stm32_control = (uint8_t)(ITER_ADVANCE + infer_ms);
        while (stm32_status != ITER_ADVANCE)
            ;
        stm32_status = 0;
        stm32_control = 0;
    }
    stm32_control = RUN_SINGLE_STEP_PID;
    uint8_t st;
    while ((st = stm32_status) == 0)
        ;
    stm32_status = 0;
    stm32_control = 0;
    if (st == BATTERY_LOW)
        low_battery = 1;
    /* The new target between two frames, as race.c sets its targets: a
     * SET_TARGET inside a frame would split the frame's delays (camera,
     * PID) so that the world may not step between two PID iterations. */
    if (retarget && st != TARGET_REACHED) {
        set_target(target);
        retargets++;
#ifdef VISION_TRACE
        printf("[vision] wp %d target %d %d %d (n %u)\n", wp + 1, (int)target[0], (int)target[1],
               (int)target[2], (unsigned)seen_n);
#endif
    }
    return st == TARGET_REACHED;
}

int main(void)
{
    printf("[vision] race with the gate detector in the loop\n");
    stm32_perform(INIT_PID);
    stm32_perform(GET_STABLE);
    for (int wp = 0; wp < WAYPOINTS && !low_battery; wp++) {
        int32_t p[3], yaw, target[3] = {waypoint[wp][0], waypoint[wp][1], waypoint[wp][2]};
        estimate(p, &yaw);
        /* Face the next waypoint (the camera looks along body x): turn on
         * the spot first (holding the last target), then fly. Turning while
         * the race controller accelerates tilts the drone far more than the
         * race does (and a tilted camera misplaces the gate). */
        int32_t heading = atan2_mrad(target[1] - p[1], target[0] - p[0]);
        set_heading(heading);
        for (int n = 0; n < TURN_FRAMES_MAX && !low_battery; n++) {
            int32_t err = heading - yaw;
            while (err > PI_MRAD)
                err -= 2 * PI_MRAD;
            while (err < -PI_MRAD)
                err += 2 * PI_MRAD;
            if (err < TURN_DONE_MRAD && err > -TURN_DONE_MRAD)
                break;
            frame_step(-1, target, 0);
            estimate(p, &yaw);
        }
        seen_sum[0] = seen_sum[1] = seen_sum[2] = 0;
        seen_n = 0;
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
                standoffs++;
                while (!low_battery && !frame_step(wp, target, 0)) {
                    estimate(p, &yaw);
                    if (dist2(p, standoff) <= (int64_t)STANDOFF_DONE_MM * STANDOFF_DONE_MM)
                        break;
                }
            }
            /* The sightings on the way to the standoff point are the
             * target's first estimate. */
            if (seen_n > 0)
                for (int k = 0; k < 3; k++)
                    target[k] = (int32_t)(seen_sum[k] / (int32_t)seen_n);
        }
        set_target(target);
        while (!frame_step(wp, target, 1) && !low_battery)
            ;
        printf("[vision] waypoint %d reached at %d %d %d mm\n", wp + 1, (int)target[0],
               (int)target[1], (int)target[2]);
    }
    stm32_perform(GO_DOWN);
    uint32_t mean = frames ? (uint32_t)(cycles_sum / frames) : 0;
    printf("[vision] captured %u, detector frames %u, gate found in %u, used in %u, retargets %u, inference %u ms\n",
           (unsigned)captured, (unsigned)frames, (unsigned)frames_found, (unsigned)frames_used, (unsigned)retargets,
           (unsigned)infer_ms_sum);
    /* SET_TARGETs: one per waypoint, one per standoff point, one per
     * retarget (the STM32 counts the last two as replaced). */
    printf("[vision] waypoints %d, standoff points %u, target moves %u\n", WAYPOINTS, (unsigned)standoffs,
           (unsigned)retargets);
    printf("[vision] cycles per frame (copy + detect): mean %u, max %u; clock %u cycles/ms\n",
           (unsigned)mean, (unsigned)cycles_max, (unsigned)cycles_per_ms);
    stm32_control = PRINT_SIMUL_TIME;
    while (stm32_status != PRINT_SIMUL_TIME)
        ;
    return 0;
}
