/*
 * Unit checks of the frontier regions and goal choice, the planner and the
 * follower, on hand-made grids (expected values worked out in the comments;
 * costs in PL_STRAIGHT = 5 per cell side, PL_DIAGONAL = 7).
 */
#include <string.h>

#include "../explore.h"
#include "../fixmath.h"
#include "../follow.h"
#include "../frontier.h"
#include "../grid.h"
#include "../plan.h"
#include "selftest.h"

static og_grid g;
static fr_result fr;

static void grid(int32_t w, int32_t h, uint16_t cell_mm)
{
    explore_settings s;
    explore_default_settings(&s);
    s.x_min_mm = 0;
    s.y_min_mm = 0;
    s.x_max_mm = w * cell_mm;
    s.y_max_mm = h * cell_mm;
    s.cell_mm = cell_mm;
    char msg[160];
    CHECK(og_init(&g, &s, msg, sizeof msg) == EXPLORE_OK, "grid: %s", msg);
}

static void fill(int32_t x0, int32_t y0, int32_t x1, int32_t y1, int8_t l)
{
    for (int32_t y = y0; y <= y1; y++)
        for (int32_t x = x0; x <= x1; x++)
            og_set(&g, x, y, l);
}

static int idx(int32_t x, int32_t y) { return og_index(&g, x, y); }

void test_frontiers(void)
{
    /* 10 x 10 cells of 100 mm; the left half (x 0..4) free, the right
     * half unknown: one frontier region, the column x = 4 (10 cells),
     * centroid (450, 500). Its cells (4, 4) and (4, 5) are both 50 mm from
     * the centroid: the cheaper from the drone at cell (0, 0) wins, (4, 4)
     * at 4 diagonals = 28. */
    grid(10, 10, 100);
    fill(0, 0, 4, 9, -20);
    pl_inflate(&g, 0);
    CHECK_EQ("half-known: reached", pl_dijkstra(&g, 50, 50), 50);
    fr_detect(&g, 1, NULL, &fr);
    CHECK_EQ("half-known: frontier cells", fr.frontier_cells, 10);
    CHECK_EQ("half-known: regions", fr.n, 1);
    CHECK_EQ("half-known: region size", fr.r[0].count, 10);
    CHECK_EQ("half-known: centroid x", fr.r[0].cx_mm, 450);
    CHECK_EQ("half-known: centroid y", fr.r[0].cy_mm, 500);
    CHECK_EQ("half-known: best", fr.best, 0);
    CHECK_EQ("half-known: goal", fr.r[0].goal, idx(4, 4));
    CHECK_EQ("half-known: goal cost", fr.r[0].goal_cost, 28);

    /* Skip list: a visited goal at (450, 450) with 150 mm skips (4, 3),
     * (4, 4), (4, 5); of the rest (4, 6) is nearest the centroid (150 mm);
     * cost 4 diagonals + 2 straight = 38. */
    pl_point visited = {450, 450};
    fr_skip skip = {&visited, 1, 150};
    fr_detect(&g, 1, &skip, &fr);
    CHECK_EQ("skip: goal", fr.r[0].goal, idx(4, 6));
    CHECK_EQ("skip: cost", fr.r[0].goal_cost, 38);

    /* An obstacle at (4, 5) splits the frontier into x = 4, y 0..4 (5
     * cells, centroid (450, 250), goal (4, 2)) and y 6..9 (4 cells,
     * centroid (450, 800), goal (4, 8) over (4, 7) by cost). From cell
     * (0, 9): (4, 8) costs 1 diagonal + 3 straight = 22, (4, 2) costs 4
     * diagonals + 3 straight = 43: the upper region is the goal. */
    og_set(&g, 4, 5, 20);
    pl_inflate(&g, 0);
    pl_dijkstra(&g, 50, 950);
    fr_detect(&g, 1, NULL, &fr);
    CHECK_EQ("split: regions", fr.n, 2);
    CHECK(fr.r[0].count == 5 && fr.r[0].cx_mm == 450 && fr.r[0].cy_mm == 250,
          "split: lower region %d cells at (%ld, %ld)", fr.r[0].count, (long)fr.r[0].cx_mm,
          (long)fr.r[0].cy_mm);
    CHECK(fr.r[1].count == 4 && fr.r[1].cx_mm == 450 && fr.r[1].cy_mm == 800,
          "split: upper region %d cells at (%ld, %ld)", fr.r[1].count, (long)fr.r[1].cx_mm,
          (long)fr.r[1].cy_mm);
    CHECK(fr.r[0].goal == idx(4, 2) && fr.r[0].goal_cost == 43, "split: lower goal %ld cost %lu",
          (long)fr.r[0].goal, (unsigned long)fr.r[0].goal_cost);
    CHECK(fr.r[1].goal == idx(4, 8) && fr.r[1].goal_cost == 22, "split: upper goal %ld cost %lu",
          (long)fr.r[1].goal, (unsigned long)fr.r[1].goal_cost);
    CHECK_EQ("split: best", fr.best, 1);
    /* Regions shorter than the drone (5 cells here) are dropped. */
    fr_detect(&g, 5, NULL, &fr);
    CHECK(fr.n == 1 && fr.small == 1 && fr.best == 0 && fr.r[0].goal == idx(4, 2),
          "min size: n %d small %d best %d", fr.n, fr.small, fr.best);

    /* Unreachable frontier: zone 1 (x 0..2, y 0..8 free, y = 9 unknown)
     * holds the drone at (2, 0); a wall at x = 3; zone 2 (x 4..5 free,
     * x 6..9 unknown) is behind it. Zone 2's frontier (x = 5, centroid
     * (550, 500), 541 mm away) is nearer than zone 1's (y = 8, centroid
     * (150, 850), 806 mm) but unreachable: skipped, the goal is (1, 8) at
     * 1 diagonal + 7 straight = 42. */
    grid(10, 10, 100);
    fill(0, 0, 2, 8, -20);
    fill(3, 0, 3, 9, 20);
    fill(4, 0, 5, 9, -20);
    pl_inflate(&g, 0);
    CHECK_EQ("walled: reached", pl_dijkstra(&g, 250, 50), 27);
    fr_detect(&g, 1, NULL, &fr);
    CHECK_EQ("walled: regions", fr.n, 2);
    CHECK(fr.r[0].count == 10 && fr.r[0].goal == -1, "walled: zone 2 region %d cells, goal %ld",
          fr.r[0].count, (long)fr.r[0].goal);
    CHECK_EQ("walled: best", fr.best, 1);
    CHECK(fr.r[1].goal == idx(1, 8) && fr.r[1].goal_cost == 42, "walled: goal %ld cost %lu",
          (long)fr.r[1].goal, (unsigned long)fr.r[1].goal_cost);
    /* Only the unreachable frontier left: no goal, at once. */
    fill(0, 9, 2, 9, -20);
    pl_dijkstra(&g, 250, 50);
    fr_detect(&g, 1, NULL, &fr);
    CHECK(fr.n == 1 && fr.best == -1, "only unreachable: n %d best %d", fr.n, fr.best);
}

/* Blocked by the test's own geometry (not pl_flags): a cell centre within
 * r_mm of an occupied cell's centre. */
static int near_obstacle(int32_t ix, int32_t iy, int32_t r_mm)
{
    for (int32_t y = 0; y < g.h; y++)
        for (int32_t x = 0; x < g.w; x++)
            if (og_get(&g, x, y) > 0) {
                int32_t dx = (x - ix) * g.cell_mm, dy = (y - iy) * g.cell_mm;
                if (dx * dx + dy * dy <= r_mm * r_mm)
                    return 1;
            }
    return 0;
}

void test_planner(void)
{
    /* 20 x 20 cells of 50 mm, all free, a wall at x = 10 from y = 0 to 14,
     * inflated by 100 mm (2 cells): blocked x 8..12 for y <= 14, and
     * (9, 15), (10, 15), (11, 15), (10, 16): 79 cells; 321 reachable.
     * From (5, 5) to (15, 5) the path goes over the wall: straight up to
     * (5, 13), 4 diagonals to (9, 17) (no corner cutting past (8, 14)),
     * 2 straight to (11, 17), and the mirror image down: 2 (8 x 5 + 4 x 7)
     * + 2 x 5 = 146, i.e. 1460 mm. */
    grid(20, 20, 50);
    fill(0, 0, 19, 19, -20);
    fill(10, 0, 10, 14, 20);
    pl_inflate(&g, 100);
    int blocked = 0;
    for (int i = 0; i < 400; i++)
        blocked += (pl_flags[i] & PL_BLOCKED) != 0;
    CHECK_EQ("inflated cells", blocked, 79);
    uint64_t c0 = explore_cycles();
    int reached = pl_dijkstra(&g, og_cx(&g, 5), og_cy(&g, 5));
    uint64_t c1 = explore_cycles();
    CHECK_EQ("around: reached", reached, 321);
    int goal = idx(15, 5);
    CHECK_EQ("around: cost", pl_cost[goal], 146);
    pl_path path;
    CHECK(pl_path_to(&g, goal, &path), "around: path");
    uint64_t c2 = explore_cycles();
    CHECK_EQ("around: path cost", path.cost, 146);
    CHECK_EQ("around: path mm", pl_cost_mm(&g, path.cost), 1460);
    /* The raw path: from the start to the goal, one neighbour at a time,
     * never within 100 mm of the wall (checked from the geometry). */
    int bad = 0;
    for (uint32_t i = 0; i < path.cells; i++) {
        int c = pl_aux[i];
        if (near_obstacle(c % g.w, c / g.w, 100))
            bad++;
        if (i + 1 < path.cells) {
            int d = pl_aux[i + 1];
            if (fx_abs(c % g.w - d % g.w) > 1 || fx_abs(c / g.w - d / g.w) > 1)
                bad++;
        }
    }
    CHECK(bad == 0 && pl_aux[0] == goal && pl_aux[path.cells - 1] == idx(5, 5),
          "around: raw path of %lu cells has %d faults", (unsigned long)path.cells, bad);
    /* The waypoints: start and goal centres at the ends; every point of the
     * polyline (sampled every 5 mm) lies in a cell clear of the inflation;
     * its length is at most the grid path's and at least the bound through
     * the gap (x = 525, y >= 850): 2 sqrt(250^2 + 575^2) = 1254 mm. */
    CHECK(path.n >= 3 && path.wp[0].x_mm == 275 && path.wp[0].y_mm == 275 &&
              path.wp[path.n - 1].x_mm == 775 && path.wp[path.n - 1].y_mm == 275,
          "around: %d waypoints", path.n);
    uint32_t len = 0;
    bad = 0;
    for (int i = 0; i + 1 < path.n; i++) {
        pl_point a = path.wp[i], b = path.wp[i + 1];
        uint32_t d = fl_dist(a.x_mm, a.y_mm, b.x_mm, b.y_mm);
        len += d;
        for (uint32_t t = 0; t <= d; t += 5) {
            int32_t x = a.x_mm + (int32_t)((b.x_mm - a.x_mm) * (int32_t)t / (int32_t)d);
            int32_t y = a.y_mm + (int32_t)((b.y_mm - a.y_mm) * (int32_t)t / (int32_t)d);
            if (near_obstacle(x / 50, y / 50, 100))
                bad++;
        }
    }
    CHECK(bad == 0, "around: %d polyline samples in inflated cells", bad);
    CHECK(len >= 1254 && len <= 1460, "around: polyline %lu mm", (unsigned long)len);
    printf("planner around a wall: 20x20 cells, Dijkstra %lu cycles, path %lu cycles, "
           "%d waypoints, %lu mm\n",
           (unsigned long)(c1 - c0), (unsigned long)(c2 - c1), path.n, (unsigned long)len);
    /* An occupied cell is never a path's end. */
    CHECK(!pl_path_to(&g, idx(10, 5), &path), "path into the wall");

    /* Escape: from (9, 5), inside the inflation, the path leaves through
     * blocked cells (at 8 times the cost) and never enters one again. */
    pl_dijkstra(&g, og_cx(&g, 9), og_cy(&g, 5));
    CHECK(pl_path_to(&g, idx(5, 5), &path), "escape: path");
    int out = 0, reentered = 0;
    for (int i = (int)path.cells - 1; i >= 0; i--) {
        int blk = near_obstacle(pl_aux[i] % g.w, pl_aux[i] / g.w, 100);
        if (!blk)
            out = 1;
        else if (out)
            reentered = 1;
    }
    CHECK(out && !reentered, "escape: left the inflation once (%lu cells)",
          (unsigned long)path.cells);
    /* (9, 5) -> (8, 5), blocked: 8 x 5; then 3 straight to (5, 5). */
    CHECK_EQ("escape: cost", path.cost, 8 * 5 + 3 * 5);

    /* A gap of one cell (50 mm) in the wall is narrower than the drone:
     * the far side is unreachable. */
    fill(10, 0, 10, 19, 20);
    og_set(&g, 10, 10, -20);
    pl_inflate(&g, 100);
    pl_dijkstra(&g, og_cx(&g, 5), og_cy(&g, 5));
    CHECK(!(pl_flags[goal] & PL_REACHED) && !pl_path_to(&g, goal, &path), "narrow gap is closed");
    /* Without inflation the gap is passable, but only straight (no corner
     * cutting past (10, 9) or (10, 11)): (5, 5) to (9, 10) is 4 diagonals
     * + 1 straight = 33, through the gap to (11, 10) 10, and 33 down to
     * (15, 5): 76. */
    pl_inflate(&g, 0);
    pl_dijkstra(&g, og_cx(&g, 5), og_cy(&g, 5));
    CHECK_EQ("gap without inflation", pl_cost[goal], 76);
}

void test_follow(void)
{
    /* Yaw 90°: the world's +x is the body's right (-y). */
    fl_vel b = fl_world_to_body((fl_vel){200, 0}, 1571);
    CHECK(fx_abs(b.vx) <= 1 && b.vy == -200, "world to body: (%ld, %ld)", (long)b.vx, (long)b.vy);
    b = fl_world_to_body((fl_vel){0, 200}, 0);
    CHECK(b.vx == 0 && b.vy == 200, "world to body at yaw 0");

    /* Avoidance, threshold 100 mm, speed 200: front at 50 mm stops the
     * forward 200 and pushes back by 200 (100 - 50) / 100 = 100. */
    uint16_t r[4] = {50, 0, 1000, 300};
    fl_vel v = {200, 0};
    CHECK(fl_avoid(&v, r, 100, 200) && v.vx == -100 && v.vy == 0, "avoid front: (%ld, %ld)",
          (long)v.vx, (long)v.vy);
    /* Front at 95 mm: back off 10 mm/s, nearly still while it wanted 200:
     * side-step at 100 towards the freer side (left 1000 > right 300). */
    r[0] = 95;
    v = (fl_vel){200, 0};
    fl_avoid(&v, r, 100, 200);
    CHECK(v.vx == -10 && v.vy == 100, "side-step: (%ld, %ld)", (long)v.vx, (long)v.vy);
    /* Right at 60 mm while hovering: pushed left at 80. */
    uint16_t r2[4] = {0, 0, 0, 60};
    v = (fl_vel){0, 0};
    fl_avoid(&v, r2, 100, 200);
    CHECK(v.vx == 0 && v.vy == 80, "push from the right: (%ld, %ld)", (long)v.vx, (long)v.vy);
    /* Nothing near, or no readings: unchanged. */
    uint16_t r3[4] = {0, 500, 100, 2000};
    v = (fl_vel){150, -50};
    CHECK(!fl_avoid(&v, r3, 100, 200) && v.vx == 150 && v.vy == -50, "no avoidance");

    /* Map-based avoidance, radius 110 mm, speed 200, one occupied cell
     * (5, 5) centred at (275, 275). From 100 mm below, flying at it: the
     * approach is removed and the push is 200 (110 - 100) / 110 = 18. */
    grid(10, 10, 50);
    og_set(&g, 5, 5, 20);
    v = (fl_vel){0, 200};
    CHECK(fl_avoid_map(&g, 275, 175, 110, 200, &v) && v.vx == 0 && v.vy == -18,
          "map avoid below: (%ld, %ld)", (long)v.vx, (long)v.vy);
    /* Diagonally, 98 mm off (isqrt 9800), flying (100, 100) at it: the
     * approach, 142 along the diagonal, leaves (-1, -1); the push
     * 200 (110 - 98) / 110 = 21 adds 21 * 70 / 98 = 15 away on each axis. */
    v = (fl_vel){100, 100};
    CHECK(fl_avoid_map(&g, 205, 205, 110, 200, &v) && v.vx == -16 && v.vy == -16,
          "map avoid diagonal: (%ld, %ld)", (long)v.vx, (long)v.vy);
    /* 175 mm off: outside the radius, nothing. */
    v = (fl_vel){0, 200};
    CHECK(!fl_avoid_map(&g, 275, 100, 110, 200, &v) && v.vx == 0 && v.vy == 200, "map avoid far");

    /* Following (0,0) -> (1000,0) -> (1000,1000), goal tolerance 100,
     * waypoints passed within 20 mm (or within 100 mm once beyond them),
     * slowing over the last 400 mm. */
    fl_state f;
    memset(&f, 0, sizeof f);
    f.path.n = 3;
    f.path.wp[0] = (pl_point){0, 0};
    f.path.wp[1] = (pl_point){1000, 0};
    f.path.wp[2] = (pl_point){1000, 1000};
    f.next = 1;
    uint32_t rem;
    CHECK(fl_follow(&f, 0, 0, 200, 100, 20, 400, &v, &rem) == FL_MOVING && v.vx == 200 &&
              v.vy == 0 && rem == 2000,
          "follow start: (%ld, %ld) rem %lu", (long)v.vx, (long)v.vy, (unsigned long)rem);
    /* At (950, 0) the corner is 50 mm ahead, not passed: straight on. */
    fl_follow(&f, 950, 0, 200, 100, 20, 400, &v, &rem);
    CHECK(f.next == 1 && v.vx == 200 && v.vy == 0 && rem == 1050,
          "follow before the corner: (%ld, %ld)", (long)v.vx, (long)v.vy);
    /* At (960, 30), within 100 mm and beyond the square to the next leg
     * (dot (0, 1000).(-40, 30) > 0): passed, on to (1000, 1000), 970 mm
     * away (floor of 970.8): (40, 970) * 200 / 970 = (8, 200). */
    fl_follow(&f, 960, 30, 200, 100, 20, 400, &v, &rem);
    CHECK(f.next == 2 && v.vx == 8 && v.vy == 200 && rem == 970,
          "follow corner: (%ld, %ld) rem %lu", (long)v.vx, (long)v.vy, (unsigned long)rem);
    /* 200 mm before the goal: half speed. */
    fl_follow(&f, 1000, 800, 200, 100, 20, 400, &v, &rem);
    CHECK(v.vx == 0 && v.vy == 100, "follow slowing: (%ld, %ld)", (long)v.vx, (long)v.vy);
    CHECK(fl_follow(&f, 1000, 950, 200, 100, 20, 400, &v, &rem) == FL_ARRIVED && v.vx == 0 &&
              v.vy == 0,
          "follow arrived");
}
