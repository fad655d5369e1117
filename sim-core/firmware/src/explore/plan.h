/*
 * Grid path planning (Yamauchi's robot planned "the shortest obstacle-free
 * path to the cell that contains the goal" on the grid, seed §2.5.1):
 * obstacles inflated by the drone's radius plus a margin, then Dijkstra from
 * the drone's cell over known-free cells, 8-connected, with costs 5 per
 * straight and 7 per diagonal step (7/5 = 1.4 ~ sqrt 2), no corner cutting;
 * small integer costs allow a bucket queue instead of a heap.
 * One Dijkstra gives the path cost to every reachable cell, which is what
 * the frontier goal selection needs (nearest region by path length); a path
 * to any reached cell then follows the parents. The path is shortened to
 * waypoints by line of sight.
 *
 * Unknown cells are not traversable. If the drone stands in an inflated
 * cell (the map changed around it), it may leave through inflated cells
 * ("escape", at PL_ESCAPE_FACTOR times the cost, so by the shortest way
 * out) but never enter them again once out, so paths never squeeze through
 * gaps narrower than the drone.
 */
#ifndef EXPLORE_PLAN_H
#define EXPLORE_PLAN_H

#include <stdint.h>

#include "grid.h"

#define PL_STRAIGHT 5
#define PL_DIAGONAL 7
/* A step into a blocked cell while escaping costs this many times more:
 * the path leaves the inflation by the shortest way out instead of running
 * along the obstacle inside it. */
#define PL_ESCAPE_FACTOR 8
#define PL_UNREACHED 0xffffu
#define PL_MAX_WAYPOINTS 64

/* Per-cell work arrays, shared with the frontier detection. */
extern uint16_t pl_cost[EXPLORE_MAX_CELLS];
extern uint8_t pl_flags[EXPLORE_MAX_CELLS];
extern uint16_t pl_queue[EXPLORE_MAX_CELLS]; /* open-set links, then the frontier FIFO */
extern uint16_t pl_aux[EXPLORE_MAX_CELLS];   /* open-set links, then the raw path */

/* pl_flags bits. */
#define PL_PARENT 0x07   /* direction to the parent (index into the neighbour table) */
#define PL_REACHED 0x08  /* cost is final (closed) */
#define PL_BLOCKED 0x10  /* occupied, or within the inflation radius of an occupied cell */
#define PL_ESCAPE 0x20   /* blocked, but reached while leaving the start's blocked area */
#define PL_SEEN 0x40     /* frontier labelling: visited */
#define PL_FRONTIER 0x80 /* frontier labelling: a frontier cell */

typedef struct {
    int32_t x_mm, y_mm;
} pl_point;

typedef struct {
    pl_point wp[PL_MAX_WAYPOINTS]; /* first: the start cell's centre; last: the goal's */
    int n;
    int truncated; /* more than PL_MAX_WAYPOINTS were needed: re-plan at the end */
    uint32_t cost; /* path cost, PL_STRAIGHT per cell side */
    uint32_t cells;
} pl_path;

/* Marks blocked cells: occupied cells dilated by radius_mm (a cell is
 * blocked if its centre is within radius_mm of an occupied cell's centre).
 * Clears all other flags. */
void pl_inflate(const og_grid *g, uint32_t radius_mm);

/* Dijkstra from the cell holding (x, y) after pl_inflate. Returns the number
 * of cells reached (0 if the start is outside the grid or not free). */
int pl_dijkstra(const og_grid *g, int32_t x_mm, int32_t y_mm);

/* A cell can end a path: reached, free, and not blocked. */
static inline int pl_goal_ok(const og_grid *g, int idx)
{
    return (pl_flags[idx] & (PL_REACHED | PL_BLOCKED)) == PL_REACHED && g->lo[idx] < 0;
}

/* Path to a cell reached by the last pl_dijkstra; returns 0 if unreachable.
 * Uses pl_aux. */
int pl_path_to(const og_grid *g, int goal_idx, pl_path *out);

/* Line of sight between two cells: every cell the segment between the
 * centres touches, but the first, is free and not blocked (escape cells
 * included: inside the inflation the path is flown cell by cell). */
int pl_line_of_sight(const og_grid *g, int32_t ax, int32_t ay, int32_t bx, int32_t by);

/* 1 if the segment between two cells' centres touches a cell now known to
 * be occupied, the first (the drone's own) excepted: the path is blocked by
 * something seen since it was planned. */
int pl_segment_blocked(const og_grid *g, int32_t ax, int32_t ay, int32_t bx, int32_t by);

/* Path length in mm from a cost. */
static inline uint32_t pl_cost_mm(const og_grid *g, uint32_t cost)
{
    return (cost * (uint32_t)g->cell_mm + PL_STRAIGHT / 2) / PL_STRAIGHT;
}

#endif
