/*
 * Frontier detection and goal selection (seed §2.5.1, Yamauchi 1997;
 * Algorithm 2 of §4.2.1.B): a frontier cell is a free cell with an unknown
 * 4-neighbour inside the grid; frontier cells are grouped into regions
 * (8-connected); regions shorter than the drone's size are dropped; each
 * region's centroid is the mean of its cells' centres.
 *
 * The goal (Algorithm 2 step 7, "closest centroid"): closest by PATH LENGTH
 * on the grid, from the Dijkstra of plan.c run at the drone's position. A
 * centroid itself may lie in unknown space or off the region (a curved
 * frontier), so each region's goal cell is the region cell closest to the
 * centroid (Euclidean) among those the drone can stop in: reached by the
 * Dijkstra, not blocked, and not within `skip_mm` of a point on the skip
 * list (goals already visited or found unreachable). A region without such a
 * cell is skipped, so an unreachable frontier never stalls the search. The
 * goal is the region whose goal cell has the smallest path cost; ties go to
 * the region found first (row-major scan), so the choice is deterministic.
 */
#ifndef EXPLORE_FRONTIER_H
#define EXPLORE_FRONTIER_H

#include <stdint.h>

#include "grid.h"
#include "plan.h"

#define FR_MAX_REGIONS 128

typedef struct {
    uint16_t first, count; /* the region's cells: pl_queue[first .. first + count) */
    int32_t cx_mm, cy_mm;  /* centroid */
    int32_t goal;          /* goal cell index, -1 if none */
    uint32_t goal_cost;    /* path cost to the goal cell (PL_* units) */
} fr_region;

typedef struct {
    fr_region r[FR_MAX_REGIONS];
    int n;       /* regions recorded (at least min_cells long) */
    int dropped; /* regions past FR_MAX_REGIONS (not considered) */
    int small;   /* regions shorter than min_cells */
    int frontier_cells;
    int best; /* index of the chosen region, -1 if none */
} fr_result;

typedef struct {
    const pl_point *pts;
    int n;
    uint32_t skip_mm;
} fr_skip;

/* Detects the regions and chooses the goal. Needs pl_dijkstra to have run
 * (for the costs; on a grid without Dijkstra, call pl_inflate and
 * pl_dijkstra first anyway). min_cells: the shortest region kept. */
void fr_detect(const og_grid *g, int min_cells, const fr_skip *skip, fr_result *out);

#endif
