/*
 * The exploration state machine (seed §5.2: take off, 360° scan, frontier
 * goal, fly there, repeat; land when no goal is left) and the round flight
 * of Table 6 (§5.1: take off, go around the room without stopping, land at
 * the start). See explore.h for the boundary and docs/EXPLORE.md.
 */
#include <string.h>

#include "explore.h"
#include "fixmath.h"
#include "follow.h"
#include "frontier.h"
#include "grid.h"
#include "plan.h"
#include "wallfollow.h"

#if defined(__riscv)
#include "../cycles.h"
#endif

/* Visited and failed goals: frontier cells near them are skipped. A ring:
 * with more goals than this the oldest zones lapse (the time budget still
 * ends the run). */
#define EX_MAX_SKIP 128
/* Progress smaller than this does not reset the stuck timer. */
#define EX_PROGRESS_MM 50
/* A blocked segment ahead forces a re-plan, at most this often. */
#define EX_BLOCKED_REPLAN_MS 500
/* The round flight lands this close to the take-off point at most. */
#define EX_HOME_SEARCH_MM 500
/* One full turn for the scan, in mrad (2 pi). */
#define EX_TURN_MRAD 6283

static struct {
    explore_settings s;
    og_grid g;
    explore_state st;
    int inited, started;
    char err[160];
    explore_stats stats;
    uint32_t t0;
    int32_t home_x, home_y;
    int32_t last_yaw;
    uint32_t last_t;
    int32_t scan_acc; /* mrad turned in this scan */
    /* Current goal and path. */
    int goal; /* cell index */
    int32_t goal_x, goal_y;
    fl_state fl;
    uint32_t plan_ms;
    uint32_t best_rem, best_ms;
    pl_point skip[EX_MAX_SKIP];
    int nskip, skip_next;
    fr_result fr;
    wf_state wf;
} explorer;

void explore_default_settings(explore_settings *s)
{
    memset(s, 0, sizeof *s);
    s->mode = EXPLORE_MODE_FRONTIER;
    /* 8 x 8 m around the take-off point (the flow deck's origin), at the
     * seed's 5 cm cells (§5.2): exactly EXPLORE_MAX_CELLS. */
    s->x_min_mm = -4000;
    s->y_min_mm = -4000;
    s->x_max_mm = 4000;
    s->y_max_mm = 4000;
    s->cell_mm = 50;
    s->fov_cdeg = 400; /* §5.2: FOV parameter 4.0° */
    /* ln(0.65/0.35) = 0.62 nat per observation, the example the seed's
     * implementation follows (§4.2.1.A, footnote 9). Clamped at p = 0.12
     * and 0.97 (-2.0 and +3.5 nat), OctoMap's clamping thresholds (Hornung
     * et al. 2013), so that the map follows a changed room: a cell long
     * seen free turns occupied after 4 hits, not 11. */
    s->l_occ = 10;
    s->l_free = -10;
    s->l_min = -32;
    s->l_max = 56;
    /* Crazyflie 2.1: 92 mm motor to motor diagonally, 45 mm propellers:
     * about 70 mm from the centre to a propeller tip. */
    s->drone_radius_mm = 70;
    s->margin_mm = 80;
    s->min_frontier_mm = 140; /* Yamauchi: "roughly the size of the robot" */
    s->speed_mm_s = 200;      /* §5.1: "flying at 0,2 m/s" */
    s->height_mm = 300;       /* cflib MotionCommander's default height */
    s->scan_rate_mrad_s = 500;
    s->avoid_mm = 100;
    s->goal_tol_mm = 100;
    s->wall_mm = 400;
    s->visited_mm = 300;
    s->time_budget_ms = 300000;
    s->stuck_ms = 10000;
    s->replan_ms = 2000;
}

int explore_init(const explore_settings *s)
{
    memset(&explorer, 0, sizeof explorer);
    explorer.s = *s;
    int rc = og_init(&explorer.g, s, explorer.err, sizeof explorer.err);
    if (rc == EXPLORE_OK && (!s->speed_mm_s || !s->height_mm || !s->goal_tol_mm ||
                             !s->scan_rate_mrad_s || !s->wall_mm || !s->stuck_ms)) {
        rc = EXPLORE_E_MOTION;
        strcpy(explorer.err, "explore: speed, height, goal tolerance, scan rate, wall distance and "
                             "stuck time must be > 0");
    }
    explorer.st = rc == EXPLORE_OK ? EXPLORE_ST_GROUND : EXPLORE_ST_ERROR;
    explorer.inited = rc == EXPLORE_OK;
    return rc;
}

const char *explore_last_error(void) { return explorer.err; }
const explore_stats *explore_get_stats(void) { return &explorer.stats; }

const uint8_t *explore_map_export(uint32_t *len) { return og_export(&explorer.g, len); }

uint64_t explore_cycles(void)
{
#if defined(__riscv)
    return csr_mcycle64();
#else
    return 0;
#endif
}

static void skip_add(int32_t x, int32_t y)
{
    explorer.skip[explorer.skip_next] = (pl_point){x, y};
    explorer.skip_next = (explorer.skip_next + 1) % EX_MAX_SKIP;
    if (explorer.nskip < EX_MAX_SKIP)
        explorer.nskip++;
}

static uint32_t inflation_mm(void)
{
    return (uint32_t)explorer.s.drone_radius_mm + explorer.s.margin_mm;
}

/* Intermediate waypoints are passed within half a cell (at least 20 mm). */
static uint32_t pass_mm(void) { return (uint32_t)fx_max(explorer.g.half_mm, 20); }

static void start_follow(const explore_input *in)
{
    explorer.fl.next = 1;
    explorer.plan_ms = in->t_ms;
    fl_vel v;
    uint32_t rem;
    fl_follow(&explorer.fl, in->x_mm, in->y_mm, explorer.s.speed_mm_s, explorer.s.goal_tol_mm,
              pass_mm(), 0, &v, &rem);
    explorer.best_rem = rem;
}

/* Algorithm 2 with the planner: a new frontier goal and the path to it.
 * Returns 0 if no frontier goal is left. */
static int plan_goal(const explore_input *in)
{
    uint64_t c0 = explore_cycles();
    pl_inflate(&explorer.g, inflation_mm());
    pl_dijkstra(&explorer.g, in->x_mm, in->y_mm);
    int min_cells = (explorer.s.min_frontier_mm + explorer.g.cell_mm - 1) / explorer.g.cell_mm;
    fr_skip skip = {explorer.skip, explorer.nskip, explorer.s.visited_mm};
    fr_detect(&explorer.g, min_cells > 0 ? min_cells : 1, &skip, &explorer.fr);
    int ok = explorer.fr.best >= 0;
    for (int i = 0; i < explorer.fr.n; i++)
        explorer.stats.regions_unreachable += explorer.fr.r[i].goal < 0;
    if (ok) {
        explorer.goal = explorer.fr.r[explorer.fr.best].goal;
        explorer.goal_x = og_cx(&explorer.g, explorer.goal % explorer.g.w);
        explorer.goal_y = og_cy(&explorer.g, explorer.goal / explorer.g.w);
        pl_path_to(&explorer.g, explorer.goal, &explorer.fl.path);
        explorer.stats.goals++;
    }
    explorer.stats.plans++;
    explorer.stats.plan_cycles += explore_cycles() - c0;
    if (ok) {
        start_follow(in);
        explorer.best_ms = in->t_ms;
    }
    return ok;
}

/* A new path to the current goal cell. Returns 0 if it is unreachable. */
static int replan_path(const explore_input *in)
{
    uint64_t c0 = explore_cycles();
    pl_inflate(&explorer.g, inflation_mm());
    pl_dijkstra(&explorer.g, in->x_mm, in->y_mm);
    int ok = pl_goal_ok(&explorer.g, explorer.goal) &&
             pl_path_to(&explorer.g, explorer.goal, &explorer.fl.path);
    explorer.stats.plans++;
    explorer.stats.plan_cycles += explore_cycles() - c0;
    if (ok)
        start_follow(in); /* keeps best_ms: re-planning is not progress */
    return ok;
}

static void set_velocity(explore_output *out, const explore_input *in, fl_vel world)
{
    /* Inside the inflation (well inside: half the margin), keep off the
     * mapped obstacles the rangers may not see. */
    uint32_t inside = explorer.s.drone_radius_mm + explorer.s.margin_mm / 2u;
    if (fl_avoid_map(&explorer.g, in->x_mm, in->y_mm, inside, explorer.s.speed_mm_s, &world))
        explorer.stats.map_avoid_steps++;
    fl_vel b = fl_world_to_body(world, in->yaw_mrad);
    const uint16_t r[4] = {in->range_mm[EXPLORE_FRONT], in->range_mm[EXPLORE_BACK],
                           in->range_mm[EXPLORE_LEFT], in->range_mm[EXPLORE_RIGHT]};
    if (fl_avoid(&b, r, explorer.s.avoid_mm, explorer.s.speed_mm_s))
        explorer.stats.avoid_steps++;
    out->cmd = EXPLORE_CMD_VELOCITY;
    out->vx_mm_s = b.vx;
    out->vy_mm_s = b.vy;
}

/* A 360° scan where the drone is; its place joins the skip list, so that
 * frontier cells left within visited_mm of it (ones the scan could not
 * resolve) do not bring the drone back. */
static void begin_scan(const explore_input *in)
{
    skip_add(in->x_mm, in->y_mm);
    explorer.st = EXPLORE_ST_SCAN;
    explorer.scan_acc = 0;
    explorer.last_yaw = in->yaw_mrad;
}

/* After a scan, or when a goal is given up: the next goal, or land. */
static void next_goal(const explore_input *in, explore_output *out)
{
    if (plan_goal(in)) {
        explorer.st = EXPLORE_ST_FOLLOW;
        out->new_goal = 1;
    } else {
        explorer.st = EXPLORE_ST_LAND;
    }
}

static void fail_goal(const explore_input *in, explore_output *out)
{
    explorer.stats.goals_failed++;
    skip_add(explorer.goal_x, explorer.goal_y);
    if (explorer.st == EXPLORE_ST_HOME)
        explorer.st = EXPLORE_ST_LAND;
    else
        next_goal(in, out);
}

/* FOLLOW and HOME: fly the path; returns 1 on arrival. */
static int fly_path(const explore_input *in, explore_output *out)
{
    uint32_t t = in->t_ms;
    int next = explorer.fl.next < explorer.fl.path.n ? explorer.fl.next : explorer.fl.path.n - 1;
    int32_t ax, ay, bx, by;
    int blocked = explorer.fl.path.n > 0 && og_cell_of(&explorer.g, in->x_mm, in->y_mm, &ax, &ay) &&
                  og_cell_of(&explorer.g, explorer.fl.path.wp[next].x_mm,
                             explorer.fl.path.wp[next].y_mm, &bx, &by) &&
                  pl_segment_blocked(&explorer.g, ax, ay, bx, by);
    if ((t - explorer.plan_ms >= explorer.s.replan_ms) ||
        (blocked && t - explorer.plan_ms >= EX_BLOCKED_REPLAN_MS)) {
        if (!replan_path(in)) {
            fail_goal(in, out);
            return 0;
        }
    }
    fl_vel v;
    uint32_t rem;
    int r = fl_follow(&explorer.fl, in->x_mm, in->y_mm, explorer.s.speed_mm_s,
                      explorer.s.goal_tol_mm, pass_mm(), 2u * explorer.s.speed_mm_s, &v, &rem);
    if (r == FL_ARRIVED) {
        if (explorer.fl.path.truncated) {
            if (!replan_path(in))
                fail_goal(in, out);
            return 0;
        }
        return 1;
    }
    if (rem + EX_PROGRESS_MM < explorer.best_rem) {
        explorer.best_rem = rem;
        explorer.best_ms = t;
    } else if (t - explorer.best_ms >= explorer.s.stuck_ms) {
        fail_goal(in, out);
        return 0;
    }
    set_velocity(out, in, v);
    return 0;
}

/* Where to land at the end of the round flight: the take-off cell, or, if
 * the drone cannot stop there (inside the inflation: a take-off close to a
 * wall), the reachable cell nearest to it within EX_HOME_SEARCH_MM. -1 if
 * none. Needs pl_dijkstra. */
static int home_cell(void)
{
    const og_grid *g = &explorer.g;
    int32_t hx, hy;
    if (!og_cell_of(g, explorer.home_x, explorer.home_y, &hx, &hy))
        return -1;
    int32_t r = EX_HOME_SEARCH_MM / g->cell_mm;
    int best = -1;
    int32_t best_d2 = 0;
    for (int32_t iy = fx_max(0, hy - r); iy <= fx_min(g->h - 1, hy + r); iy++) {
        for (int32_t ix = fx_max(0, hx - r); ix <= fx_min(g->w - 1, hx + r); ix++) {
            int idx = og_index(g, ix, iy);
            int32_t d2 = (ix - hx) * (ix - hx) + (iy - hy) * (iy - hy);
            if (d2 <= r * r && pl_goal_ok(g, idx) && (best < 0 || d2 < best_d2)) {
                best = idx;
                best_d2 = d2;
            }
        }
    }
    return best;
}

static void go_home(const explore_input *in)
{
    uint64_t c0 = explore_cycles();
    pl_inflate(&explorer.g, inflation_mm());
    pl_dijkstra(&explorer.g, in->x_mm, in->y_mm);
    int home = home_cell();
    int ok = home >= 0;
    if (ok) {
        explorer.goal = home;
        explorer.goal_x = og_cx(&explorer.g, home % explorer.g.w);
        explorer.goal_y = og_cy(&explorer.g, home / explorer.g.w);
        ok = pl_path_to(&explorer.g, home, &explorer.fl.path);
    }
    explorer.stats.plans++;
    explorer.stats.plan_cycles += explore_cycles() - c0;
    if (ok) {
        start_follow(in);
        explorer.best_ms = in->t_ms;
        explorer.st = EXPLORE_ST_HOME;
    } else {
        explorer.st = EXPLORE_ST_LAND;
    }
}

static int airborne(explore_state st)
{
    return st == EXPLORE_ST_SCAN || st == EXPLORE_ST_FOLLOW || st == EXPLORE_ST_ROUND ||
           st == EXPLORE_ST_HOME;
}

void explore_step(const explore_input *in, explore_output *out)
{
    memset(out, 0, sizeof *out);
    explorer.stats.steps++;
    out->z_mm = explorer.s.height_mm;
    if (!explorer.inited) {
        out->cmd = EXPLORE_CMD_LAND;
        out->state = EXPLORE_ST_ERROR;
        return;
    }
    if (!explorer.started) {
        explorer.started = 1;
        explorer.t0 = in->t_ms;
        explorer.home_x = in->x_mm;
        explorer.home_y = in->y_mm;
        explorer.last_yaw = in->yaw_mrad;
        explorer.stats.start_ms = in->t_ms;
    }
    explorer.stats.end_ms = in->t_ms;
    /* The map is a 2D slice at the flight height (§4.2.1.A): update it only
     * there. */
    if (airborne(explorer.st) && in->z_mm >= (int32_t)explorer.s.height_mm / 2) {
        uint64_t c0 = explore_cycles();
        og_update(&explorer.g, in);
        explorer.stats.map_cycles += explore_cycles() - c0;
        explorer.stats.map_updates++;
    }
    if (airborne(explorer.st) && in->t_ms - explorer.t0 >= explorer.s.time_budget_ms)
        explorer.st = EXPLORE_ST_LAND;

    switch (explorer.st) {
    case EXPLORE_ST_GROUND:
        explorer.st = EXPLORE_ST_TAKEOFF;
        /* fall through */
    case EXPLORE_ST_TAKEOFF:
        out->cmd = EXPLORE_CMD_TAKEOFF;
        if (in->z_mm >= (int32_t)explorer.s.height_mm * 9 / 10) {
            if (explorer.s.mode == EXPLORE_MODE_ROUND) {
                explorer.st = EXPLORE_ST_ROUND;
                wf_init(&explorer.wf, in->t_ms, in->x_mm, in->y_mm);
            } else {
                begin_scan(in);
            }
        }
        break;
    case EXPLORE_ST_SCAN: {
        explorer.scan_acc += fx_abs(fx_mrad_diff(in->yaw_mrad, explorer.last_yaw));
        out->cmd = EXPLORE_CMD_VELOCITY;
        int32_t left = EX_TURN_MRAD - explorer.scan_acc;
        /* Slow the last step so that the turn ends where it began (the
         * sensors stay square to the walls for the round flight and the
         * avoidance); the period is taken from the last step. */
        uint32_t dt = in->t_ms - explorer.last_t;
        int32_t rate = explorer.s.scan_rate_mrad_s;
        if (dt > 0 && dt < 1000 && left * 1000 / (int32_t)dt < rate)
            rate = left * 1000 / (int32_t)dt;
        if (left > 2 && rate > 0)
            out->yaw_rate_mrad_s = rate;
        else
            next_goal(in, out);
        break;
    }
    case EXPLORE_ST_FOLLOW:
        if (fly_path(in, out)) {
            explorer.stats.goals_reached++;
            begin_scan(in);
            out->cmd = EXPLORE_CMD_VELOCITY;
        }
        break;
    case EXPLORE_ST_ROUND: {
        fl_vel b;
        const uint16_t r[4] = {in->range_mm[EXPLORE_FRONT], in->range_mm[EXPLORE_BACK],
                               in->range_mm[EXPLORE_LEFT], in->range_mm[EXPLORE_RIGHT]};
        wf_params p = {explorer.s.wall_mm, explorer.s.speed_mm_s, in->max_range_mm,
                       explorer.s.stuck_ms / 2};
        if (wf_step(&explorer.wf, &p, in->t_ms, in->x_mm, in->y_mm, r, &b) == WF_LOOP_CLOSED) {
            go_home(in);
            out->cmd = EXPLORE_CMD_VELOCITY;
            break;
        }
        if (fl_avoid(&b, r, explorer.s.avoid_mm, explorer.s.speed_mm_s))
            explorer.stats.avoid_steps++;
        out->cmd = EXPLORE_CMD_VELOCITY;
        out->vx_mm_s = b.vx;
        out->vy_mm_s = b.vy;
        break;
    }
    case EXPLORE_ST_HOME:
        if (fly_path(in, out)) {
            explorer.st = EXPLORE_ST_LAND;
            out->cmd = EXPLORE_CMD_LAND;
        }
        break;
    case EXPLORE_ST_LAND:
        out->cmd = EXPLORE_CMD_LAND;
        if (in->z_mm <= 50)
            explorer.st = EXPLORE_ST_DONE;
        break;
    case EXPLORE_ST_DONE:
    case EXPLORE_ST_ERROR:
        out->cmd = explorer.st == EXPLORE_ST_DONE ? EXPLORE_CMD_DONE : EXPLORE_CMD_LAND;
        break;
    }
    /* A state change inside this step that left no command: hover. */
    if (out->cmd == EXPLORE_CMD_NONE)
        out->cmd = explorer.st == EXPLORE_ST_LAND ? EXPLORE_CMD_LAND : EXPLORE_CMD_VELOCITY;
    explorer.last_yaw = in->yaw_mrad;
    explorer.last_t = in->t_ms;
    out->state = explorer.st;
    if (explorer.st == EXPLORE_ST_FOLLOW || explorer.st == EXPLORE_ST_HOME) {
        out->goal_x_mm = explorer.goal_x;
        out->goal_y_mm = explorer.goal_y;
    }
}
