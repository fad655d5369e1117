/*
 * The firmware's deterministic generator: xorshift32 (Marsaglia 2003),
 * seeded through splitmix64 from the radio's EUI, so drones with EUIs 1, 2,
 * 3 get unrelated streams and every run repeats exactly. It replaces the
 * thesis's rand() seeded from the DW1000 clock (§6.2).
 */
#ifndef SWARM_PRNG_H
#define SWARM_PRNG_H

#include <stdint.h>

typedef struct {
    uint32_t s;
} swarm_prng_t;

static inline void swarm_prng_seed(swarm_prng_t *r, uint64_t seed)
{
    uint64_t z = seed + UINT64_C(0x9e3779b97f4a7c15);
    z = (z ^ (z >> 30)) * UINT64_C(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94d049bb133111eb);
    z ^= z >> 31;
    uint32_t s = (uint32_t)z ^ (uint32_t)(z >> 32);
    r->s = s ? s : 0x6d2b79f5u; /* xorshift's one forbidden state */
}

static inline uint32_t swarm_prng_next(swarm_prng_t *r)
{
    uint32_t x = r->s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return r->s = x;
}

/* Uniform in [0, n), n > 0 (the bias of the modulo is below n/2^32). */
static inline uint32_t swarm_prng_below(swarm_prng_t *r, uint32_t n)
{
    return (uint32_t)(((uint64_t)swarm_prng_next(r) * n) >> 32);
}

#endif
