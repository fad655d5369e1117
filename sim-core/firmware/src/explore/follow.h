/*
 * Path following and reactive avoidance. The follower flies straight at
 * the next waypoint at the cruise speed (seed §5.1: 0.2 m/s), slowing down
 * linearly over the last `slow_mm` before the goal; the set-point goes out
 * in the body frame, as cflib's MotionCommander takes it (§4.2.1.B: "the
 * command contains velocities along the x and y axis and yaw rate").
 *
 * The map may lag the world (Yamauchi's point in §2.5.1: the robot "cannot
 * trust solely on its map"), so the ranges act directly: for each of the
 * four horizontal directions whose range is below the threshold, the
 * velocity towards it is removed and a push away is added, growing
 * linearly to the cruise speed at range 0; if that leaves the drone nearly
 * still while it wanted to move, it side-steps at half speed towards the
 * freer perpendicular side.
 */
#ifndef EXPLORE_FOLLOW_H
#define EXPLORE_FOLLOW_H

#include <stdint.h>

#include "plan.h"

typedef struct {
    int32_t vx, vy; /* mm/s */
} fl_vel;

/* World-frame velocity to body frame for a yaw (mrad). */
fl_vel fl_world_to_body(fl_vel v, int32_t yaw_mrad);

/* Applies the reactive avoidance to a body-frame velocity. ranges: front,
 * back, left, right (mm, 0 = no reading); returns 1 if it acted. */
int fl_avoid(fl_vel *v, const uint16_t ranges[4], uint32_t avoid_mm, uint32_t speed);

/* The same from the map, for what the four rangers cannot see (an obstacle
 * diagonally ahead): for each occupied cell whose centre is within
 * radius_mm of (x, y), the world-frame velocity towards it is removed; the
 * pushes away (growing linearly to the cruise speed at distance 0) are
 * summed and capped at half the cruise speed. Acts only when the drone is
 * inside the inflation (the map changed around it, or it was pushed there);
 * returns 1 if it acted. */
int fl_avoid_map(const og_grid *g, int32_t x, int32_t y, uint32_t radius_mm, uint32_t speed,
                 fl_vel *v);

typedef struct {
    pl_path path;
    int next; /* waypoint being flown to */
} fl_state;

enum { FL_MOVING = 0, FL_ARRIVED = 1 };

/* One step along the path from (x, y): a world-frame velocity towards the
 * next waypoint. An intermediate waypoint is passed when the drone is
 * within pass_mm of it, or within tol_mm and already beyond the line
 * through it square to the next leg: waypoints sit at obstacle corners, so
 * passing them early would cut the corner. Returns FL_ARRIVED when the last
 * waypoint is within tol_mm; *remaining_mm is the distance left along the
 * waypoints. */
int fl_follow(fl_state *f, int32_t x, int32_t y, uint32_t speed, uint32_t tol_mm, uint32_t pass_mm,
              uint32_t slow_mm, fl_vel *out, uint32_t *remaining_mm);

/* Euclidean distance (mm) between two points. */
uint32_t fl_dist(int32_t ax, int32_t ay, int32_t bx, int32_t by);

#endif
