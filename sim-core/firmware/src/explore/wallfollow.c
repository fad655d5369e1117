/* Wall following around the room: see wallfollow.h. */
#include "wallfollow.h"

#include <string.h>

#include "fixmath.h"

/* Body-frame unit vectors of the travel directions, and the range index
 * (front, back, left, right) looking that way. */
static const int8_t VX[4] = {1, 0, -1, 0};
static const int8_t VY[4] = {0, 1, 0, -1};
static const uint8_t LOOK[4] = {0, 2, 1, 3};

void wf_init(wf_state *w, uint32_t t_ms, int32_t x, int32_t y)
{
    memset(w, 0, sizeof *w);
    w->last_x = w->prog_x = x;
    w->last_y = w->prog_y = y;
    w->prog_t = t_ms;
}

static uint32_t range(const wf_params *p, const uint16_t r[4], int dir)
{
    uint16_t v = r[LOOK[dir & 3]];
    return v == 0 ? p->max_range_mm : v;
}

static void mark(wf_state *w, int32_t x, int32_t y)
{
    w->mark_x = x;
    w->mark_y = y;
}

int wf_step(wf_state *w, const wf_params *p, uint32_t t, int32_t x, int32_t y, const uint16_t r[4],
            fl_vel *b)
{
    uint32_t d = p->wall_mm, v = p->speed_mm_s;
    if (w->looping)
        w->odo_mm += fl_dist(w->last_x, w->last_y, x, y);
    w->last_x = x;
    w->last_y = y;
    int stuck = 0;
    if (fl_dist(x, y, w->prog_x, w->prog_y) >= WF_PROGRESS_MM) {
        w->prog_x = x;
        w->prog_y = y;
        w->prog_t = t;
    } else if (t - w->prog_t >= p->stuck_ms) {
        stuck = 1;
        w->prog_t = t;
        w->stuck_turns++;
    }
    if (w->looping && w->odo_mm >= WF_MIN_LOOP_MM &&
        fl_dist(x, y, w->loop_x, w->loop_y) <= WF_CLOSE_MM) {
        b->vx = b->vy = 0;
        return WF_LOOP_CLOSED;
    }
    int left = (w->dir + 1) & 3, right = (w->dir + 3) & 3;
    uint32_t ahead = stuck ? 0 : range(p, r, w->dir), side = range(p, r, left);
    switch (w->sub) {
    case WF_SEEK:
        if (ahead <= d) {
            w->dir = right;
            w->sub = WF_FOLLOW;
            w->looping = 1;
            w->loop_x = x;
            w->loop_y = y;
        }
        break;
    case WF_FOLLOW:
        if (ahead <= d) {
            w->dir = right; /* inner corner */
        } else if (side > 2 * d) {
            w->sub = WF_CORNER;
            mark(w, x, y);
        }
        break;
    case WF_CORNER:
        if (ahead <= d) {
            w->dir = right;
            w->sub = WF_FOLLOW;
        } else if (fl_dist(x, y, w->mark_x, w->mark_y) >= d) {
            w->dir = left;
            w->sub = WF_REGAIN;
            mark(w, x, y);
        }
        break;
    case WF_REGAIN:
        if (ahead <= d) {
            w->dir = right;
            w->sub = WF_FOLLOW;
        } else if (side <= 2 * d) {
            w->sub = WF_FOLLOW;
        } else if (fl_dist(x, y, w->mark_x, w->mark_y) >= 2 * d) {
            w->dir = left;
            mark(w, x, y);
        }
        break;
    }
    /* Recompute for the (possibly new) direction. */
    ahead = range(p, r, w->dir);
    side = range(p, r, (w->dir + 1) & 3);
    /* Slow down as the wall ahead nears: full speed from 2 wall_mm, a
     * quarter at wall_mm. */
    int32_t fwd = (int32_t)v;
    if (ahead < 2 * d)
        fwd = fx_max((int32_t)(v * (ahead > d ? ahead - d : 0) / d), (int32_t)v / 4);
    int32_t lat = 0;
    if (w->sub == WF_FOLLOW && side <= 2 * d)
        lat = fx_clamp((int32_t)side - (int32_t)d, -(int32_t)v / 2, (int32_t)v / 2); /* 1/s gain */
    int ldir = (w->dir + 1) & 3;
    b->vx = VX[w->dir] * fwd + VX[ldir] * lat;
    b->vy = VY[w->dir] * fwd + VY[ldir] * lat;
    return WF_FLYING;
}
