/*
 * Cycle measurements (the core's mcycle) of one mapping update and of one
 * planning step at the seed's cell sizes and FOVs (Table 6) and at a few
 * grid sizes. Printed as "cycles ..." lines for the platform test's report.
 */
#include <string.h>

#include "../explore.h"
#include "../frontier.h"
#include "../grid.h"
#include "../plan.h"
#include "selftest.h"

static og_grid g;
static fr_result fr;

static int area(int32_t half_mm, uint16_t cell_mm, uint16_t fov_cdeg)
{
    explore_settings s;
    explore_default_settings(&s);
    s.x_min_mm = -half_mm;
    s.y_min_mm = -half_mm;
    s.x_max_mm = half_mm;
    s.y_max_mm = half_mm;
    s.cell_mm = cell_mm;
    s.fov_cdeg = fov_cdeg;
    char msg[160];
    int rc = og_init(&g, &s, msg, sizeof msg);
    CHECK(rc == EXPLORE_OK, "bench grid: %s", msg);
    return rc == EXPLORE_OK;
}

/* Mean cycles of og_update over four yaws (0°, 20°, 45°, 70°), all four
 * ranges at range_mm, max 3000 mm. */
static void map_case(int32_t half_mm, uint16_t cell_mm, uint16_t fov_cdeg, uint16_t range_mm)
{
    if (!area(half_mm, cell_mm, fov_cdeg))
        return;
    static const int32_t yaws[4] = {0, 349, 785, 1222};
    uint64_t total = 0;
    int cells = 0;
    for (int k = 0; k < 4; k++) {
        explore_input in = {
            .x_mm = 0, .y_mm = 0, .z_mm = 300, .yaw_mrad = yaws[k], .max_range_mm = 3000};
        for (int r = 0; r < 4; r++)
            in.range_mm[r] = range_mm;
        uint64_t c0 = explore_cycles();
        cells += og_update(&g, &in);
        total += explore_cycles() - c0;
    }
    printf("cycles map: grid %ldx%ld, cell %u mm, fov %u.%02u deg, ranges %u mm: %lu per update, "
           "%d cells per update\n",
           (long)g.w, (long)g.h, cell_mm, fov_cdeg / 100, fov_cdeg % 100, range_mm,
           (unsigned long)(total / 4), cells / 4);
}

/* A known square room with an unknown one-cell border (the frontier) and
 * two walls; the drone in the middle. One planning step as the explorer
 * does it: inflate, Dijkstra, frontiers and goal, path. */
static void plan_case(int32_t half_mm, uint16_t cell_mm)
{
    if (!area(half_mm, cell_mm, 400))
        return;
    for (int32_t iy = 1; iy < g.h - 1; iy++)
        for (int32_t ix = 1; ix < g.w - 1; ix++)
            og_set(&g, ix, iy, -20);
    for (int32_t i = g.h / 4; i < g.h * 3 / 4; i++) {
        og_set(&g, g.w / 3, i, 20);
        og_set(&g, g.w * 2 / 3, g.h - 1 - i, 20);
    }
    uint64_t c0 = explore_cycles();
    pl_inflate(&g, 150);
    uint64_t c1 = explore_cycles();
    int reached = pl_dijkstra(&g, 0, 0);
    uint64_t c2 = explore_cycles();
    fr_skip none = {NULL, 0, 0};
    fr_detect(&g, 3, &none, &fr);
    uint64_t c3 = explore_cycles();
    pl_path p;
    int ok = fr.best >= 0 && pl_path_to(&g, fr.r[fr.best].goal, &p);
    uint64_t c4 = explore_cycles();
    CHECK(ok, "bench plan %ldx%ld: a goal", (long)g.w, (long)g.h);
    printf("cycles plan: grid %ldx%ld, cell %u mm: inflate %lu, dijkstra %lu (%d cells), frontiers "
           "%lu (%d regions), path %lu; total %lu\n",
           (long)g.w, (long)g.h, cell_mm, (unsigned long)(c1 - c0), (unsigned long)(c2 - c1),
           reached, (unsigned long)(c3 - c2), fr.n, (unsigned long)(c4 - c3),
           (unsigned long)(c4 - c0));
}

void bench_run(void)
{
    /* Table 6's cells and FOVs; 20 mm cells fit 3.2 x 3.2 m in the budget. */
    static const uint16_t fovs[3] = {200, 500, 1000};
    map_case(1600, 20, 200, 1500);
    map_case(1600, 20, 500, 1500);
    map_case(1600, 20, 1000, 1500);
    for (int i = 0; i < 3; i++)
        map_case(4000, 50, fovs[i], 1500);
    map_case(4000, 50, 400, 1500);
    map_case(4000, 50, 400, 3000);
    for (int i = 0; i < 3; i++)
        map_case(4000, 80, fovs[i], 1500);
    map_case(4000, 80, 500, 3000);
    plan_case(1000, 50);
    plan_case(2000, 50);
    plan_case(4000, 50);
    plan_case(4000, 80);
}
