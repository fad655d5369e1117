/*
 * Whole flights inside the firmware: a synthetic room (axis-aligned solid
 * rectangles, in mm), a ray caster that gives the six ranges, and a
 * perfect kinematic drone that does what the commands say (a perfect pose:
 * this validates the algorithms before the real world and STM32 are
 * wired). The ray caster is integer (soft-float is slow) and the drone
 * double precision (libm), neither using the firmware's fixed-point
 * helpers, so an error in those cannot hide. Build on the host with
 * -DSIM_TRACE for a per-step trace ("T" lines) and the final maps ("M").
 *
 * Coverage (DESIGN.md §9: "free space of the true plan observed"; Table 6:
 * "the percentage of terrain that was explored"): the share of the truly
 * free cells (whole square inside the room, touching no obstacle) that the
 * map has observed (log-odds not 0). Accuracy (§9: "observed cells whose
 * state matches the true plan"): of the observed cells whose truth is
 * clear-cut (wholly free, or centre inside an obstacle), the share whose
 * map class matches. "Free coverage", the truly free cells mapped free, is
 * printed as well. All from the exported map image.
 */
#include <math.h>
#include <string.h>

#include "../explore.h"
#include "selftest.h"
#include "sim.h"

/* The seed's test room (§5.1: "approximately 6,5 m x 2,5 m", an open zone
 * on the left and a cluttered zone on the right, Figure 5.1), as we lay it
 * out: walls 100 mm thick; a divider at x = 4.0 m from the bottom wall up
 * to 1.5 m; a 0.5 m box and two 40 mm table legs in the cluttered zone. The
 * take-off point is in a corner of the open zone, as in Figure 5.2. */
static const rect seed_rects[] = {
    {-100, -100, 6600, 0},    {-100, 2500, 6600, 2600}, {-100, 0, 0, 2500},
    {6500, 0, 6600, 2500},    {4000, 0, 4100, 1500},    {5000, 900, 5500, 1400},
    {4600, 2000, 4640, 2040}, {6000, 500, 6040, 540},
};
const world sim_seed_room = {"seed room", seed_rects, 8, {0, 0, 6500, 2500}, 500, 500, 0, 0};

/* The seed room, and a 300 x 400 mm box put down at 17.6 s 83 mm ahead of
 * the drone, which is then crossing the open zone at 0.2 m/s along y = 470
 * (found from the flight's trace): closer than the avoidance threshold, and
 * not yet on the map. */
static const rect seed_late_rects[] = {
    {-100, -100, 6600, 0},    {-100, 2500, 6600, 2600}, {-100, 0, 0, 2500},
    {6500, 0, 6600, 2500},    {4000, 0, 4100, 1500},    {5000, 900, 5500, 1400},
    {4600, 2000, 4640, 2040}, {6000, 500, 6040, 540},   {1360, 300, 1660, 700},
};
const world sim_seed_room_late_box = {
    "seed room, late box", seed_late_rects, 9, {0, 0, 6500, 2500}, 500, 500, 1, 17600};

/* Two 2 x 2 m rooms joined by a 250 mm slot, narrower than the drone with
 * its margin (2 x 150 mm): from 500 mm away the rangers (20° cones) see
 * through it into the second room, whose frontier is then unreachable. */
static const rect slot_rects[] = {
    {-100, -100, 4100, 0}, {-100, 2000, 4100, 2100}, {-100, 0, 0, 2000},
    {4000, 0, 4100, 2000}, {2000, 0, 2100, 875},     {2000, 1125, 2100, 2000},
};
const world sim_slot_rooms = {"slot rooms", slot_rects, 6, {0, 0, 2000, 2000}, 1500, 1000, 0, 0};

/* A 1.5 x 1.5 m room with the take-off 100 mm from a wall: inside the
 * planner's inflation, so the round flight must land at the nearest cell it
 * can stop in. */
static const rect small_rects[] = {
    {-100, -100, 1600, 0},
    {-100, 1500, 1600, 1600},
    {-100, 0, 0, 1500},
    {1500, 0, 1600, 1500},
};
const world sim_small_room = {"small room", small_rects, 4, {0, 0, 1500, 1500}, 100, 750, 0, 0};

/* Simulated time of the step being simulated, for the late rectangles. */
static uint32_t sim_now_ms;

static int active_rects(const world *w)
{
    return sim_now_ms >= w->late_ms ? w->nrects : w->nrects - w->nlate;
}

typedef struct {
    double x, y, z, yaw; /* mm, rad */
    uint32_t collisions;
    double flown_mm;
} drone;

#define SIM_DRONE_RADIUS_MM 70.0
#define SIM_CLIMB_MM_S 300.0
#define SIM_CEILING_MM 2500.0

/* Distance (mm) along a ray from (px, py) with unit direction (dx, dy) in
 * Q12 to the first rectangle, or INT32_MAX. Integer slabs: soft-float costs
 * ~2k cycles per rectangle, this ~200 (direction error 1/4096 rad: under
 * a millimetre at 3 m). */
static int32_t cast(const world *w, int32_t px, int32_t py, int32_t dx, int32_t dy)
{
    int32_t best = INT32_MAX;
    for (int i = 0, n = active_rects(w); i < n; i++) {
        const rect *r = &w->rects[i];
        int32_t t0 = 0, t1 = INT32_MAX;
        const int32_t lo[2] = {r->x0 - px, r->y0 - py}, hi[2] = {r->x1 - px, r->y1 - py};
        const int32_t d[2] = {dx, dy};
        int miss = 0;
        for (int k = 0; k < 2; k++) {
            if (d[k] == 0) {
                miss |= lo[k] > 0 || hi[k] < 0;
                continue;
            }
            int32_t a = lo[k] * 4096 / d[k], b = hi[k] * 4096 / d[k];
            if (a > b) {
                int32_t t = a;
                a = b;
                b = t;
            }
            if (a > t0)
                t0 = a;
            if (b < t1)
                t1 = b;
        }
        if (!miss && t0 <= t1 && t0 < best)
            best = t0;
    }
    return best;
}

/* The VL53L1x reports the nearest return within its field of view (seed
 * §4.2.1.A: "sensor returns the shortest measure that it detects in that
 * 20° angle"): the minimum over SIM_RAYS rays spread over SIM_FOV_RAD. */
#define SIM_RAYS 9
#define SIM_FOV_RAD (20.0 * M_PI / 180.0)

/* One ranger looking along heading (hc, hs): its rays are that direction
 * turned by the offsets (cos/sin computed once: libm's soft-float trig
 * costs ~10k cycles a call). */
static int32_t ranger(const world *w, const drone *d, double hc, double hs)
{
    static double oc[SIM_RAYS], os[SIM_RAYS];
    static int init;
    if (!init) {
        for (int k = 0; k < SIM_RAYS; k++) {
            double a = SIM_FOV_RAD * ((double)k / (SIM_RAYS - 1) - 0.5);
            oc[k] = cos(a);
            os[k] = sin(a);
        }
        init = 1;
    }
    int32_t px = (int32_t)lround(d->x), py = (int32_t)lround(d->y), best = INT32_MAX;
    for (int k = 0; k < SIM_RAYS; k++) {
        int32_t dx = (int32_t)lround(4096 * (hc * oc[k] - hs * os[k]));
        int32_t dy = (int32_t)lround(4096 * (hs * oc[k] + hc * os[k]));
        int32_t t = cast(w, px, py, dx, dy);
        if (t < best)
            best = t;
    }
    return best;
}

static int hits(const world *w, double x, double y, double radius)
{
    for (int i = 0, n = active_rects(w); i < n; i++) {
        const rect *r = &w->rects[i];
        double cx = x < r->x0 ? r->x0 : x > r->x1 ? r->x1 : x;
        double cy = y < r->y0 ? r->y0 : y > r->y1 ? r->y1 : y;
        if ((cx - x) * (cx - x) + (cy - y) * (cy - y) < radius * radius)
            return 1;
    }
    return 0;
}

static void sense(const world *w, const drone *d, uint16_t max_mm, uint32_t t_ms, explore_input *in)
{
    in->t_ms = t_ms;
    in->x_mm = (int32_t)lround(d->x);
    in->y_mm = (int32_t)lround(d->y);
    in->z_mm = (int32_t)lround(d->z);
    double yaw = remainder(d->yaw, 2 * M_PI);
    in->yaw_mrad = (int32_t)lround(yaw * 1000);
    /* front, back, left, right at 0, 180, 90, 270 degrees from the yaw */
    double c = cos(d->yaw), s = sin(d->yaw);
    const double hc[4] = {c, -c, -s, s}, hs[4] = {s, -s, c, -c};
    for (int k = 0; k < 4; k++) {
        int32_t t = ranger(w, d, hc[k], hs[k]);
        in->range_mm[k] = t >= max_mm ? max_mm : (uint16_t)t;
    }
    in->range_mm[EXPLORE_UP] = (uint16_t)lround(SIM_CEILING_MM - d->z);
    in->range_mm[EXPLORE_DOWN] = (uint16_t)lround(d->z);
    in->max_range_mm = max_mm;
}

static void act(const world *w, drone *d, const explore_output *o, uint32_t dt_ms)
{
    double dt = dt_ms / 1000.0;
    switch (o->cmd) {
    case EXPLORE_CMD_TAKEOFF:
        d->z = fmin(o->z_mm, d->z + SIM_CLIMB_MM_S * dt);
        break;
    case EXPLORE_CMD_VELOCITY: {
        double c = cos(d->yaw), s = sin(d->yaw);
        double nx = d->x + (c * o->vx_mm_s - s * o->vy_mm_s) * dt;
        double ny = d->y + (s * o->vx_mm_s + c * o->vy_mm_s) * dt;
        if (hits(w, nx, ny, SIM_DRONE_RADIUS_MM)) {
            d->collisions++;
        } else {
            d->flown_mm += hypot(nx - d->x, ny - d->y);
            d->x = nx;
            d->y = ny;
        }
        d->yaw += o->yaw_rate_mrad_s / 1000.0 * dt;
        d->z = o->z_mm;
        break;
    }
    case EXPLORE_CMD_LAND:
        d->z = fmax(0, d->z - SIM_CLIMB_MM_S * dt);
        break;
    default:
        break;
    }
}

static int32_t rd32(const uint8_t *p)
{
    return (int32_t)(p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24);
}
static int32_t rd16(const uint8_t *p) { return p[0] | p[1] << 8; }

static int inside_rect(const rect *r, double x, double y)
{
    return x >= r->x0 && x <= r->x1 && y >= r->y0 && y <= r->y1;
}

/* Coverage and accuracy of the exported map against the room. */
static quality assess(const world *w)
{
    uint32_t len;
    const uint8_t *img = explore_map_export(&len);
    int32_t gw = rd16(img + 8), gh = rd16(img + 10), cell = rd16(img + 12);
    int32_t ox = rd32(img + 16), oy = rd32(img + 20);
    const int8_t *lo = (const int8_t *)(img + rd16(img + 6));
    quality q = {0, 0, 0, 0, 0};
    for (int32_t iy = 0; iy < gh; iy++) {
        for (int32_t ix = 0; ix < gw; ix++) {
            rect sq = {ox + ix * cell, oy + iy * cell, ox + (ix + 1) * cell, oy + (iy + 1) * cell};
            double cx = sq.x0 + cell / 2.0, cy = sq.y0 + cell / 2.0;
            int in_room = sq.x0 >= w->interior.x0 && sq.x1 <= w->interior.x1 &&
                          sq.y0 >= w->interior.y0 && sq.y1 <= w->interior.y1;
            int touches = 0, centre_in = 0;
            for (int i = 0; i < w->nrects; i++) {
                const rect *r = &w->rects[i];
                if (sq.x0 < r->x1 && sq.x1 > r->x0 && sq.y0 < r->y1 && sq.y1 > r->y0)
                    touches = 1;
                if (inside_rect(r, cx, cy))
                    centre_in = 1;
            }
            int8_t l = lo[iy * gw + ix];
            int is_free = in_room && !touches;
            if (is_free) {
                q.truth_free++;
                q.covered += l != 0;
                q.covered_free += l < 0;
            }
            if (l != 0 && (is_free || centre_in)) {
                q.judged++;
                q.correct += is_free ? l < 0 : l > 0;
            }
        }
    }
    return q;
}

flight sim_fly(const world *w, const explore_settings *s, uint16_t max_mm, int verbose)
{
    flight f;
    memset(&f, 0, sizeof f);
    int rc = explore_init(s);
    CHECK(rc == EXPLORE_OK, "%s: init: %s", w->name, explore_last_error());
    if (rc != EXPLORE_OK)
        return f;
    drone d = {w->start_x, w->start_y, 0, 0, 0, 0};
    const uint32_t dt = 100;                       /* the seed's 100 ms log period (§4.2.1.A) */
    uint32_t limit = s->time_budget_ms / dt + 600; /* budget + time to land */
    explore_input in;
    explore_output o;
    uint32_t t = 0;
    for (f.steps = 0; f.steps < limit; f.steps++, t += dt) {
        memset(&in, 0, sizeof in);
        sim_now_ms = t;
        sense(w, &d, max_mm, t, &in);
        explore_step(&in, &o);
#ifdef SIM_TRACE
        printf("T %s %lu st %d pos %ld %ld yaw %ld r %u %u %u %u cmd %d v %ld %ld w %ld coll %lu\n",
               w->name, (unsigned long)t, o.state, (long)in.x_mm, (long)in.y_mm, (long)in.yaw_mrad,
               in.range_mm[0], in.range_mm[1], in.range_mm[2], in.range_mm[3], o.cmd,
               (long)o.vx_mm_s, (long)o.vy_mm_s, (long)o.yaw_rate_mrad_s,
               (unsigned long)d.collisions);
#endif
        if (o.new_goal && verbose)
            printf("  goal at %lu.%lu s: (%ld, %ld)\n", (unsigned long)(t / 1000),
                   (unsigned long)(t % 1000 / 100), (long)o.goal_x_mm, (long)o.goal_y_mm);
        if (o.cmd == EXPLORE_CMD_DONE) {
            f.done = 1;
            break;
        }
        act(w, &d, &o, dt);
    }
    f.t_ms = t;
    f.collisions = d.collisions;
    f.flown_mm = d.flown_mm;
    f.end_dist_home = hypot(d.x - w->start_x, d.y - w->start_y);
    f.st = *explore_get_stats();
    f.q = assess(w);
#ifdef SIM_TRACE
    {
        uint32_t len;
        const uint8_t *img = explore_map_export(&len);
        int32_t gw = rd16(img + 8), gh = rd16(img + 10);
        for (int32_t iy = gh - 1; iy >= 0; iy--) {
            printf("M ");
            for (int32_t ix = 0; ix < gw; ix++) {
                int8_t l = (int8_t)img[32 + iy * gw + ix];
                putchar(l < 0 ? '.' : l > 0 ? '#' : ' ');
            }
            printf("\n");
        }
    }
#endif
    return f;
}

/* Tenths of a percent. */
static long permille(int32_t n, int32_t d) { return d ? (long)n * 1000L / d : 0; }

void sim_report(const char *what, const world *w, const explore_settings *s, const flight *f)
{
    const explore_stats *st = &f->st;
    long cov = permille(f->q.covered, f->q.truth_free), acc = permille(f->q.correct, f->q.judged);
    long fcov = permille(f->q.covered_free, f->q.truth_free);
    printf("flight %s, %s: cell %u mm, fov %u.%02u deg: %s after %lu.%lu s, coverage %ld.%ld %%, "
           "accuracy %ld.%ld %%, free coverage %ld.%ld %%, goals %lu (reached %lu, abandoned %lu), "
           "flown %ld mm, collisions %lu, home %ld mm\n",
           what, w->name, s->cell_mm, s->fov_cdeg / 100, s->fov_cdeg % 100,
           f->done ? "done" : "NOT DONE", (unsigned long)(f->t_ms / 1000),
           (unsigned long)(f->t_ms % 1000 / 100), cov / 10, cov % 10, acc / 10, acc % 10, fcov / 10,
           fcov % 10, (unsigned long)st->goals, (unsigned long)st->goals_reached,
           (unsigned long)st->goals_failed, (long)f->flown_mm, (unsigned long)f->collisions,
           (long)f->end_dist_home);
    printf("cycles %s: map %lu updates, %lu per update; plan %lu, %lu per plan; avoid steps %lu "
           "(map %lu); unreachable regions skipped %lu\n",
           what, (unsigned long)st->map_updates,
           (unsigned long)(st->map_updates ? st->map_cycles / st->map_updates : 0),
           (unsigned long)st->plans, (unsigned long)(st->plans ? st->plan_cycles / st->plans : 0),
           (unsigned long)st->avoid_steps, (unsigned long)st->map_avoid_steps,
           (unsigned long)st->regions_unreachable);
}

void sim_seed_settings(explore_settings *s)
{
    explore_default_settings(s);
    /* The room and 200 mm around it. */
    s->x_min_mm = -200;
    s->y_min_mm = -200;
    s->x_max_mm = 6700;
    s->y_max_mm = 2700;
}
