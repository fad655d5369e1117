/* Inflation, Dijkstra, paths and line of sight: see plan.h. */
#include "plan.h"

#include <string.h>

#include "fixmath.h"

uint16_t pl_cost[EXPLORE_MAX_CELLS];
uint8_t pl_flags[EXPLORE_MAX_CELLS];
uint16_t pl_queue[EXPLORE_MAX_CELLS];
uint16_t pl_aux[EXPLORE_MAX_CELLS];

_Static_assert(EXPLORE_MAX_CELLS <= 65535, "cell indices are uint16_t");

/* The 8 neighbours: straight first, then diagonal. Index k's opposite is
 * OPP[k]; a cell's PL_PARENT field holds the direction towards its parent. */
static const int8_t DX[8] = {1, 0, -1, 0, 1, -1, -1, 1};
static const int8_t DY[8] = {0, 1, 0, -1, 1, 1, -1, -1};
static const uint8_t OPP[8] = {2, 3, 0, 1, 6, 7, 4, 5};

void pl_inflate(const og_grid *g, uint32_t radius_mm)
{
    int32_t n = g->w * g->h, cell = g->cell_mm;
    int32_t r = (int32_t)radius_mm / cell;
    uint32_t r2 = radius_mm * radius_mm;
    memset(pl_flags, 0, (size_t)n);
    for (int32_t iy = 0; iy < g->h; iy++) {
        for (int32_t ix = 0; ix < g->w; ix++) {
            if (og_get(g, ix, iy) <= 0)
                continue;
            int32_t y0 = fx_max(0, iy - r), y1 = fx_min(g->h - 1, iy + r);
            int32_t x0 = fx_max(0, ix - r), x1 = fx_min(g->w - 1, ix + r);
            for (int32_t y = y0; y <= y1; y++) {
                int32_t dy = (y - iy) * cell;
                uint8_t *row = pl_flags + og_index(g, 0, y);
                for (int32_t x = x0; x <= x1; x++) {
                    int32_t dx = (x - ix) * cell;
                    if ((uint32_t)(dx * dx + dy * dy) <= r2)
                        row[x] |= PL_BLOCKED;
                }
            }
        }
    }
}

/* The open set: a bucket queue (Dial's algorithm). Edge costs are at most
 * PL_DIAGONAL * PL_ESCAPE_FACTOR = 56, so the open cells' costs lie within
 * [c, c + 56] of the cost c being expanded: 64 circular buckets by cost
 * & 63, each a doubly linked list through pl_aux (next) and pl_queue
 * (prev), so that a cost decrease moves a cell in O(1). Fewer cycles per
 * cell than a binary heap on this core (about 600 against 850). */
#define NIL 0xffffu
#define NBUCKETS 64
_Static_assert(PL_DIAGONAL *PL_ESCAPE_FACTOR < NBUCKETS, "costs in flight must fit the buckets");
static uint16_t bucket[NBUCKETS];
static int open_n;

static void open_insert(int v)
{
    uint16_t *head = &bucket[pl_cost[v] & (NBUCKETS - 1)];
    pl_aux[v] = *head;
    pl_queue[v] = NIL;
    if (*head != NIL)
        pl_queue[*head] = (uint16_t)v;
    *head = (uint16_t)v;
    open_n++;
}

static void open_remove(int v, uint32_t old_cost)
{
    uint16_t next = pl_aux[v], prev = pl_queue[v];
    if (prev != NIL)
        pl_aux[prev] = next;
    else
        bucket[old_cost & (NBUCKETS - 1)] = next;
    if (next != NIL)
        pl_queue[next] = prev;
    open_n--;
}

/* The open cell of least cost; *c is the cost being expanded (it only
 * grows). */
static int open_pop(uint32_t *c)
{
    for (;;) {
        uint16_t *head = &bucket[*c & (NBUCKETS - 1)];
        if (*head != NIL) {
            int u = *head;
            open_remove(u, *c);
            return u;
        }
        (*c)++;
    }
}

/* A cell a path may enter: known free, and not blocked unless the path is
 * still escaping the start's blocked area. */
static inline int passable(const og_grid *g, int idx, int escaping)
{
    return g->lo[idx] < 0 && (!(pl_flags[idx] & PL_BLOCKED) || escaping);
}

int pl_dijkstra(const og_grid *g, int32_t x_mm, int32_t y_mm)
{
    int32_t n = g->w * g->h, w = g->w;
    memset(pl_cost, 0xff, (size_t)n * sizeof pl_cost[0]);
    for (int32_t i = 0; i < n; i++)
        pl_flags[i] &= PL_BLOCKED;
    for (int i = 0; i < NBUCKETS; i++)
        bucket[i] = NIL;
    open_n = 0;
    int32_t sx, sy;
    if (!og_cell_of(g, x_mm, y_mm, &sx, &sy))
        return 0;
    /* The start is where the drone is: accepted whatever the map says. */
    int s = og_index(g, sx, sy);
    pl_cost[s] = 0;
    if (pl_flags[s] & PL_BLOCKED)
        pl_flags[s] |= PL_ESCAPE;
    open_insert(s);
    uint32_t expanding = 0;
    int reached = 0;
    /* Neighbour index offsets, and which neighbours stay inside the grid
     * for a cell on each edge (bit k: direction k allowed). */
    const int32_t off[8] = {1, w, -1, -w, w + 1, w - 1, -w - 1, -w + 1};
    while (open_n) {
        int u = open_pop(&expanding);
        pl_flags[u] |= PL_REACHED;
        reached++;
        int32_t uy = u / w, ux = u - uy * w;
        unsigned ok = 0xff;
        if (ux == 0)
            ok &= ~((1u << 2) | (1u << 5) | (1u << 6));
        if (ux == w - 1)
            ok &= ~((1u << 0) | (1u << 4) | (1u << 7));
        if (uy == 0)
            ok &= ~((1u << 3) | (1u << 6) | (1u << 7));
        if (uy == g->h - 1)
            ok &= ~((1u << 1) | (1u << 4) | (1u << 5));
        int esc = pl_flags[u] & PL_ESCAPE;
        uint32_t cu = pl_cost[u];
        /* Straight neighbours' passability, for the corner rule. */
        unsigned pass = 0;
        for (int k = 0; k < 4; k++)
            if ((ok >> k & 1) && passable(g, u + off[k], esc))
                pass |= 1u << k;
        for (int k = 0; k < 8; k++) {
            if (!(ok >> k & 1))
                continue;
            if (k < 4) {
                if (!(pass >> k & 1))
                    continue;
            } else {
                /* No corner cutting: both straight neighbours passable
                 * (diagonal k is straight k - 4 plus straight (k - 3) & 3). */
                unsigned need = (1u << (k - 4)) | (1u << ((k - 3) & 3));
                if ((pass & need) != need)
                    continue;
            }
            int v = u + off[k];
            if (pl_flags[v] & PL_REACHED || (k >= 4 && !passable(g, v, esc)))
                continue;
            uint32_t step = k < 4 ? PL_STRAIGHT : PL_DIAGONAL;
            if (pl_flags[v] & PL_BLOCKED)
                step *= PL_ESCAPE_FACTOR;
            uint32_t nc = cu + step;
            if (nc >= PL_UNREACHED || nc >= pl_cost[v])
                continue;
            if (pl_cost[v] != PL_UNREACHED)
                open_remove(v, pl_cost[v]);
            pl_cost[v] = (uint16_t)nc;
            uint8_t f = pl_flags[v] & PL_BLOCKED;
            pl_flags[v] = (uint8_t)(f | OPP[k] | (f ? PL_ESCAPE : 0));
            open_insert(v);
        }
    }
    return reached;
}

/* A cell a straight segment may cross. Strict: as a path flown straight
 * (free, not blocked); otherwise: not occupied. */
static inline int los_ok(const og_grid *g, int32_t x, int32_t y, int strict)
{
    if (!og_inside(g, x, y))
        return 0;
    int idx = og_index(g, x, y);
    if (!strict)
        return g->lo[idx] <= 0;
    return g->lo[idx] < 0 && !(pl_flags[idx] & PL_BLOCKED);
}

/* Every cell the segment between the centres passes through, but the
 * first; at an exact corner both side cells count (conservative). */
static int segment(const og_grid *g, int32_t ax, int32_t ay, int32_t bx, int32_t by, int strict)
{
    int32_t dx = fx_abs(bx - ax), dy = fx_abs(by - ay);
    int32_t xi = bx > ax ? 1 : -1, yi = by > ay ? 1 : -1;
    int32_t x = ax, y = ay, err = dx - dy, n = 1 + dx + dy;
    int first = 1;
    dx *= 2;
    dy *= 2;
    while (n > 0) {
        if (!first && !los_ok(g, x, y, strict))
            return 0;
        first = 0;
        if (err > 0) {
            x += xi;
            err -= dy;
            n--;
        } else if (err < 0) {
            y += yi;
            err += dx;
            n--;
        } else {
            if (!los_ok(g, x + xi, y, strict) || !los_ok(g, x, y + yi, strict))
                return 0;
            x += xi;
            y += yi;
            err += dx - dy;
            n -= 2;
        }
    }
    return 1;
}

int pl_line_of_sight(const og_grid *g, int32_t ax, int32_t ay, int32_t bx, int32_t by)
{
    return segment(g, ax, ay, bx, by, 1);
}

int pl_segment_blocked(const og_grid *g, int32_t ax, int32_t ay, int32_t bx, int32_t by)
{
    return !segment(g, ax, ay, bx, by, 0);
}

int pl_path_to(const og_grid *g, int goal, pl_path *out)
{
    int32_t w = g->w;
    out->n = 0;
    out->truncated = 0;
    out->cost = 0;
    out->cells = 0;
    if (goal < 0 || goal >= g->w * g->h || !(pl_flags[goal] & PL_REACHED))
        return 0;
    out->cost = pl_cost[goal];
    /* Goal back to start into pl_aux: pl_aux[cells - 1] is the start. */
    uint32_t cells = 0;
    int cur = goal;
    for (;;) {
        pl_aux[cells++] = (uint16_t)cur;
        if (pl_cost[cur] == 0 || cells >= (uint32_t)(g->w * g->h))
            break;
        int k = pl_flags[cur] & PL_PARENT;
        cur += DX[k] + DY[k] * w;
    }
    out->cells = cells;
    /* Greedy shortening: from each waypoint, the farthest path cell still in
     * line of sight. */
    int i = (int)cells - 1;
    out->wp[out->n++] = (pl_point){og_cx(g, pl_aux[i] % w), og_cy(g, pl_aux[i] / w)};
    while (i > 0) {
        if (out->n == PL_MAX_WAYPOINTS) {
            out->truncated = 1;
            break;
        }
        int32_t ax = pl_aux[i] % w, ay = pl_aux[i] / w;
        int j = i - 1;
        while (j > 0 && pl_line_of_sight(g, ax, ay, pl_aux[j - 1] % w, pl_aux[j - 1] / w))
            j--;
        out->wp[out->n++] = (pl_point){og_cx(g, pl_aux[j] % w), og_cy(g, pl_aux[j] / w)};
        i = j;
    }
    return 1;
}
