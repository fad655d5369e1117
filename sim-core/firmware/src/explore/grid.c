/* Occupancy grid and inverse sensor model: see grid.h. */
#include "grid.h"

#include <stdio.h>
#include <string.h>

#include "fixmath.h"

/* The export image: header, then the cells. The grid's log-odds live here,
 * so the export needs no copy. Global symbols, so that the platform (or a
 * test) can find the image in memory. */
uint8_t explore_map_image[OG_HEADER_BYTES + EXPLORE_MAX_CELLS] __attribute__((aligned(4)));
uint32_t explore_map_image_len;

/* Writes a one-line message (if asked for) and returns the code. */
#define FAIL(code, ...)                                                                            \
    do {                                                                                           \
        if (msg && n)                                                                              \
            snprintf(msg, n, __VA_ARGS__);                                                         \
        return code;                                                                               \
    } while (0)

int og_init(og_grid *g, const explore_settings *s, char *msg, unsigned n)
{
    if (msg && n)
        msg[0] = 0;
    if (s->cell_mm < 10 || s->cell_mm > 1000)
        FAIL(EXPLORE_E_CELL, "explore: cell size %u mm outside 10..1000 mm", s->cell_mm);
    int32_t ex = s->x_max_mm - s->x_min_mm, ey = s->y_max_mm - s->y_min_mm;
    int far = s->x_min_mm < -1000000 || s->y_min_mm < -1000000 || s->x_max_mm > 1000000 ||
              s->y_max_mm > 1000000;
    if (far || ex <= 0 || ey <= 0 || ex > OG_EXTENT_CAP_MM || ey > OG_EXTENT_CAP_MM)
        FAIL(EXPLORE_E_BOUNDS,
             "explore: area x %ld..%ld, y %ld..%ld mm is empty, beyond 1 km or wider than %d mm",
             (long)s->x_min_mm, (long)s->x_max_mm, (long)s->y_min_mm, (long)s->y_max_mm,
             OG_EXTENT_CAP_MM);
    int32_t w = (ex + s->cell_mm - 1) / s->cell_mm, h = (ey + s->cell_mm - 1) / s->cell_mm;
    if ((int64_t)w * h > EXPLORE_MAX_CELLS)
        FAIL(EXPLORE_E_BUDGET,
             "explore: grid %ld x %ld = %ld cells exceeds the budget of %ld cells "
             "(EXPLORE_MAX_CELLS)",
             (long)w, (long)h, (long)w * h, (long)EXPLORE_MAX_CELLS);
    if (s->fov_cdeg > 9000)
        FAIL(EXPLORE_E_FOV, "explore: FOV %u cdeg outside 0..9000 cdeg", s->fov_cdeg);
    if (s->l_occ <= 0 || s->l_free >= 0 || s->l_max <= 0 || s->l_min >= 0)
        FAIL(EXPLORE_E_LOGODDS,
             "explore: log-odds need l_occ > 0, l_free < 0, l_min < 0 < l_max (got %d, %d, %d, %d)",
             s->l_occ, s->l_free, s->l_min, s->l_max);
    g->x0_mm = s->x_min_mm;
    g->y0_mm = s->y_min_mm;
    g->w = w;
    g->h = h;
    g->cell_mm = s->cell_mm;
    g->half_mm = s->cell_mm / 2;
    g->fov_cdeg = s->fov_cdeg;
    uint16_t half_angle = fx_cdeg_to_bam(s->fov_cdeg) / 2;
    g->tan_half_q14 = fx_sin(half_angle) * FX_Q14 / fx_cos(half_angle);
    g->l_occ = s->l_occ;
    g->l_free = s->l_free;
    g->l_min = s->l_min;
    g->l_max = s->l_max;
    g->lo = (int8_t *)(explore_map_image + OG_HEADER_BYTES);
    memset(explore_map_image, 0, sizeof explore_map_image);
    explore_map_image_len = 0;
    return EXPLORE_OK;
}

int og_cell_of(const og_grid *g, int32_t x, int32_t y, int32_t *ix, int32_t *iy)
{
    int32_t dx = x - g->x0_mm, dy = y - g->y0_mm;
    if (dx < 0 || dy < 0)
        return 0;
    *ix = dx / g->cell_mm;
    *iy = dy / g->cell_mm;
    return *ix < g->w && *iy < g->h;
}

void og_add(og_grid *g, int idx, int32_t dl)
{
    int32_t v = g->lo[idx] + dl;
    g->lo[idx] = (int8_t)fx_clamp(v, g->l_min, g->l_max);
}

static int32_t floor_div(int32_t a, int32_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

int og_update_beam(og_grid *g, int32_t x, int32_t y, uint16_t angle, uint32_t range, uint32_t max)
{
    /* No reading, or a pose so far off that the arithmetic could overflow
     * (the grid is within 1 km of the origin). */
    if (range == 0 || max == 0 || fx_abs(x) > 2000000 || fx_abs(y) > 2000000)
        return 0;
    if (max > OG_RANGE_CAP_MM)
        max = OG_RANGE_CAP_MM;
    int hit = range < max;
    int32_t z = hit ? (int32_t)range : (int32_t)max;
    int32_t half = g->half_mm;
    int32_t reach = hit ? z + half : z; /* farthest centre distance updated */
    /* Squared-distance thresholds: free up to free_r2, occupied up to occ_r2. */
    /* Unsigned: with a 90° cone a corner of the box is up to ~34 m^2 away. */
    uint32_t free_r2, occ_r2;
    int free_any = 1, occ_any = hit;
    if (hit) {
        free_any = z > half;
        free_r2 = free_any ? (uint32_t)((z - half) * (z - half)) : 0;
        occ_r2 = (uint32_t)(reach * reach);
    } else {
        free_r2 = (uint32_t)(z * z);
        occ_r2 = 0;
    }
    int32_t c = fx_cos(angle), s = fx_sin(angle), tanh = g->tan_half_q14;

    /* Bounding box of the widened cone: its hull is the quadrilateral with
     * the apex widened by half a cell and the base at along = reach,
     * across = +-(reach tan + half). One millimetre of slack for rounding. */
    int32_t wmax = ((reach * tanh) >> 14) + half + 1;
    int32_t bx = x + ((reach * c) >> 14), by = y + ((reach * s) >> 14);
    int32_t px = (wmax * -s) >> 14, py = (wmax * c) >> 14;
    int32_t xs[4] = {x - half - 1, x + half + 1, bx + px, bx - px};
    int32_t ys[4] = {y - half - 1, y + half + 1, by + py, by - py};
    int32_t minx = xs[0], maxx = xs[0], miny = ys[0], maxy = ys[0];
    for (int i = 1; i < 4; i++) {
        minx = fx_min(minx, xs[i]);
        maxx = fx_max(maxx, xs[i]);
        miny = fx_min(miny, ys[i]);
        maxy = fx_max(maxy, ys[i]);
    }
    int32_t ix0 = fx_max(0, floor_div(minx - g->x0_mm, g->cell_mm));
    int32_t ix1 = fx_min(g->w - 1, floor_div(maxx - g->x0_mm, g->cell_mm));
    int32_t iy0 = fx_max(0, floor_div(miny - g->y0_mm, g->cell_mm));
    int32_t iy1 = fx_min(g->h - 1, floor_div(maxy - g->y0_mm, g->cell_mm));
    if (ix0 > ix1 || iy0 > iy1)
        return 0;

    int updated = 0;
    int32_t cell = g->cell_mm;
    /* Along a row, dx grows by one cell: along and across (Q14) and r^2
     * follow incrementally. */
    int32_t step_a = cell * c, step_c = -cell * s;
    for (int32_t iy = iy0; iy <= iy1; iy++) {
        int32_t dy = og_cy(g, iy) - y;
        int32_t dx = og_cx(g, ix0) - x;
        int32_t a = dx * c + dy * s;   /* along, Q14 mm */
        int32_t cr = -dx * s + dy * c; /* across, Q14 mm */
        uint32_t r2 = (uint32_t)(dx * dx) + (uint32_t)(dy * dy);
        int8_t *row = g->lo + og_index(g, 0, iy);
        for (int32_t ix = ix0; ix <= ix1; ix++) {
            int32_t along = (a + 8192) >> 14;
            if (along > 0) {
                int32_t across = fx_abs((cr + 8192) >> 14);
                if (across <= ((along * tanh) >> 14) + half) {
                    int32_t dl = 0;
                    if (free_any && r2 <= free_r2)
                        dl = g->l_free;
                    else if (occ_any && r2 <= occ_r2)
                        dl = g->l_occ;
                    if (dl) {
                        int32_t v = row[ix] + dl;
                        row[ix] = (int8_t)(v < g->l_min ? g->l_min : v > g->l_max ? g->l_max : v);
                        updated++;
                    }
                }
            }
            r2 += (uint32_t)(2 * dx * cell + cell * cell); /* modular: exact */
            dx += cell;
            a += step_a;
            cr += step_c;
        }
    }
    return updated;
}

int og_update(og_grid *g, const explore_input *in)
{
    static const uint8_t which[4] = {EXPLORE_FRONT, EXPLORE_LEFT, EXPLORE_BACK, EXPLORE_RIGHT};
    uint16_t yaw = fx_mrad_to_bam(in->yaw_mrad);
    int n = 0;
    for (int k = 0; k < 4; k++)
        n += og_update_beam(g, in->x_mm, in->y_mm, (uint16_t)(yaw + k * FX_BAM_QUARTER),
                            in->range_mm[which[k]], in->max_range_mm);
    int32_t ix, iy;
    if (og_cell_of(g, in->x_mm, in->y_mm, &ix, &iy)) {
        og_add(g, og_index(g, ix, iy), g->l_free);
        n++;
    }
    return n;
}

uint32_t og_crc32(const uint8_t *p, uint32_t n)
{
    uint32_t crc = 0xffffffffu;
    while (n--) {
        crc ^= *p++;
        for (int k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xedb88320u & -(crc & 1));
    }
    return ~crc;
}

static void put16(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put32(uint8_t *p, uint32_t v)
{
    put16(p, v);
    put16(p + 2, v >> 16);
}

const uint8_t *og_export(const og_grid *g, uint32_t *len)
{
    uint8_t *h = explore_map_image;
    uint32_t cells = (uint32_t)(g->w * g->h);
    memcpy(h, "CFOG", 4);
    put16(h + 4, 1); /* version */
    put16(h + 6, OG_HEADER_BYTES);
    put16(h + 8, (uint32_t)g->w);
    put16(h + 10, (uint32_t)g->h);
    put16(h + 12, (uint32_t)g->cell_mm);
    put16(h + 14, g->fov_cdeg);
    put32(h + 16, (uint32_t)g->x0_mm);
    put32(h + 20, (uint32_t)g->y0_mm);
    h[24] = EXPLORE_LO_PER_NAT;
    h[25] = (uint8_t)g->l_min;
    h[26] = (uint8_t)g->l_max;
    h[27] = 0;
    put32(h + 28, og_crc32(h + OG_HEADER_BYTES, cells));
    explore_map_image_len = OG_HEADER_BYTES + cells;
    *len = explore_map_image_len;
    return h;
}
