/*
 * Self-test of the exploration firmware on the ISS: unit checks of the
 * inverse sensor model, frontiers, planner and follower on hand-made cases,
 * cycle measurements, and whole explorations of synthetic rooms (sim.c).
 * Exit status: the number of failed checks.
 */
#include "selftest.h"

int st_checks, st_failures;

int main(void)
{
    test_fixmath();
    test_settings();
    test_sensor_model();
    test_export();
    test_frontiers();
    test_planner();
    test_follow();
    bench_run();
    sim_run_all();
    printf("explore_selftest: %d checks, %d failures: %s\n", st_checks, st_failures,
           st_failures ? "FAIL" : "PASS");
    return st_failures;
}
