/*
 * Gate detector (docs/VISION.md, "Algorithm"). Integer arithmetic only.
 *
 * 1. Segmentation (gate_segment.c): runs of gate-grey pixels, joined into
 *    8-connected components: one per frame in view, legs included.
 * 2. Openings: inside the bounding box of a component, the runs of the
 *    complement ("gaps") are joined likewise (4-connected, the dual of the
 *    8-connectivity above). A gap region that reaches the box's border where
 *    the box is not at the image border is outside the frame; one that does
 *    not is enclosed by the frame: its opening. One that reaches only the
 *    image border is an opening cut by the border (or the space between the
 *    legs, which is always below the opening). Regions inside the opening's
 *    box are pieces of it (cut off by a gate seen through it).
 * 3. Geometry: the opening's side edges (vertical, level camera) and its
 *    top and bottom edges (straight lines), fitted one-sidedly robust; its
 *    corners; the centre at the intersection of the diagonals; the apparent
 *    height at the centre (gate_locate turns these into bearing and
 *    distance).
 * 4. Checks: a gate's opening is a quadrilateral (fills its corners' quad),
 *    not much wider than high, surrounded by bars of the expected width.
 *    The largest opening that passes wins.
 */
#include "gate_internal.h"

/* A component's box holds at most a few gaps per row. */
#define MAX_CANDIDATES 16
#define MAX_GAPS 3072
#define MAX_HOLES 255

/* Smallest component considered: a frame around a 2-pixel opening with
 * 1-pixel bars is 4 pixels wide. */
#define MIN_COMPONENT_SIDE 4
#define MIN_HOLE_AREA 4
/* Smallest visible piece of an opening too cut to be sized (16 x 16 px). */
#define MIN_UNSIZED_AREA 256

/* Gap flags: reaches outside the component's box; reaches an image border.
 * Hole flag: part of the opening being measured. */
#define GAP_OUT 0x100u
#define HOLE_PART 0x200u
#define GAP_BORDERS (GATE_CUT_LEFT | GATE_CUT_RIGHT | GATE_CUT_TOP | GATE_CUT_BOTTOM)

typedef struct {
    uint16_t x0, x1, y;
    uint16_t flags;
} gap_t;

static gap_t gaps[MAX_GAPS];
static uint16_t gap_link[MAX_GAPS];
static region_t holes[MAX_HOLES];

/* The opening being measured: its extent in each row and column. */
static int16_t row_l[H], row_r[H];
static int16_t col_t[W], col_b[W];

/* --- 3. edge fits --- */

/* A straight edge y(x) = mid + slope * (x - xmid), all in q8 except slope
 * (q16, pixels per pixel). */
typedef struct {
    int32_t xmid_q8, mid_q8, slope_q16;
    int32_t rms_q8; /* residual */
} line_t;

static int32_t line_at(const line_t *l, int32_t x_q8)
{
    return l->mid_q8 + (int32_t)(((int64_t)l->slope_q16 * (x_q8 - l->xmid_q8)) >> 16);
}

/* Edges are estimated one-sidedly. A gate seen through the opening whose
 * bars touch the frame in the image joins its component, and its pixels can
 * only cover part of the opening: they push an edge's samples inwards,
 * never outwards. So each line is refitted without the samples more than
 * half a pixel inwards of the previous fit (a clean edge's samples lie
 * within half a pixel of it: the renderer has no anti-aliasing), a few
 * times; on a clean edge nothing is dropped. */
#define ROBUST_PASSES 4
#define ROBUST_MARGIN (Q8 / 2)

/* Least squares over the columns (or rows) x0..x1 of ys[x] + add (edge
 * positions in whole pixels), sampled at the column centres x + 0.5; a
 * horizontal line (slope 0) when `flat`. One-sided robust: `inward` is +1
 * when larger values lie inside the opening, -1 when smaller do. */
static void fit_line(const int16_t *ys, int32_t add, int32_t x0, int32_t x1, int32_t inward, int flat,
                     line_t *l)
{
    for (int pass = 0; pass < ROBUST_PASSES; pass++) {
        /* The previous fit along the columns, q16, by increments. */
        int32_t pred = pass ? line_at(l, x0 * Q8 + Q8 / 2) * 256 : 0, step = l->slope_q16;
        int32_t n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
        for (int32_t x = x0; x <= x1; x++, pred += step) {
            int32_t y = ys[x] + add;
            if (pass > 0 && ((y << 16) - pred) * inward > ROBUST_MARGIN * 256)
                continue;
            int32_t x2 = 2 * x + 1; /* twice the column centre */
            n++;
            sx += x2;
            sy += y;
            sxx += x2 * x2;
            sxy += x2 * y;
        }
        /* The line goes through the mean point; slope per pixel is twice
         * that per half pixel. */
        line_t next;
        next.xmid_q8 = sx * (Q8 / 2) / n;
        next.mid_q8 = (sy * Q8 + n / 2) / n;
        int64_t den = (int64_t)n * sxx - (int64_t)sx * sx;
        next.slope_q16 =
            flat || den <= 0 ? 0 : (int32_t)((((int64_t)n * sxy - (int64_t)sx * sy) * 2 * 65536) / den);
        int same = pass > 0 && next.mid_q8 == l->mid_q8 && next.slope_q16 == l->slope_q16;
        *l = next;
        if (same)
            break;
    }
    /* Residual of the samples the fit keeps. */
    int32_t pred = line_at(l, x0 * Q8 + Q8 / 2) * 256, n = 0;
    int64_t sq = 0;
    for (int32_t x = x0; x <= x1; x++, pred += l->slope_q16) {
        int32_t e = (((ys[x] + add) << 16) - pred) >> 8; /* q8 */
        if (e * inward <= ROBUST_MARGIN) {
            sq += (int64_t)e * e;
            n++;
        }
    }
    l->rms_q8 = (int32_t)gate_isqrt64((uint64_t)(sq / n));
}

/* --- 2. openings of one component --- */

/* Collects the gaps of component `c` inside its box and labels their
 * regions into holes[]. Returns the number of holes, -1 if they do not fit. */
static int32_t find_holes(uint32_t c, uint32_t *n_gaps)
{
    const region_t *b = &gate_comps[c];
    uint32_t ng = 0, prev0 = 0, prev1 = 0;
    for (uint32_t y = b->y0; y <= b->y1; y++) {
        uint32_t first = ng, next = b->x0;
        uint32_t edge_row = (y == b->y0 && b->y0 > 0) || (y == b->y1 && b->y1 < H - 1);
        for (uint32_t i = gate_row_start[y]; i <= gate_row_start[y + 1]; i++) {
            /* One pass past the last run closes the row at the box's edge. */
            uint32_t end = i < gate_row_start[y + 1] ? gate_runs[i].x0 : b->x1 + 1u;
            if (i < gate_row_start[y + 1] && gate_run_link[i] != c)
                continue;
            if (end > next) {
                if (ng == MAX_GAPS)
                    return -1;
                gap_t *g = &gaps[ng];
                g->x0 = (uint16_t)next;
                g->x1 = (uint16_t)(end - 1);
                g->y = (uint16_t)y;
                g->flags = 0;
                if (edge_row || (next == b->x0 && b->x0 > 0) || (end - 1 == b->x1 && b->x1 < W - 1))
                    g->flags |= GAP_OUT;
                if (next == 0)
                    g->flags |= GATE_CUT_LEFT;
                if (end - 1 == W - 1)
                    g->flags |= GATE_CUT_RIGHT;
                if (y == 0)
                    g->flags |= GATE_CUT_TOP;
                if (y == H - 1)
                    g->flags |= GATE_CUT_BOTTOM;
                gap_link[ng] = (uint16_t)ng;
                ng++;
            }
            if (i < gate_row_start[y + 1])
                next = gate_runs[i].x1 + 1u;
        }
        /* Gaps of consecutive rows that overlap (4-connectivity). */
        uint32_t i = prev0, j = first;
        while (i < prev1 && j < ng) {
            if (gaps[i].x1 < gaps[j].x0) {
                i++;
            } else if (gaps[j].x1 < gaps[i].x0) {
                j++;
            } else {
                gate_uf_union(gap_link, i, j);
                if (gaps[i].x1 < gaps[j].x1)
                    i++;
                else
                    j++;
            }
        }
        prev0 = first;
        prev1 = ng;
    }
    uint32_t nh = gate_uf_label(gap_link, ng, MAX_HOLES);
    if (nh > MAX_HOLES)
        nh = MAX_HOLES;
    for (uint32_t h = 0; h < nh; h++) {
        holes[h].area = 0;
        holes[h].flags = 0;
    }
    for (uint32_t k = 0; k < ng; k++) {
        uint32_t h = gap_link[k];
        if (h == NONE)
            continue;
        gate_region_add(&holes[h], gaps[k].x0, gaps[k].x1, gaps[k].y);
        holes[h].flags |= gaps[k].flags;
    }
    *n_gaps = ng;
    return (int32_t)nh;
}

/* The opening among the holes: an enclosed one (the largest) if any, else
 * the highest of those cut by the image border (the space between the legs
 * is below the opening). NONE if there is none. */
static uint32_t pick_hole(uint32_t nh)
{
    uint32_t best = NONE, best_enclosed = 0;
    for (uint32_t h = 0; h < nh; h++) {
        const region_t *r = &holes[h];
        if ((r->flags & GAP_OUT) || r->area < MIN_HOLE_AREA)
            continue;
        uint32_t enclosed = !(r->flags & GAP_BORDERS);
        if (best == NONE || enclosed > best_enclosed) {
            best = h;
            best_enclosed = enclosed;
            continue;
        }
        if (enclosed < best_enclosed)
            continue;
        const region_t *b = &holes[best];
        if (enclosed ? r->area > b->area : (r->y0 < b->y0 || (r->y0 == b->y0 && r->area > b->area)))
            best = h;
    }
    return best;
}

/* Marks the parts of the opening: hole `h` and every other hole inside
 * its box. A gate seen through the opening whose bars touch the frame in
 * the image joins its component and cuts pieces off the opening; those
 * pieces are still opening. Returns their total area. */
static uint32_t opening_parts(uint32_t h, uint32_t nh)
{
    const region_t *r = &holes[h];
    uint32_t area = 0;
    for (uint32_t k = 0; k < nh; k++) {
        region_t *q = &holes[k];
        if (q->area == 0 || (q->flags & GAP_OUT) || q->x0 < r->x0 || q->x1 > r->x1 ||
            q->y0 < r->y0 || q->y1 > r->y1)
            continue;
        q->flags |= HOLE_PART;
        area += q->area;
    }
    return area;
}

/* Row and column extents of the opening (row_l/row_r, col_t/col_b): of
 * the holes marked by opening_parts, within the box of hole `h`. */
static void hole_extents(uint32_t h, uint32_t ng)
{
    const region_t *r = &holes[h];
    for (uint32_t y = r->y0; y <= r->y1; y++) {
        row_l[y] = W;
        row_r[y] = -1;
    }
    for (uint32_t k = 0; k < ng; k++) {
        if (gap_link[k] == NONE || !(holes[gap_link[k]].flags & HOLE_PART))
            continue;
        const gap_t *g = &gaps[k];
        if (g->x0 < row_l[g->y])
            row_l[g->y] = (int16_t)g->x0;
        if (g->x1 > row_r[g->y])
            row_r[g->y] = (int16_t)g->x1;
    }
    /* First and last row of each column. The rows' extents only grow
     * outwards from the first row (the opening is convex), so each column
     * is set once, when the covered span first reaches it: O(width). */
    int32_t lo = row_l[r->y0], hi = row_r[r->y0];
    for (int32_t x = lo; x <= hi; x++)
        col_t[x] = (int16_t)r->y0;
    for (uint32_t y = r->y0 + 1; y <= r->y1; y++) {
        for (int32_t x = row_l[y]; x < lo; x++)
            col_t[x] = (int16_t)y;
        for (int32_t x = hi + 1; x <= row_r[y]; x++)
            col_t[x] = (int16_t)y;
        if (row_l[y] < lo)
            lo = row_l[y];
        if (row_r[y] > hi)
            hi = row_r[y];
    }
    lo = row_l[r->y1];
    hi = row_r[r->y1];
    for (int32_t x = lo; x <= hi; x++)
        col_b[x] = (int16_t)r->y1;
    for (int32_t y = (int32_t)r->y1 - 1; y >= (int32_t)r->y0; y--) {
        for (int32_t x = row_l[y]; x < lo; x++)
            col_b[x] = (int16_t)y;
        for (int32_t x = hi + 1; x <= row_r[y]; x++)
            col_b[x] = (int16_t)y;
        if (row_l[y] < lo)
            lo = row_l[y];
        if (row_r[y] > hi)
            hi = row_r[y];
    }
}

/* Width (px) of the run of component `c` in row y that ends at column
 * `end` (side = -1) or starts at it (side = +1); 0 if that run reaches the
 * image border (its width is not seen) or is not there. */
static int32_t bar_width(uint32_t c, uint32_t y, int32_t end, int32_t side)
{
    for (uint32_t i = gate_row_start[y]; i < gate_row_start[y + 1]; i++) {
        if (gate_run_link[i] != c)
            continue;
        if (side < 0 && gate_runs[i].x1 == end)
            return gate_runs[i].x0 == 0 ? 0 : gate_runs[i].x1 - gate_runs[i].x0 + 1;
        if (side > 0 && gate_runs[i].x0 == end)
            return gate_runs[i].x1 == W - 1 ? 0 : gate_runs[i].x1 - gate_runs[i].x0 + 1;
    }
    return 0;
}

/* --- 3 and 4: measure and check one component --- */

static int measure(uint32_t c, const gate_config_t *cfg, gate_result_t *out)
{
    uint32_t ng;
    int32_t nh = find_holes(c, &ng);
    if (nh <= 0)
        return 0;
    uint32_t h = pick_hole((uint32_t)nh);
    if (h == NONE)
        return 0;
    const region_t *r = &holes[h];
    uint32_t area = opening_parts(h, (uint32_t)nh);
    hole_extents(h, ng);
    uint32_t cut = r->flags & GAP_BORDERS;
    out->flags = cut;

    /* Side edges: robust fits over the rows, top and bottom edges: over
     * the columns, two pixels short of the corners. Near
     * the corners a slanted top or bottom edge cuts rows short (and a
     * slanted side edge columns): inwards, so dropped by the robust fits.
     * Row y's first opening pixel is row_l: the edge lies within half a
     * pixel of its left side. */
    int32_t rows = r->y1 - r->y0 + 1, cols = r->x1 - r->x0 + 1;
    int32_t ym0 = r->y0 + (rows > 8 ? 2 : 0), ym1 = r->y1 - (rows > 8 ? 2 : 0);
    int32_t xm0 = r->x0 + (cols > 8 ? 2 : 0), xm1 = r->x1 - (cols > 8 ? 2 : 0);
    line_t left = {0}, right = {0}, top = {0}, bot = {0};
    /* A level camera sees the side edges vertical, so they are fitted as
     * constants: a sloped line could absorb a step (clean rows above, rows
     * pushed in below) that the one-sided fit must reject. */
    fit_line(row_l, 0, ym0, ym1, 1, 1, &left);
    fit_line(row_r, 1, ym0, ym1, -1, 1, &right);
    int32_t xl = left.mid_q8, xr = right.mid_q8;
    fit_line(col_t, 0, xm0, xm1, 1, 0, &top);
    fit_line(col_b, 1, xm0, xm1, -1, 0, &bot);

    int32_t vcut = cut & (GATE_CUT_LEFT | GATE_CUT_RIGHT);
    int32_t hcut = cut & (GATE_CUT_TOP | GATE_CUT_BOTTOM);
    int32_t hl, hr, rms = 0;
    if (!vcut && !hcut) {
        hl = line_at(&bot, xl) - line_at(&top, xl);
        hr = line_at(&bot, xr) - line_at(&top, xr);
        rms = top.rms_q8 > bot.rms_q8 ? top.rms_q8 : bot.rms_q8;
    } else if (vcut && !hcut && vcut != (GATE_CUT_LEFT | GATE_CUT_RIGHT)) {
        /* One side edge out of view: assume the opening faces the camera
         * to place it (its depth from the height at the seen edge). */
        int32_t xs = (vcut & GATE_CUT_LEFT) ? xr : xl;
        hl = hr = line_at(&bot, xs) - line_at(&top, xs);
        if (hl <= 0)
            return 0;
        int32_t zf = (int32_t)(((int64_t)cfg->focal_q8 * cfg->inner_mm + hl / 2) / hl);
        if (vcut & GATE_CUT_LEFT)
            xl = gate_other_side(cfg, xr, zf, -1);
        else
            xr = gate_other_side(cfg, xl, zf, 1);
        rms = top.rms_q8 > bot.rms_q8 ? top.rms_q8 : bot.rms_q8;
    } else if (hcut && !vcut && hcut != (GATE_CUT_TOP | GATE_CUT_BOTTOM)) {
        /* Top or bottom edge out of view: same assumption, the depth from
         * the side edges gives the height, the seen edge moved by it the
         * other. */
        int32_t zf = gate_depth_from_sides(cfg, xl, xr);
        if (zf <= 0)
            return 0;
        hl = hr = (int32_t)(((int64_t)cfg->focal_q8 * cfg->inner_mm + zf / 2) / zf);
        line_t *seen = (hcut & GATE_CUT_TOP) ? &bot : &top;
        line_t *other = (hcut & GATE_CUT_TOP) ? &top : &bot;
        *other = *seen;
        other->mid_q8 += (hcut & GATE_CUT_TOP) ? -hl : hl;
        rms = seen->rms_q8;
    } else {
        /* A corner or a middle part only: no size, only a direction. With
         * nothing to check it against, it must at least be a sizeable
         * piece of opening, not a sliver between an object and a corner. */
        if (area < MIN_UNSIZED_AREA)
            return 0;
        out->flags |= GATE_NO_SIZE;
        out->cx_q8 = (r->x0 + r->x1 + 1) * Q8 / 2;
        out->cy_q8 = (r->y0 + r->y1 + 1) * Q8 / 2;
        out->size_q8 = 0;
        out->width_q8 = (r->x1 - r->x0 + 1) * Q8;
        out->confidence = 25;
        return 1;
    }
    if (hl <= 0 || hr <= 0 || xr <= xl)
        return 0;

    /* A trapezoid with vertical sides of heights hl, hr: its diagonals
     * cross at the fraction t = hl / (hl + hr) of the way from the left
     * side, on the line joining the sides' midpoints, where the height is
     * 2 hl hr / (hl + hr) (the projection of the centre, whose depth is the
     * mean of the sides' depths). */
    int32_t t_q16 = (int32_t)(((int64_t)hl << 16) / (hl + hr));
    int32_t cx = xl + (int32_t)(((int64_t)(xr - xl) * t_q16) >> 16);
    int32_t cy = (line_at(&top, cx) + line_at(&bot, cx)) / 2;
    int32_t size = (int32_t)((2 * (int64_t)hl * hr) / (hl + hr));
    int32_t width = xr - xl;

    /* Checks. Big enough; not wider than high (a square seen from any
     * side, level camera), nor too thin. */
    if (size < cfg->min_size_px * Q8)
        return 0;
    if (width * 5 > size * 8 || width * 8 < size)
        return 0;
    int32_t conf = hcut || vcut ? 60 : 100;
    if (!hcut && !vcut) {
        /* The opening fills the quad of its corners. */
        int64_t quad = (int64_t)(hl + hr) / 2 * width; /* q16 px^2 */
        int32_t fill = (int32_t)(((int64_t)area << 16) * 100 / (quad > 0 ? quad : 1));
        if (fill < 70 || fill > 140)
            return 0;
        conf -= fill < 100 ? 100 - fill : fill - 100;
    }
    /* Bars of the expected width on at least one side (the other may
     * touch another gate seen behind it). */
    int32_t ym = (ym0 + ym1) / 2;
    int32_t bar = (int32_t)((int64_t)size * cfg->bar_mm / cfg->inner_mm); /* q8 */
    int32_t seen = 0, good = 0;
    int32_t wl = vcut & GATE_CUT_LEFT ? 0 : bar_width(c, (uint32_t)ym, row_l[ym] - 1, -1);
    int32_t wr = vcut & GATE_CUT_RIGHT ? 0 : bar_width(c, (uint32_t)ym, row_r[ym] + 1, 1);
    for (int k = 0; k < 2; k++) {
        int32_t wpx = k ? wr : wl;
        if (wpx == 0)
            continue;
        seen++;
        /* Within a third and three times the width (a bar seen obliquely
         * shows two faces), one pixel of quantisation either way. */
        if (wpx * Q8 * 3 >= bar - 3 * Q8 && wpx * Q8 <= 3 * bar + Q8)
            good++;
    }
    if (seen && !good)
        return 0;
    if (good < seen)
        conf -= 20;
    /* Straight edges: every pixel of residual costs 10 points. */
    if (rms > Q8 / 2)
        conf -= (rms - Q8 / 2) * 10 / Q8;
    if (conf < 1)
        conf = 1;

    out->cx_q8 = cx;
    out->cy_q8 = cy;
    out->size_q8 = size;
    out->width_q8 = width;
    out->left_q8 = xl;
    out->right_q8 = xr;
    out->height_left_q8 = hl;
    out->height_right_q8 = hr;
    out->confidence = conf;
    return 1;
}

int gate_detect(const uint8_t *image, const gate_config_t *cfg, gate_result_t *out)
{
    uint32_t flags = 0;
    *out = (gate_result_t){0};
    if (cfg->inner_mm == 0 || cfg->focal_q8 <= 0)
        return 0;
    /* The band [grey - tolerance, grey + tolerance], clipped to 0..255. */
    int32_t lo = cfg->grey - cfg->tolerance, hi = cfg->grey + cfg->tolerance;
    lo = lo < 0 ? 0 : lo;
    hi = hi > 255 ? 255 : hi;

    uint32_t t1 = gate_mcycle(), scan = 0; /* stage cycles, for profiling */
    uint32_t nc = gate_segment(image, (uint8_t)lo, (uint8_t)(hi - lo), &flags, &scan);

    /* The largest components first, at most MAX_CANDIDATES of them. */
    uint16_t cand[MAX_CANDIDATES];
    uint32_t ncand = 0;
    for (uint32_t c = 0; c < nc; c++) {
        const region_t *b = &gate_comps[c];
        if (b->x1 - b->x0 + 1 < MIN_COMPONENT_SIDE || b->y1 - b->y0 + 1 < MIN_COMPONENT_SIDE)
            continue;
        uint32_t k = ncand < MAX_CANDIDATES ? ncand++ : MAX_CANDIDATES;
        if (k == MAX_CANDIDATES) {
            /* Full: replace the smallest if this one is larger. */
            k = MAX_CANDIDATES - 1;
            if (gate_comps[cand[k]].area >= b->area)
                continue;
        }
        while (k > 0 && gate_comps[cand[k - 1]].area < b->area) {
            cand[k] = cand[k - 1];
            k--;
        }
        cand[k] = (uint16_t)c;
    }

    /* The nearest gate: the largest apparent opening (size, or the visible
     * width for one cut too much to be sized). */
    uint32_t t2 = gate_mcycle();
    int32_t best_key = -1, found = 0;
    for (uint32_t k = 0; k < ncand; k++) {
        gate_result_t r = {0};
        if (!measure(cand[k], cfg, &r))
            continue;
        found++;
        int32_t key = (r.flags & GATE_NO_SIZE) ? r.width_q8 : r.size_q8;
        if (key > best_key) {
            best_key = key;
            *out = r;
        }
    }
    out->flags |= flags;
    out->candidates = found;
    out->cycles_scan = scan;
    out->cycles_components = t2 - t1 - scan;
    out->cycles_openings = gate_mcycle() - t2;
    if (!found)
        return 0;
    out->found = 1;
    gate_locate(cfg, out);
    return 1;
}
