/*
 * The self-test's flights (sim.c): an unreachable frontier seen through a
 * slot, Table 6's round flight, an obstacle appearing ahead of the drone,
 * and §5.2's exploration of the seed room.
 */
#include "../explore.h"
#include "selftest.h"
#include "sim.h"

void sim_run_all(void)
{
    explore_settings s;

    /* The unreachable room: the run ends by itself, well inside the
     * budget, without a collision, having mapped the first room. */
    explore_default_settings(&s);
    s.x_min_mm = -200;
    s.y_min_mm = -200;
    s.x_max_mm = 4200;
    s.y_max_mm = 2200;
    flight f = sim_fly(&sim_slot_rooms, &s, 3000, 0);
    sim_report("explore", &sim_slot_rooms, &s, &f);
    CHECK(f.done && f.t_ms < s.time_budget_ms, "slot rooms: not done in time");
    CHECK(f.st.regions_unreachable > 0, "slot rooms: no unreachable frontier was seen");
    CHECK_EQ("slot rooms: collisions", f.collisions, 0);
    CHECK(f.q.covered * 100 >= 90 * f.q.truth_free, "slot rooms: coverage %ld of %ld",
          (long)f.q.covered, (long)f.q.truth_free);

    /* The round flight from a take-off beside a wall: home is inside the
     * inflation, the drone lands at the nearest cell it can stop in, within
     * the inflation (150 mm) and the goal tolerance (100 mm) of home. */
    explore_default_settings(&s);
    s.mode = EXPLORE_MODE_ROUND;
    s.x_min_mm = -200;
    s.y_min_mm = -200;
    s.x_max_mm = 1700;
    s.y_max_mm = 1700;
    f = sim_fly(&sim_small_room, &s, 3000, 0);
    sim_report("round", &sim_small_room, &s, &f);
    CHECK(f.done && f.t_ms < s.time_budget_ms, "small room: not done in time");
    CHECK_EQ("small room: collisions", f.collisions, 0);
    CHECK(f.end_dist_home <= 250 && f.st.goals_failed == 0,
          "small room: landed %ld mm from the start", (long)f.end_dist_home);

    /* Table 6's flight: around the room along the walls, land at the start. */
    sim_seed_settings(&s);
    s.mode = EXPLORE_MODE_ROUND;
    f = sim_fly(&sim_seed_room, &s, 3000, 0);
    sim_report("round", &sim_seed_room, &s, &f);
    CHECK(f.done, "round: not done");
    CHECK_EQ("round: collisions", f.collisions, 0);
    CHECK(f.end_dist_home <= 200, "round: landed %ld mm from the start", (long)f.end_dist_home);

    /* The time budget: 40 s is not enough for the room; the drone lands
     * when it is spent (landing from 300 mm takes about a second). */
    sim_seed_settings(&s);
    s.time_budget_ms = 40000;
    f = sim_fly(&sim_seed_room, &s, 3000, 0);
    sim_report("explore, 40 s budget", &sim_seed_room, &s, &f);
    CHECK(f.done && f.t_ms >= 40000 && f.t_ms <= 42000, "budget: done %d at %lu ms", f.done,
          (unsigned long)f.t_ms);
    CHECK_EQ("budget: collisions", f.collisions, 0);

    /* A box put down just ahead of the flying drone: the avoidance backs it
     * off and side-steps, the map learns the box, the path goes round. */
    sim_seed_settings(&s);
    f = sim_fly(&sim_seed_room_late_box, &s, 3000, 0);
    sim_report("explore", &sim_seed_room_late_box, &s, &f);
    CHECK(f.done, "late box: not done");
    CHECK_EQ("late box: collisions", f.collisions, 0);
    CHECK(f.st.avoid_steps > 0, "late box: the avoidance never acted");
    CHECK(f.q.covered * 100 >= 90 * f.q.truth_free, "late box: coverage %ld of %ld",
          (long)f.q.covered, (long)f.q.truth_free);

    /* §5.2's exploration: 5 cm cells, FOV 4°, ranges capped at 3 m. Last,
     * so that its map stays in explore_map_image for the platform test. */
    sim_seed_settings(&s);
    f = sim_fly(&sim_seed_room, &s, 3000, 1);
    sim_report("explore", &sim_seed_room, &s, &f);
    CHECK(f.done, "explore: not done");
    CHECK_EQ("explore: collisions", f.collisions, 0);
    CHECK(f.q.covered * 100 >= 90 * f.q.truth_free, "explore: coverage %ld of %ld",
          (long)f.q.covered, (long)f.q.truth_free);
    uint32_t len;
    explore_map_export(&len);
    printf(
        "map image: %lu bytes, observed %ld of %ld free cells (%ld mapped free), accuracy %ld of "
        "%ld\n",
        (unsigned long)len, (long)f.q.covered, (long)f.q.truth_free, (long)f.q.covered_free,
        (long)f.q.correct, (long)f.q.judged);
}
