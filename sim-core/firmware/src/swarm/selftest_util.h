/* Shared by the swarm self-test's files: checks, cycle counter, noise. */
#ifndef SWARM_SELFTEST_UTIL_H
#define SWARM_SELFTEST_UTIL_H

#include <stdint.h>
#include <stdio.h>

#include "../cycles.h"
#include "prng.h"

extern int st_checks, st_failures;

/* Count a check; print it when it fails. */
#define CHECK(cond, ...)                                                                   \
    do {                                                                                   \
        st_checks++;                                                                       \
        if (!(cond)) {                                                                     \
            st_failures++;                                                                 \
            printf("FAIL %s:%d: ", __FILE__, __LINE__);                                    \
            printf(__VA_ARGS__);                                                           \
            printf("\n");                                                                  \
        }                                                                                  \
    } while (0)

/* The core's mcycle CSR (awake cycles, 64 bits). */
static inline uint64_t st_cycles(void)
{
    return csr_mcycle64();
}

/* Standard normal draw: sum of 12 uniforms minus 6 (Irwin-Hall; no libm). */
static inline float st_gauss(swarm_prng_t *r)
{
    float s = 0.0f;
    for (int i = 0; i < 12; i++)
        s += (float)(swarm_prng_next(r) >> 8) * (1.0f / 16777216.0f);
    return s - 6.0f;
}

/* Cost statistics of one piece of code, in cycles. */
typedef struct {
    const char *name;
    uint64_t total, max;
    uint32_t count;
} st_cost_t;

static inline void st_cost_add(st_cost_t *c, uint64_t cycles)
{
    c->total += cycles;
    c->count++;
    if (cycles > c->max)
        c->max = cycles;
}

static inline void st_cost_print(const st_cost_t *c)
{
    unsigned long mean = c->count ? (unsigned long)(c->total / c->count) : 0;
    printf("cycles %s: mean %lu max %lu n %lu\n", c->name, mean, (unsigned long)c->max,
           (unsigned long)c->count);
}

#endif
