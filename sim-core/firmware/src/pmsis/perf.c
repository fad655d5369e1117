/*
 * Performance counters per core, PMSIS style (conf, reset, start, stop,
 * read), from the core's own CSRs: minstret, mcycle (cycles awake; a core
 * asleep in the event unit or in wfi does not count) and, for
 * PI_PERF_CYCLES, the wall clock of the core's domain (the `time` CSR).
 */
#include "pmsis_internal.h"

enum { CNT_CYCLES, CNT_ACTIVE, CNT_INSTR, CNT_N };

/* Index 0..7: cluster cores, 8: the FC. */
static struct perf {
    unsigned events;
    int running;
    uint32_t start[CNT_N];
    uint32_t total[CNT_N];
} perf[CL_MAX_CORES + 1];

static struct perf *mine(void)
{
    return &perf[pi_is_fc() ? CL_MAX_CORES : pi_core_id()];
}

/* The `time` CSR counts every cycle of the core's clock, asleep or not:
 * the FC's CLINT mtime, a cluster core's cluster clock (docs/CLUSTER.md). */
static uint32_t wall_cycles(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

static void sample(uint32_t v[CNT_N])
{
    v[CNT_CYCLES] = wall_cycles();
    __asm__ volatile("csrr %0, mcycle" : "=r"(v[CNT_ACTIVE]));
    __asm__ volatile("csrr %0, minstret" : "=r"(v[CNT_INSTR]));
}

void pi_perf_conf(unsigned events)
{
    mine()->events = events;
}

void pi_perf_reset(void)
{
    struct perf *p = mine();
    for (int i = 0; i < CNT_N; i++)
        p->total[i] = 0;
    if (p->running)
        sample(p->start);
}

void pi_perf_start(void)
{
    struct perf *p = mine();
    if (!p->running) {
        sample(p->start);
        p->running = 1;
    }
}

void pi_perf_stop(void)
{
    struct perf *p = mine();
    if (p->running) {
        uint32_t now[CNT_N];
        sample(now);
        for (int i = 0; i < CNT_N; i++)
            p->total[i] += now[i] - p->start[i];
        p->running = 0;
    }
}

unsigned int pi_perf_read(int event)
{
    struct perf *p = mine();
    int c;
    switch (event) {
    case PI_PERF_CYCLES: c = CNT_CYCLES; break;
    case PI_PERF_ACTIVE_CYCLES: c = CNT_ACTIVE; break;
    case PI_PERF_INSTR: c = CNT_INSTR; break;
    default: return 0;
    }
    if (!(p->events & (1u << event)))
        return 0;
    uint32_t v = p->total[c];
    if (p->running) {
        uint32_t now[CNT_N];
        sample(now);
        v += now[c] - p->start[c];
    }
    return v;
}
