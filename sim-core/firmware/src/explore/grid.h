/*
 * Occupancy grid with integer log-odds (seed §2.4.2, §4.2.1.A; Probabilistic
 * Robotics ch. 9): one int8_t per cell, 0 = the prior (p = 0.5, unknown),
 * in units of 1/EXPLORE_LO_PER_NAT nat, clamped to [l_min, l_max]. A cell is
 * free when its log-odds is below 0 and occupied above 0: the seed's
 * normalisation (§4.2.1.A) and Yamauchi's three classes (§2.5.1).
 */
#ifndef EXPLORE_GRID_H
#define EXPLORE_GRID_H

#include <stdint.h>

#include "explore.h"

/* Bytes of the export header in front of the cells. */
#define OG_HEADER_BYTES 32
/* Ranges are clamped here (the VL53L1x reaches 4 m) so that the beam's
 * squared distances fit in 32 bits. */
#define OG_RANGE_CAP_MM 16000
/* Largest extent of the area per axis: squared distances fit in 32 bits. */
#define OG_EXTENT_CAP_MM 20000

typedef struct {
    int32_t x0_mm, y0_mm; /* lower-left corner of cell (0, 0) */
    int32_t w, h;         /* cells */
    int32_t cell_mm;
    int32_t half_mm; /* cell_mm / 2: the cone's widening and the hit band */
    uint16_t fov_cdeg;
    int32_t tan_half_q14; /* tan(FOV / 2), Q14 */
    int8_t l_occ, l_free, l_min, l_max;
    int8_t *lo; /* w * h cells, row-major, ix fastest */
} og_grid;

enum { OG_UNKNOWN = 0, OG_FREE = 1, OG_OCC = 2 };

static inline int og_class(int8_t l) { return l < 0 ? OG_FREE : l > 0 ? OG_OCC : OG_UNKNOWN; }

/* Validates the map settings, sizes the grid in the static storage and
 * clears it. Returns EXPLORE_OK or an EXPLORE_E_* code, with a one-line
 * message in msg (if not NULL). */
int og_init(og_grid *g, const explore_settings *s, char *msg, unsigned msg_len);

static inline int og_index(const og_grid *g, int32_t ix, int32_t iy) { return iy * g->w + ix; }
static inline int og_inside(const og_grid *g, int32_t ix, int32_t iy)
{
    return ix >= 0 && iy >= 0 && ix < g->w && iy < g->h;
}
/* Centre of a cell (mm). */
static inline int32_t og_cx(const og_grid *g, int32_t ix)
{
    return g->x0_mm + ix * g->cell_mm + g->half_mm;
}
static inline int32_t og_cy(const og_grid *g, int32_t iy)
{
    return g->y0_mm + iy * g->cell_mm + g->half_mm;
}
/* Cell holding a point; 0 if the point is outside the grid. */
int og_cell_of(const og_grid *g, int32_t x_mm, int32_t y_mm, int32_t *ix, int32_t *iy);

static inline int8_t og_get(const og_grid *g, int32_t ix, int32_t iy)
{
    return g->lo[og_index(g, ix, iy)];
}
static inline void og_set(og_grid *g, int32_t ix, int32_t iy, int8_t l)
{
    g->lo[og_index(g, ix, iy)] = l;
}

/* Adds a log-odds increment to a cell, clamped to [l_min, l_max]. */
void og_add(og_grid *g, int idx, int32_t dl);

/*
 * The inverse sensor model for one range beam from (x, y) along the binary
 * angle `angle` (seed §4.2.1.A: a cone of the FOV setting, not a line;
 * Probabilistic Robotics Table 9.2). For a cell with centre at distance r
 * and, in the beam's frame, `along` and `across` (mm, rounded):
 *   - the cell is in the cone if along > 0 and
 *       |across| <= along * tan(FOV / 2) + cell / 2
 *     (the cone widened by half a cell, so that even a 0° beam marks a
 *     connected line of cells);
 *   - a hit (0 < range < max): free if r <= range - cell/2, occupied if
 *     range - cell/2 < r <= range + cell/2 (the one-cell band at the hit),
 *     unchanged beyond;
 *   - no hit (range >= max): free if r <= max, unchanged beyond;
 *   - range 0 (no reading): nothing.
 * Returns the number of cells updated.
 */
int og_update_beam(og_grid *g, int32_t x_mm, int32_t y_mm, uint16_t angle, uint32_t range_mm,
                   uint32_t max_mm);

/* The four horizontal beams of one sample (front, left, back, right at 0°,
 * 90°, 180°, 270° from the yaw; the sensors sit at the drone's centre) and
 * a free observation of the drone's own cell (it is flying there). Returns
 * the number of cells updated. */
int og_update(og_grid *g, const explore_input *in);

/* Fills the export header in front of the cells and returns the image. */
const uint8_t *og_export(const og_grid *g, uint32_t *len);

/* CRC-32 (IEEE 802.3, reflected, as zlib) of a buffer. */
uint32_t og_crc32(const uint8_t *p, uint32_t n);

#endif
