/*
 * The race with vision in the loop (DESIGN.md §10, docs/VISION.md):
 * race.c's course, but the GAP8 looks. For every frame it copies the image
 * into L2, runs the gate detector (gate_detect.c, integer arithmetic) and
 * steers: the drone turns to face the next waypoint (EXT_SET_HEADING; the
 * thesis's race holds +y and never sees most gates), and the STM32's target
 * moves to the gate it sees when the gate is where the course says one
 * should be (within ACCEPT_MM of the nominal waypoint), the nominal waypoint
 * otherwise. The flying is ../guidance/guidance.c's (shared with the
 * network's race, nn/nn_race.c); this file is the detector's side.
 *
 * No fixed inference delay: the detector's cycles (mcycle around the copy
 * and gate_detect) at the platform clock, rounded up to whole ms, are the
 * inference time that ITER_ADVANCE gives the world, where race.c advances a
 * fixed INFERENCE_MS = 10. The clock is measured against the camera's 16 ms
 * capture (cycles per ms), as firmware calibrates against a timer, so the
 * same ELF runs at any core frequency of the platform file.
 */
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../guidance/guidance.h"
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
/* The detector runs on every LOOK_EVERY-th frame (about 100 ms apart at 3:
 * the target moves by centimetres between looks; it keeps the ISS's work,
 * and the run's wall time, within twice the race's). */
#ifndef LOOK_EVERY
#define LOOK_EVERY 5
#endif
/* A seen gate is accepted only this far above or below its waypoint (mm):
 * a pitched camera moves the gate vertically first. */
#define ACCEPT_DZ_MM 300

static uint8_t frame[GATE_IMAGE_WIDTH * GATE_IMAGE_HEIGHT] __attribute__((aligned(4)));
static const gate_config_t cfg = GATE_CONFIG_DEFAULT;

/* The image into L2, a word at a time (the window composes unaligned words
 * from bytes, docs/VISION.md "What the flight integration needs" 1). */
static void copy_frame(void)
{
    const volatile uint8_t *src = &REG8(CAMERA_IMAGE_OFFSET);
    uint32_t *dst = (uint32_t *)frame;
    for (int i = 0; i < GATE_IMAGE_WIDTH * GATE_IMAGE_HEIGHT / 4; i++)
        dst[i] = *(const volatile uint32_t *)(src + 4 * i);
}

static void look(int wp, guidance_sighting_t *s)
{
    gate_result_t r = {0};
    copy_frame();
    gate_detect(frame, &cfg, &r);
    s->found = r.found;
    /* Only openings seen whole: a cut edge is estimated assuming the gate
     * faces the camera, which drifts on an oblique gate. */
    s->usable = r.found && wp >= 0 && wp < GUIDANCE_WAYPOINTS - 1 && r.flags == 0 &&
                r.confidence >= 50 && r.range_mm >= MIN_RANGE_MM && r.range_mm <= MAX_RANGE_MM;
    s->body_mm[0] = r.body_x_mm;
    s->body_mm[1] = r.body_y_mm;
    s->body_mm[2] = r.body_z_mm;
}

int main(void)
{
    printf("[vision] race with the gate detector in the loop\n");
    const guidance_config_t g = {
        .look = look,
        .look_every = LOOK_EVERY,
        .accept_mm = ACCEPT_MM,
        .accept_dz_mm = ACCEPT_DZ_MM,
        .tag = "[vision]",
    };
    guidance_fly(&g);
    const guidance_stats_t *s = &guidance_stats;
    uint32_t mean = s->looks ? (uint32_t)(s->cycles_sum / s->looks) : 0;
    printf("[vision] captured %u, detector frames %u, gate found in %u, used in %u, retargets %u, inference %u ms\n",
           (unsigned)s->captured, (unsigned)s->looks, (unsigned)s->found, (unsigned)s->used,
           (unsigned)s->retargets, (unsigned)s->infer_ms_sum);
    /* SET_TARGETs: one per waypoint, one per standoff point, one per
     * retarget (the STM32 counts the last two as replaced). */
    printf("[vision] waypoints %d, standoff points %u, target moves %u\n", GUIDANCE_WAYPOINTS,
           (unsigned)s->standoffs, (unsigned)s->retargets);
    printf("[vision] cycles per frame (copy + detect): mean %u, max %u; clock %u cycles/ms\n",
           (unsigned)mean, (unsigned)s->cycles_max, (unsigned)s->cycles_per_ms);
    guidance_print_simul_time();
    return 0;
}
