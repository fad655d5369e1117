/*
 * The round flight of Table 6 (§5.1: "go around the room, without
 * stopping") as the seed's Follower autopilot (§4.2.1.B): "keep following,
 * at a safe distance, the obstacle that is currently detecting at its
 * left", adjusting the speed to how close the obstacle ahead is.
 *
 * The yaw is held (the four rangers look along the body axes), so the
 * follower travels along one of the four body directions at a time; the
 * wall is on the left of the travel direction. It assumes walls roughly
 * along the body axes (take off aligned with the room, as in a lab):
 *   SEEK    fly forward until a wall is ahead, then turn right (the wall is
 *           now on the left) and start the loop there;
 *   FOLLOW  hold wall_mm to the left wall; a wall ahead: turn right (inner
 *           corner); the left wall lost (beyond 2 wall_mm): CORNER;
 *   CORNER  go on for wall_mm to clear the corner, turn left, REGAIN;
 *   REGAIN  fly until the wall shows on the left again (FOLLOW); if it does
 *           not within 2 wall_mm, turn left again.
 * The loop is closed when the drone is back within WF_CLOSE_MM of where it
 * started following, having flown at least WF_MIN_LOOP_MM. An obstacle the
 * four rangers miss (a thin leg beside the path) can hold the drone while
 * it commands motion: no WF_PROGRESS_MM of progress for stuck_ms counts as
 * a wall ahead (turn right).
 */
#ifndef EXPLORE_WALLFOLLOW_H
#define EXPLORE_WALLFOLLOW_H

#include <stdint.h>

#include "follow.h"

#define WF_CLOSE_MM 250
#define WF_MIN_LOOP_MM 2000
#define WF_PROGRESS_MM 50

enum { WF_SEEK, WF_FOLLOW, WF_CORNER, WF_REGAIN };
enum { WF_FLYING = 0, WF_LOOP_CLOSED = 1 };

typedef struct {
    int sub;
    int dir; /* travel direction: 0 front, 1 left, 2 back, 3 right */
    int looping;
    int32_t loop_x, loop_y; /* where the loop started */
    int32_t mark_x, mark_y; /* where CORNER / REGAIN started */
    int32_t last_x, last_y;
    uint32_t odo_mm;        /* flown since the loop started */
    int32_t prog_x, prog_y; /* last place of progress */
    uint32_t prog_t;
    uint32_t stuck_turns;
} wf_state;

typedef struct {
    uint32_t wall_mm, speed_mm_s, max_range_mm, stuck_ms;
} wf_params;

void wf_init(wf_state *w, uint32_t t_ms, int32_t x, int32_t y);

/* One step: ranges front, back, left, right (mm, 0 = no reading, read as
 * nothing seen); a body-frame velocity out. */
int wf_step(wf_state *w, const wf_params *p, uint32_t t_ms, int32_t x, int32_t y,
            const uint16_t ranges[4], fl_vel *body);

#endif
