/*
 * Host-driven test program for the gate detector (tests/tests/e2e/vision_detector.rs).
 *
 * The host runs it on the ISS with `ebreak_stops` (a plain ebreak stops the
 * run, like a debugger breakpoint). At every stop the host may write a frame
 * into `vision_frame` (and a configuration into `vision_config`), sets
 * `vision_command` (1: detect, 0: exit) and resumes after the ebreak; the
 * program runs the detector, leaves the result in `vision_result` and its
 * cycle count (mcycle, detector only) in `vision_cycles`, prints one line
 * and stops again. The frame lives in .bss: the start file clears it before
 * the first stop, so the host writes it only after that.
 *
 * Run without such a host, the first ebreak traps and the program exits
 * with status 131 (128 + breakpoint cause, start.S).
 */
#include <stdio.h>
#include "../host_stop.h"

#include "gate_detect.h"

uint8_t vision_frame[GATE_IMAGE_WIDTH * GATE_IMAGE_HEIGHT] __attribute__((aligned(4)));
gate_config_t vision_config = GATE_CONFIG_DEFAULT;
volatile uint32_t vision_command;
gate_result_t vision_result;
uint32_t vision_cycles;

static inline uint32_t mcycle(void)
{
    uint32_t c;
    __asm__ volatile("csrr %0, mcycle" : "=r"(c));
    return c;
}


int main(void)
{
    printf("gate_detect_test: ready, frame at %p\n", (void *)vision_frame);
    for (uint32_t frame = 0;; frame++) {
        host_stop();
        if (vision_command != 1)
            break;
        uint32_t t0 = mcycle();
        gate_detect(vision_frame, &vision_config, &vision_result);
        uint32_t t1 = mcycle();
        vision_cycles = t1 - t0;
        const gate_result_t *r = &vision_result;
        printf("frame %lu: found %ld flags %#lx cand %ld conf %ld centre %ld/256 %ld/256 "
               "size %ld/256 width %ld/256 az %ld el %ld mrad body %ld %ld %ld mm "
               "range %ld mm cycles %lu\n",
               (unsigned long)frame, (long)r->found, (unsigned long)r->flags,
               (long)r->candidates, (long)r->confidence, (long)r->cx_q8, (long)r->cy_q8,
               (long)r->size_q8, (long)r->width_q8, (long)r->azimuth_mrad,
               (long)r->elevation_mrad, (long)r->body_x_mm, (long)r->body_y_mm,
               (long)r->body_z_mm, (long)r->range_mm, (unsigned long)vision_cycles);
    }
    printf("gate_detect_test: done\n");
    return 0;
}
