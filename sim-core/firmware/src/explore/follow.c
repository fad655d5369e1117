/* Path following and reactive avoidance: see follow.h. */
#include "follow.h"

#include "fixmath.h"

uint32_t fl_dist(int32_t ax, int32_t ay, int32_t bx, int32_t by)
{
    int32_t dx = bx - ax, dy = by - ay;
    return fx_isqrt((uint32_t)(dx * dx) + (uint32_t)(dy * dy));
}

fl_vel fl_world_to_body(fl_vel v, int32_t yaw_mrad)
{
    uint16_t a = fx_mrad_to_bam(yaw_mrad);
    int32_t c = fx_cos(a), s = fx_sin(a);
    fl_vel b = {fx_div_round(v.vx * c + v.vy * s, FX_Q14),
                fx_div_round(-v.vx * s + v.vy * c, FX_Q14)};
    return b;
}

int fl_avoid(fl_vel *v, const uint16_t r[4], uint32_t avoid_mm, uint32_t speed)
{
    /* front (+x), back (-x), left (+y), right (-y) */
    int acted = 0;
    int32_t want = fx_abs(v->vx) + fx_abs(v->vy);
    int along_x = fx_abs(v->vx) >= fx_abs(v->vy); /* mainly forward/backward */
    for (int k = 0; k < 4; k++) {
        if (r[k] == 0 || r[k] >= avoid_mm)
            continue;
        acted = 1;
        int32_t push = (int32_t)(speed * (avoid_mm - r[k]) / avoid_mm);
        int32_t *c = k < 2 ? &v->vx : &v->vy;
        int32_t sign = (k == 0 || k == 2) ? 1 : -1; /* direction of the sensor */
        if (*c * sign > 0)
            *c = 0;        /* stop moving towards it */
        *c -= sign * push; /* and back off */
    }
    if (acted && want > (int32_t)speed / 2 && fx_abs(v->vx) + fx_abs(v->vy) < (int32_t)speed / 4) {
        /* Stuck against something: side-step towards the freer side of the
         * wanted direction (its perpendiculars, by their ranges). */
        uint16_t pa = along_x ? r[2] : r[0], pb = along_x ? r[3] : r[1];
        int32_t side = pa >= pb ? 1 : -1; /* a missing reading counts as 0 */
        if (along_x)
            v->vy += side * (int32_t)speed / 2;
        else
            v->vx += side * (int32_t)speed / 2;
    }
    return acted;
}

/* Has (x, y) reached intermediate waypoint i? */
static int passed(const pl_path *p, int i, int32_t x, int32_t y, uint32_t tol_mm, uint32_t pass_mm)
{
    int32_t wx = p->wp[i].x_mm, wy = p->wp[i].y_mm;
    uint32_t d = fl_dist(x, y, wx, wy);
    if (d <= pass_mm)
        return 1;
    int64_t dot =
        (int64_t)(p->wp[i + 1].x_mm - wx) * (x - wx) + (int64_t)(p->wp[i + 1].y_mm - wy) * (y - wy);
    return d <= tol_mm && dot > 0;
}

int fl_avoid_map(const og_grid *g, int32_t x, int32_t y, uint32_t radius_mm, uint32_t speed,
                 fl_vel *v)
{
    int32_t cx, cy;
    if (!og_cell_of(g, x, y, &cx, &cy))
        return 0;
    int32_t r = (int32_t)radius_mm / g->cell_mm + 1, rad = (int32_t)radius_mm;
    int64_t px = 0, py = 0; /* summed push, mm/s */
    int acted = 0;
    for (int32_t iy = fx_max(0, cy - r); iy <= fx_min(g->h - 1, cy + r); iy++) {
        for (int32_t ix = fx_max(0, cx - r); ix <= fx_min(g->w - 1, cx + r); ix++) {
            if (og_get(g, ix, iy) <= 0)
                continue;
            int32_t dx = og_cx(g, ix) - x, dy = og_cy(g, iy) - y;
            int32_t d = (int32_t)fl_dist(0, 0, dx, dy);
            if (d > rad || d == 0)
                continue;
            acted = 1;
            /* Remove the component towards the cell. */
            int64_t along = ((int64_t)v->vx * dx + (int64_t)v->vy * dy) / d;
            if (along > 0) {
                v->vx -= (int32_t)(along * dx / d);
                v->vy -= (int32_t)(along * dy / d);
            }
            int64_t push = (int64_t)speed * (rad - d) / rad;
            px -= push * dx / d;
            py -= push * dy / d;
        }
    }
    if (!acted)
        return 0;
    int32_t cap = (int32_t)speed / 2;
    uint32_t m = fl_dist(0, 0, (int32_t)fx_clamp((int32_t)px, -65535, 65535),
                         (int32_t)fx_clamp((int32_t)py, -65535, 65535));
    if (m > (uint32_t)cap) {
        px = px * cap / m;
        py = py * cap / m;
    }
    v->vx += (int32_t)px;
    v->vy += (int32_t)py;
    return 1;
}

int fl_follow(fl_state *f, int32_t x, int32_t y, uint32_t speed, uint32_t tol_mm, uint32_t pass_mm,
              uint32_t slow_mm, fl_vel *out, uint32_t *remaining_mm)
{
    const pl_path *p = &f->path;
    out->vx = out->vy = 0;
    *remaining_mm = 0;
    if (p->n == 0)
        return FL_ARRIVED;
    if (f->next < 1)
        f->next = 1;
    while (f->next < p->n - 1 && passed(p, f->next, x, y, tol_mm, pass_mm))
        f->next++;
    int last = p->n - 1;
    int32_t tx = p->wp[f->next < p->n ? f->next : last].x_mm;
    int32_t ty = p->wp[f->next < p->n ? f->next : last].y_mm;
    uint32_t d = fl_dist(x, y, tx, ty);
    uint32_t rem = d;
    for (int i = f->next; i < last; i++)
        rem += fl_dist(p->wp[i].x_mm, p->wp[i].y_mm, p->wp[i + 1].x_mm, p->wp[i + 1].y_mm);
    *remaining_mm = rem;
    if (rem <= tol_mm || p->n == 1)
        return FL_ARRIVED;
    uint32_t v = speed;
    if (rem < slow_mm)
        v = fx_max((int32_t)(speed * rem / slow_mm), (int32_t)speed / 4);
    if (d == 0)
        return FL_MOVING;
    out->vx = (int32_t)((int64_t)(tx - x) * v / d);
    out->vy = (int32_t)((int64_t)(ty - y) * v / d);
    return FL_MOVING;
}
