/*
 * Flying the race on what the camera sees (docs/VISION.md, docs/NN.md
 * "nn-race"): the guidance vision_race.c and nn_race.c share. The course is
 * race.c's (Appendix D's waypoints); for each gate the drone turns on the
 * spot to face it (EXT_SET_HEADING), lines up level with a climbing or
 * descending gate at a standoff point, then flies to it while a detector
 * looks: every accepted sighting of the gate (within accept_mm of its
 * nominal waypoint) joins the running mean that is the STM32's target. The
 * detector is the caller's (`look`); its time, rounded up to whole ms, is
 * the ITER_ADVANCE the world advances by before each PID step.
 *
 * Integer arithmetic (mm, mrad); only the STM32's registers are doubles.
 */
#ifndef GUIDANCE_H
#define GUIDANCE_H

#include <stdint.h>

/* Appendix D's waypoints (race.c), mm; the last one is the start (no gate).
 * -DSHORT_COURSE (tests): one gate's waypoint 2 m ahead of the start, then
 * a point 1 m beyond it. */
#ifdef SHORT_COURSE
#define GUIDANCE_WAYPOINTS 2
#else
#define GUIDANCE_WAYPOINTS 11
#endif
extern const int32_t guidance_waypoint[GUIDANCE_WAYPOINTS][3];

/* What the detector made of the frame just captured. */
typedef struct {
    /* It reports a gate at all (counted as `found`). */
    int found;
    /* ... and one the guidance may use (its own checks passed). */
    int usable;
    /* The gate's centre in the body frame: x forward, y left, z up (mm). */
    int32_t body_mm[3];
} guidance_sighting_t;

typedef struct {
    /* Runs the detector on the frame the camera holds (wp: the gate being
     * approached); fills `s`. */
    void (*look)(int wp, guidance_sighting_t *s);
    /* The clock the detector's time is measured on, calibrated against the
     * camera's 16 ms capture: 0 mcycle (the core's awake cycles: a detector
     * on the FC), 1 the time CSR (cycles asleep too: the FC waiting for the
     * cluster). */
    int time_csr;
    /* Look on every look_every-th frame. */
    int look_every;
    /* A sighting is the next gate within this of its nominal waypoint (mm),
     * and within accept_dz_mm above or below it. */
    int32_t accept_mm, accept_dz_mm;
    /* Temporal gating (0: off): once track_min sightings of a gate were
     * accepted, one farther than track_mm from their mean is rejected. */
    int32_t track_mm;
    uint32_t track_min;
    /* The target lies this far beyond the gate's mean sighting, along the
     * horizontal line from where the approach began (0: at the gate). */
    int32_t through_mm;
    /* The console lines' prefix, e.g. "[vision]". */
    const char *tag;
} guidance_config_t;

/* What the flight did, for the caller's report. */
typedef struct {
    uint32_t captured, looks, found, used, rejected, retargets, standoffs, infer_ms_sum;
    /* The detector's time (the clock above): sum and maximum per look. */
    uint64_t cycles_sum;
    uint32_t cycles_max;
    /* The clock's cycles per ms (from the first capture). */
    uint32_t cycles_per_ms;
    /* BATTERY_LOW was reported. */
    int low_battery;
} guidance_stats_t;

extern guidance_stats_t guidance_stats;

/* INIT_PID, GET_STABLE, the course, GO_DOWN. */
void guidance_fly(const guidance_config_t *cfg);

/* atan2 in mrad over the whole circle; sin and cos of mrad in Q14. */
int32_t guidance_atan2_mrad(int32_t y, int32_t x);
int32_t guidance_sin_q14(int32_t a);
int32_t guidance_cos_q14(int32_t a);

/* The end of a run: PRINT_SIMUL_TIME, answered by the STM32. */
void guidance_print_simul_time(void);

#endif
