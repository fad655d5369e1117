/*
 * The positioning half of seed 003 (§5.3.2, §6.8.4): the frame's
 * references, where filters start, and the filter updates after each
 * packet. See docs/SWARM_FIRMWARE.md §3.
 */
#include "swarm_nodes.h"

void swarm_positions_reset(swarm_t *s)
{
    s->nref = 0;
    s->building = 1;
    s->self_kf.init = 0;
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++)
        s->nb[i].kf.init = 0;
}

/* The closed-form place of `node` as reference number `role` of the frame
 * (§5.3.2), from the references before it; 0 while a distance it needs is
 * missing or the result is degenerate. */
static int frame_position(const swarm_t *s, int node, int role, swarm_vec3_t *out)
{
    const int8_t *r = s->ref;
    if (role == 0) {
        *out = (swarm_vec3_t){0.0f, 0.0f, 0.0f};
        return 1;
    }
    for (int k = 0; k < role; k++)
        if (!swarm_tof(s, node, r[k]))
            return 0;
    if (role == 1)
        return swarm_frame_p2(swarm_tof_m(s, node, r[0]), out) == SWARM_COORDS_OK;
    if (!swarm_tof(s, r[0], r[1]))
        return 0;
    if (role == 2)
        return swarm_frame_p3(swarm_tof_m(s, r[0], r[1]), swarm_tof_m(s, node, r[0]),
                              swarm_tof_m(s, node, r[1]), out) != SWARM_COORDS_DEGENERATE;
    swarm_vec3_t p3;
    if (!swarm_tof(s, r[0], r[2]) || !swarm_tof(s, r[1], r[2]) ||
        swarm_frame_p3(swarm_tof_m(s, r[0], r[1]), swarm_tof_m(s, r[0], r[2]),
                       swarm_tof_m(s, r[1], r[2]), &p3) == SWARM_COORDS_DEGENERATE)
        return 0;
    return swarm_frame_p4(swarm_tof_m(s, r[0], r[1]), &p3, swarm_tof_m(s, node, r[0]),
                          swarm_tof_m(s, node, r[1]), swarm_tof_m(s, node, r[2]),
                          out) != SWARM_COORDS_DEGENERATE;
}

/* §5.3.2: the references are the first detected neighbours, in order.
 * Refinement: a neighbour too close to the origin, the X axis or the XY
 * plane (closer than frame_min_sep) would leave an axis undefined, so it
 * is passed over and the next detected neighbour is tried. */
static void assign_references(swarm_t *s)
{
    while (s->building && s->nref < swarm_refs_needed(s)) {
        int best = -1;
        for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++) {
            if (!s->nb[i].used || swarm_role_of(s, i) >= 0)
                continue;
            if (best >= 0 && (uint16_t)(s->nb[i].order - s->nb[best].order) < 0x8000)
                continue; /* detected after the best candidate so far */
            swarm_vec3_t p;
            if (!frame_position(s, i, s->nref, &p))
                continue;
            float off = s->nref == 1 ? p.x : s->nref == 2 ? p.y : p.z;
            if (s->nref == 0 || off >= s->set.frame_min_sep)
                best = i;
        }
        if (best < 0)
            return;
        s->ref[s->nref++] = (int8_t)best;
        /* Our own start may have used the incomplete frame. */
        s->self_kf.init = 0;
    }
}

/* Least-squares trilateration of `node` from the other nodes with a known
 * distance whose filters have σ below max_std. */
static int trilaterate_node(const swarm_t *s, int node, float max_std, swarm_vec3_t *out)
{
    swarm_vec3_t ref[SWARM_NODES];
    float dist[SWARM_NODES];
    int n = 0;
    for (int b = 0; b < SWARM_NODES; b++) {
        if (b == node || !swarm_node_used(s, b) || !swarm_tof(s, node, b) ||
            !swarm_kf_is_stable(swarm_filter(s, b), max_std))
            continue;
        ref[n] = swarm_kf_position(swarm_filter(s, b));
        dist[n++] = swarm_tof_m(s, node, b);
    }
    return swarm_trilaterate(ref, dist, n, s->set.planar, out) == SWARM_COORDS_OK;
}

/* The reference role of a node, counting this drone as the one that
 * completes a frame lacking neighbours (the seed's three-drone table: A is
 * placed from B and C alone, on +Y); -1 for the others. */
static int completing_role(const swarm_t *s, int node)
{
    int role = swarm_role_of(s, node);
    if (role < 0 && node == SWARM_SELF && s->nref >= swarm_min_completed(s) &&
        s->nref < swarm_refs_needed(s) &&
        (int)swarm_neighbour_count(s) == s->nref)
        role = s->nref;
    return role;
}

/* Where a filter starts: the closed-form frame of §5.3.2 for the
 * references, the trilateration from the placed nodes for the others. 0
 * while the distances it needs are missing. *provisional is set when the
 * start had to use nodes not yet placed (see update_node). */
static int initial_position(const swarm_t *s, int node, swarm_vec3_t *out, int *provisional)
{
    *provisional = 0;
    int role = completing_role(s, node);
    if (role >= 0) {
        if (!frame_position(s, node, role, out))
            return 0;
        /* A start on the plane (axis) the point completes is a saddle of
         * the distance measurements: the filter would never leave it. The
         * point is by definition on the positive side (§5.3.2); start it
         * there, at least half the separation a reference needs. */
        float *c = role == 2 ? &out->y : role == 3 ? &out->z : 0;
        if (c && *c < 0.5f * s->set.frame_min_sep && !(role == 3 && s->set.planar))
            *c = 0.5f * s->set.frame_min_sep;
        return 1;
    }
    if (trilaterate_node(s, node, s->set.stable_std, out))
        return 1;
    /* A frame's fourth reference is often poorly observed from the three
     * others alone, and becomes stable only once other neighbours measure
     * it too: start those from the nodes roughly known (σ below 4x the
     * stable one), and start them again properly once enough are placed. */
    *provisional = 1;
    return trilaterate_node(s, node, 4.0f * s->set.stable_std, out);
}

/* Distances alone cannot tell a point from its mirror image through the
 * references' plane (the XY plane; the X axis in 2D), and a Kalman filter
 * started on the wrong side stays there: the plane is a ridge of the
 * measurements it never crosses. Compare both sides against every
 * distance to a placed node and jump when the mirror fits clearly better
 * (the residuals at least halved). */
static void resolve_flip(swarm_t *s, int node)
{
    swarm_kf_t *kf = swarm_filter_mut(s, node);
    int axis = s->set.planar ? 1 : 2;
    swarm_vec3_t p = swarm_kf_position(kf), m = p;
    if (axis == 1)
        m.y = -m.y;
    else
        m.z = -m.z;
    float here = 0.0f, there = 0.0f;
    int n = 0;
    for (int b = 0; b < SWARM_NODES; b++) {
        if (b == node || !swarm_placed(s, b) || !swarm_tof(s, node, b))
            continue;
        swarm_vec3_t pb = swarm_kf_position(swarm_filter(s, b));
        float d = swarm_tof_m(s, node, b);
        float e1 = swarm_vec3_dist(&p, &pb) - d, e2 = swarm_vec3_dist(&m, &pb) - d;
        here += e1 * e1;
        there += e2 * e2;
        n++;
    }
    if (n > swarm_refs_needed(s) - 1 && there < 0.5f * here)
        swarm_kf_mirror(kf, axis);
}

/* Feed one node's filter with its distances to the placed nodes (all of
 * them, or only `only` when ≥ 0), plus the frame's arbitrary values
 * (§6.8.4 scenarios 1 and 2). */
static void update_node(swarm_t *s, int node, int only, uint32_t now_us)
{
    swarm_kf_t *kf = swarm_filter_mut(s, node);
    const swarm_settings_t *set = &s->set;
    if (!kf->init || kf->provisional) {
        swarm_vec3_t p0;
        int provisional;
        if (initial_position(s, node, &p0, &provisional) && (!kf->init || !provisional)) {
            swarm_kf_init(kf, &p0, set->init_std, set->init_std, now_us);
            kf->provisional = (uint8_t)provisional;
        }
        if (!kf->init)
            return;
    }
    swarm_kf_advance(kf, now_us, &set->kf);
    for (int b = 0; b < SWARM_NODES; b++) {
        if (b == node || (only >= 0 && b != only) || !swarm_placed(s, b) || !swarm_tof(s, node, b))
            continue;
        swarm_vec3_t pb = swarm_kf_position(swarm_filter(s, b));
        swarm_kf_update_distance(kf, &pb, swarm_tof_m(s, node, b), set->meas_std, &set->kf);
    }
    int role = swarm_role_of(s, node);
    if (role >= 0 && (s->building || set->keep_frame)) {
        /* ref0 at the origin, ref1 on the X axis, ref2 in the XY plane. */
        for (int axis = role; axis < 3; axis++)
            swarm_kf_update_axis(kf, axis, 0.0f, set->pseudo_std, &set->kf);
        /* ...on the positive side of the axis it defines. */
        if (role >= 1 && kf->x[role - 1] < 0.0f)
            swarm_kf_mirror(kf, role - 1);
    }
    /* This drone completing the frame defines the side of its axis too:
     * a first update with the start's σ of 100 m can throw the filter
     * across the X axis (found by swarm-table: A settled at y = -0.5). */
    int completes = role < 0 && completing_role(s, node) >= 1;
    if (completes && (s->building || set->keep_frame) && kf->x[s->nref - 1] < 0.0f)
        swarm_kf_mirror(kf, s->nref - 1);
    if (set->planar)
        swarm_kf_update_axis(kf, 2, 0.0f, set->pseudo_std, &set->kf);
    if (set->planar == SWARM_LINE)
        swarm_kf_update_axis(kf, 1, 0.0f, set->pseudo_std, &set->kf);
    /* A flip happens after a poor start, not later: look every 8th update
     * (the check costs two square roots per placed node). */
    if (role < 0 && !completes && !s->building && (kf->updates & 7) == 0)
        resolve_flip(s, node);
}

void swarm_positions_update(swarm_t *s, int node, uint32_t now_us)
{
    assign_references(s);
    update_node(s, node, -1, now_us);
    /* Built when every reference is placed; with one neighbour too few,
     * this drone completes the frame (see initial_position) and must be
     * placed too. */
    int need = swarm_refs_needed(s);
    int self_completes = s->nref >= swarm_min_completed(s) && s->nref == need - 1 &&
                         (int)swarm_neighbour_count(s) == s->nref;
    if (s->building && (s->nref == need || self_completes)) {
        int all = !self_completes || swarm_placed(s, SWARM_SELF);
        for (int r = 0; r < s->nref; r++)
            all &= swarm_placed(s, s->ref[r]);
        s->building = !all;
    }
    /* §6.8.4 step 2: our own position from the neighbour just updated
     * and our distance to it. */
    if (swarm_placed(s, node))
        update_node(s, SWARM_SELF, node, now_us);
}
