/*
 * Internal to swarm.c and positions.c: the nodes of a swarm_t and the two
 * entry points of the positioning half.
 */
#ifndef SWARM_NODES_H
#define SWARM_NODES_H

#include "swarm.h"

static inline int swarm_pair_index(int a, int b)
{
    if (a > b) {
        int t = a;
        a = b;
        b = t;
    }
    return b * (b - 1) / 2 + a;
}

static inline swarm_kf_t *swarm_filter_mut(swarm_t *s, int node)
{
    return node == SWARM_SELF ? &s->self_kf : &s->nb[node].kf;
}

static inline int swarm_node_used(const swarm_t *s, int node)
{
    return node == SWARM_SELF || s->nb[node].used;
}

/* §6.8.3: a node whose filter is stable is used as an anchor. */
static inline int swarm_placed(const swarm_t *s, int node)
{
    return swarm_node_used(s, node) &&
           swarm_kf_is_stable(swarm_filter(s, node), s->set.stable_std);
}

/* The node's reference number in the frame, or -1. */
static inline int swarm_role_of(const swarm_t *s, int node)
{
    for (int r = 0; r < s->nref; r++)
        if (s->ref[r] == node)
            return r;
    return -1;
}

/* References the frame needs (§5.3.2): 4 in 3D, 3 on a table. */
static inline int swarm_refs_needed(const swarm_t *s)
{
    return s->set.planar == SWARM_LINE ? 2 : s->set.planar ? 3 : 4;
}

/* The fewest references a frame that this drone completes must have: the
 * origin in 1D (the seed's §7.3 pair), origin and +X otherwise. */
static inline int swarm_min_completed(const swarm_t *s)
{
    return s->set.planar == SWARM_LINE ? 1 : 2;
}

/* A TOF of the table in metres. */
static inline float swarm_tof_m(const swarm_t *s, int a, int b)
{
    return (float)swarm_tof(s, a, b) * SWARM_METRES_PER_TICK;
}

/* §5.3.2 / §6.8.4: after a packet of `node`, its filter and ours. */
void swarm_positions_update(swarm_t *s, int node, uint32_t now_us);
/* Forget the frame and every filter (a reference has left). */
void swarm_positions_reset(swarm_t *s);

#endif
