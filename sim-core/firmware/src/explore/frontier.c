/* Frontier regions and goal selection: see frontier.h. */
#include "frontier.h"

#include "fixmath.h"

static int is_frontier(const og_grid *g, int32_t ix, int32_t iy)
{
    if (og_get(g, ix, iy) >= 0)
        return 0;
    return (ix > 0 && og_get(g, ix - 1, iy) == 0) ||
           (ix + 1 < g->w && og_get(g, ix + 1, iy) == 0) ||
           (iy > 0 && og_get(g, ix, iy - 1) == 0) || (iy + 1 < g->h && og_get(g, ix, iy + 1) == 0);
}

static int skipped(const fr_skip *skip, int32_t x, int32_t y)
{
    if (!skip)
        return 0;
    int32_t lim = (int32_t)skip->skip_mm;
    for (int i = 0; i < skip->n; i++) {
        int32_t dx = x - skip->pts[i].x_mm, dy = y - skip->pts[i].y_mm;
        if (fx_abs(dx) <= lim && fx_abs(dy) <= lim && dx * dx + dy * dy <= lim * lim)
            return 1;
    }
    return 0;
}

/* Goal cell of a region: see frontier.h. */
static void choose_goal(const og_grid *g, const fr_skip *skip, fr_region *r)
{
    r->goal = -1;
    r->goal_cost = PL_UNREACHED;
    uint32_t best_d2 = 0xffffffffu;
    for (int i = 0; i < r->count; i++) {
        int idx = pl_queue[r->first + i];
        if (!pl_goal_ok(g, idx))
            continue;
        int32_t x = og_cx(g, idx % g->w), y = og_cy(g, idx / g->w);
        if (skipped(skip, x, y))
            continue;
        int32_t dx = x - r->cx_mm, dy = y - r->cy_mm;
        uint32_t d2 = (uint32_t)(dx * dx) + (uint32_t)(dy * dy);
        if (d2 < best_d2 || (d2 == best_d2 && pl_cost[idx] < r->goal_cost)) {
            best_d2 = d2;
            r->goal = idx;
            r->goal_cost = pl_cost[idx];
        }
    }
}

void fr_detect(const og_grid *g, int min_cells, const fr_skip *skip, fr_result *out)
{
    static const int8_t DX[8] = {1, 0, -1, 0, 1, -1, -1, 1};
    static const int8_t DY[8] = {0, 1, 0, -1, 1, 1, -1, -1};
    int32_t w = g->w, h = g->h, n = w * h;
    out->n = out->dropped = out->small = out->frontier_cells = 0;
    out->best = -1;
    for (int32_t i = 0; i < n; i++)
        pl_flags[i] &= (uint8_t) ~(PL_SEEN | PL_FRONTIER);
    for (int32_t iy = 0; iy < h; iy++)
        for (int32_t ix = 0; ix < w; ix++)
            if (is_frontier(g, ix, iy)) {
                pl_flags[og_index(g, ix, iy)] |= PL_FRONTIER;
                out->frontier_cells++;
            }
    /* Flood fill each region into pl_queue: the FIFO never wraps, so a
     * region's cells stay contiguous there. Regions too small or past the
     * table are overwritten by the next. */
    int tail = 0;
    for (int32_t s = 0; s < n; s++) {
        if ((pl_flags[s] & (PL_FRONTIER | PL_SEEN)) != PL_FRONTIER)
            continue;
        int first = tail, head = tail;
        pl_queue[tail++] = (uint16_t)s;
        pl_flags[s] |= PL_SEEN;
        int64_t sx = 0, sy = 0;
        while (head < tail) {
            int u = pl_queue[head++];
            int32_t ux = u % w, uy = u / w;
            sx += og_cx(g, ux);
            sy += og_cy(g, uy);
            for (int k = 0; k < 8; k++) {
                int32_t vx = ux + DX[k], vy = uy + DY[k];
                if (!og_inside(g, vx, vy))
                    continue;
                int v = og_index(g, vx, vy);
                if ((pl_flags[v] & (PL_FRONTIER | PL_SEEN)) == PL_FRONTIER) {
                    pl_flags[v] |= PL_SEEN;
                    pl_queue[tail++] = (uint16_t)v;
                }
            }
        }
        int count = tail - first;
        if (count < min_cells) {
            out->small++;
            tail = first;
            continue;
        }
        if (out->n == FR_MAX_REGIONS) {
            out->dropped++;
            tail = first;
            continue;
        }
        fr_region *r = &out->r[out->n];
        r->first = (uint16_t)first;
        r->count = (uint16_t)count;
        /* Round half away from zero, as fx_div_round. */
        r->cx_mm = (int32_t)(sx >= 0 ? (sx + count / 2) / count : -((-sx + count / 2) / count));
        r->cy_mm = (int32_t)(sy >= 0 ? (sy + count / 2) / count : -((-sy + count / 2) / count));
        choose_goal(g, skip, r);
        if (r->goal >= 0 && (out->best < 0 || r->goal_cost < out->r[out->best].goal_cost))
            out->best = out->n;
        out->n++;
    }
}
