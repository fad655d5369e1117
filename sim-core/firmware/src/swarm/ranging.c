/* Swarm ranging of seed 003: see ranging.h. */
#include "ranging.h"

uint64_t swarm_unwrap32(uint32_t diff32, uint64_t near)
{
    /* n = round((near - diff32) / 2^32), at least 0. */
    int64_t base = (int64_t)near - (int64_t)diff32;
    int64_t n = (base + (INT64_C(1) << 31)) >> 32;
    if (n < 0)
        n = 0;
    return (uint64_t)diff32 + ((uint64_t)n << 32);
}

int swarm_clock_candidate(uint64_t local_span, uint64_t remote_span, int64_t *out)
{
    if (local_span == 0 || remote_span == 0 || local_span >= SWARM_MAX_SPAN ||
        remote_span >= SWARM_MAX_SPAN)
        return 0;
    int64_t diff = (int64_t)local_span - (int64_t)remote_span;
    /* Only small ratios make sense (a 1e-3 error is already absurd); this
     * also keeps diff·2^20 in range below. */
    int64_t limit = (int64_t)(remote_span >> 10);
    if (diff > limit || diff < -limit)
        return 0;
    /* diff·2^40 / remote in two steps of 2^20 (no 128-bit type on RV32). */
    int neg = diff < 0;
    uint64_t a = (uint64_t)(neg ? -diff : diff) << 20;
    uint64_t hi = a / remote_span;
    uint64_t rem = a % remote_span;
    uint64_t lo = ((rem << 20) + remote_span / 2) / remote_span;
    int64_t q = (int64_t)((hi << 20) + lo);
    *out = neg ? -q : q;
    return 1;
}

#define BUCKET_MAX 4

int swarm_clock_update(swarm_clock_t *c, int64_t candidate, const swarm_clock_settings_t *s)
{
    /* Absolute limits: 1 ± 2·clockDeviation. ppb → 2^-40: ·2^40/1e9. */
    /* Absolute limits 1 ± 2·clockDeviation; ppb → 2^-40 units is
     * ·2^40/1e9 (exact enough, and no overflow below 4e6 ppb). */
    int64_t abs_limit = ((int64_t)s->clock_deviation_ppb * 2 << 40) / 1000000000;
    if (candidate > abs_limit || candidate < -abs_limit)
        return 0;
    if (!c->have) {
        c->delta_q40 = candidate;
        c->have = 1;
        c->bucket = 0;
        return 1;
    }
    int64_t noise = ((int64_t)s->accepted_noise_ppb << 40) / 1000000000;
    int64_t d = candidate - c->delta_q40;
    if (d <= noise && d >= -noise) {
        /* Averaged with the value already calculated (§6.4.2). */
        c->delta_q40 = (c->delta_q40 + candidate) / 2;
        if (c->bucket < BUCKET_MAX)
            c->bucket++;
        return 1;
    }
    if (c->bucket > 0) {
        c->bucket--;
        return 0;
    }
    c->delta_q40 = candidate;
    return 1;
}

uint64_t swarm_clock_apply(uint64_t x, int64_t delta_q40)
{
    /* x < 2^35 and |delta| < 2^27 (≤ 100 ppm): the product fits. */
    int64_t corr = (int64_t)x * delta_q40;
    int64_t half = INT64_C(1) << (SWARM_CLOCK_Q - 1);
    corr = corr >= 0 ? (corr + half) >> SWARM_CLOCK_Q : -((-corr + half) >> SWARM_CLOCK_Q);
    return (uint64_t)((int64_t)x + corr);
}

int64_t swarm_tof_ticks(uint64_t round, uint64_t reply, int64_t delta_q40)
{
    int64_t twice = (int64_t)round - (int64_t)swarm_clock_apply(reply, delta_q40);
    /* Round half away from zero. */
    return twice >= 0 ? (twice + 1) / 2 : -((-twice + 1) / 2);
}

int swarm_exchange_tof(uint64_t local_tx, uint32_t remote_rx, uint32_t remote_tx, uint64_t local_rx,
                       int64_t delta_q40, int32_t antenna_delay, int32_t *tof)
{
    uint64_t round = swarm_stamp_since(local_rx, local_tx);
    if (round >= SWARM_MAX_SPAN)
        return -1;
    uint64_t reply = swarm_unwrap32(swarm_packet_since(remote_tx, remote_rx), round);
    if (reply >= SWARM_MAX_SPAN)
        return -1;
    int64_t t = swarm_tof_ticks(round, reply, delta_q40) - antenna_delay;
    if (t < 0 || t > SWARM_TOF_MAX_VALID)
        return -2;
    *tof = (int32_t)t;
    return 0;
}
