/* The synthetic rooms and the simulated drone of the self-tests (sim.c). */
#ifndef EXPLORE_SIM_H
#define EXPLORE_SIM_H

#include <stdint.h>

#include "../explore.h"

typedef struct {
    int32_t x0, y0, x1, y1;
} rect;

typedef struct {
    const char *name;
    const rect *rects;
    int nrects;
    rect interior; /* the room's inside, for the truth */
    int32_t start_x, start_y;
    /* The last nlate rectangles appear at late_ms (someone puts a box down
     * in front of the drone: Yamauchi's case for reactive avoidance). */
    int nlate;
    uint32_t late_ms;
} world;

typedef struct {
    int32_t truth_free, covered, covered_free, judged, correct;
} quality;

typedef struct {
    quality q;
    uint32_t steps, t_ms, collisions;
    int done;
    explore_stats st;
    double flown_mm, end_dist_home;
} flight;

extern const world sim_seed_room, sim_slot_rooms, sim_seed_room_late_box, sim_small_room;

/* The seed room's settings: the defaults, with the room and 200 mm around. */
void sim_seed_settings(explore_settings *s);

/* One flight from take-off to DONE (or the budget and 60 s more), at the
 * seed's 100 ms period, rangers capped at max_mm. verbose: print goals. */
flight sim_fly(const world *w, const explore_settings *s, uint16_t max_mm, int verbose);

/* "flight ..." and "cycles ..." report lines. */
void sim_report(const char *what, const world *w, const explore_settings *s, const flight *f);

#endif
