/*
 * Internals shared by the gate detector's files (not an API): the image
 * and buffer sizes, the runs of gate pixels and their components
 * (gate_segment.c), union-find and region helpers.
 */
#ifndef GATE_INTERNAL_H
#define GATE_INTERNAL_H

#include "gate_detect.h"

#define W GATE_IMAGE_WIDTH
#define H GATE_IMAGE_HEIGHT
#define Q8 GATE_Q8

/* Work buffers. A gate is 2-4 runs per row, so 4096 runs hold several
 * gates and clutter. */
#define MAX_RUNS 4096
#define MAX_COMPONENTS 255
#define NONE 0xffffu

typedef struct {
    uint16_t x0, x1; /* inclusive columns */
} run_t;

typedef struct {
    uint16_t x0, y0, x1, y1; /* inclusive */
    uint32_t area;
    uint32_t flags;
} region_t;

/* The runs of gate pixels, row by row (row y's are gate_row_start[y] to
 * gate_row_start[y + 1] - 1, in x order), each run's component label
 * (NONE past MAX_COMPONENTS) and the components' boxes and areas. */
extern run_t gate_runs[MAX_RUNS];
extern uint16_t gate_run_link[MAX_RUNS];
extern uint16_t gate_row_start[H + 1];
extern region_t gate_comps[MAX_COMPONENTS];

/* Cuts the image into runs of pixels in [lo, lo + span] and labels their
 * 8-connected components. Returns the number of components; sets
 * GATE_OVERFLOW in *flags when the runs do not fit; *scan_cycles is the
 * time of the pixel scan alone. */
uint32_t gate_segment(const uint8_t *image, uint8_t lo, uint8_t span, uint32_t *flags,
                      uint32_t *scan_cycles);

/* Union-find over indices whose root is the smallest index of its set, and
 * its labelling (gate_segment.c). */
void gate_uf_union(uint16_t *link, uint32_t a, uint32_t b);
uint32_t gate_uf_label(uint16_t *link, uint32_t n, uint32_t max);
/* Adds run [x0, x1] of row y (rows in increasing order) to a region. */
void gate_region_add(region_t *r, uint32_t x0, uint32_t x1, uint32_t y);

static inline uint32_t gate_mcycle(void)
{
    uint32_t c;
    __asm__ volatile("csrr %0, mcycle" : "=r"(c));
    return c;
}

#endif
