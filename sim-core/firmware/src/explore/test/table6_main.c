/*
 * Table 6 of seed 004 (§5.1) in the synthetic seed room: the round flight
 * ("take-off; go around the room, without stopping; land in starting
 * position") at cell sizes 2, 5 and 8 cm and FOV parameters 2, 5 and 10°,
 * reporting coverage, accuracy, the number of cells and the flight time as
 * the table does, plus the cycles. 2 cm cells do not fit the room in the
 * memory budget: those rows report explore_init's error. Exit status: the
 * number of failed checks (every flight that fits ends at its start,
 * without a collision).
 */
#include "../explore.h"
#include "selftest.h"
#include "sim.h"

int st_checks, st_failures;

int main(void)
{
    static const uint16_t cells[3] = {20, 50, 80};
    static const uint16_t fovs[3] = {200, 500, 1000};
    for (int c = 0; c < 3; c++) {
        for (int v = 0; v < 3; v++) {
            explore_settings s;
            sim_seed_settings(&s);
            s.mode = EXPLORE_MODE_ROUND;
            s.cell_mm = cells[c];
            s.fov_cdeg = fovs[v];
            int rc = explore_init(&s);
            if (rc != EXPLORE_OK) {
                printf("table6: cell %u mm, fov %u deg: %s\n", cells[c], fovs[v] / 100,
                       explore_last_error());
                CHECK(rc == EXPLORE_E_BUDGET && cells[c] == 20, "unexpected error %d", rc);
                continue;
            }
            flight f = sim_fly(&sim_seed_room, &s, 3000, 0);
            sim_report("table6", &sim_seed_room, &s, &f);
            CHECK(f.done && f.collisions == 0 && f.end_dist_home <= 200,
                  "cell %u fov %u: done %d, collisions %lu, %ld mm from home", cells[c], fovs[v],
                  f.done, (unsigned long)f.collisions, (long)f.end_dist_home);
        }
    }
    printf("explore_table6: %d checks, %d failures: %s\n", st_checks, st_failures,
           st_failures ? "FAIL" : "PASS");
    return st_failures;
}
