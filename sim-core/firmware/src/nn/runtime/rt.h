/*
 * What the runtime's cluster files share (not for the FC): the L1 area,
 * the tile pipeline, the DMA helpers and the integer arithmetic of
 * model.h.
 */
#ifndef NN_RUNTIME_RT_H
#define NN_RUNTIME_RT_H

#include <stdint.h>

#include <pmsis.h>

#include "kernels.h"
#include "model.h"

/* The tiles' area (two buffer sets) and a scratch area after it for the
 * 256-entry tables (CONCAT: one per input). */
#define NN_SCRATCH_BYTES (NN_MAX_IN * 256)
extern int8_t *nn_l1_tiles;
extern uint32_t nn_l1_tiles_bytes;
extern int8_t *nn_l1_scratch;

static inline uint32_t a4(uint32_t n) { return (n + 3u) & ~3u; }

static inline const nn_value_t *rt_value(const nn_job_t *j, uint32_t i)
{
    return (const nn_value_t *)(j->l2 + j->model->values_off) + i;
}

static inline int8_t *rt_at(const nn_job_t *j, uint32_t off)
{
    return (int8_t *)(j->l2 + off);
}

static inline int32_t rt_clamp(int32_t v, int32_t lo, int32_t hi)
{
    v = v < lo ? lo : v;
    return v > hi ? hi : v;
}

/* ---- Requantization (model.h) ----------------------------------------- */

/* rq(acc) = (acc * mult + 2^(shift-1)) >> shift in 64 bits for shifts
 * 0..62, 0 for 63, saturated to +-2^24 (beyond any int8 output once the
 * zero point is added and the clamp applied). */
int32_t rt_rq_slow(int32_t acc, int32_t mult, uint32_t shift);

/* The same. For shift in 33..62, the records' usual range (a ratio below
 * 2^-2: mult has 31 bits), the rounding constant lies in the high word:
 * (p + 2^(s-1)) >> s = (hi(p) + 2^(s-33)) >> (s-32), one mulh, no
 * carry (|p| < 2^62, so |hi| < 2^30 and the sum stays in int32). */
static inline int32_t rt_rq(int32_t acc, int32_t mult, uint32_t shift)
{
    if (shift - 33u < 30u) {
        int32_t hi = (int32_t)(((int64_t)acc * mult) >> 32);
        return (hi + (1 << (shift - 33))) >> (shift - 32);
    }
    return rt_rq_slow(acc, mult, shift);
}

/* clamp(zp_out + rq(acc), lo, hi). */
static inline int32_t rt_out(int32_t acc, const nn_record_t *r, int32_t zp, int32_t lo,
                             int32_t hi)
{
    return rt_clamp(zp + rt_rq(acc, r->mult, r->shift), lo, hi);
}

/* `a / b` rounded half to even (b > 0), the reference's
 * div_round_half_even. */
static inline int32_t rt_div_rhe(int32_t a, int32_t b)
{
    int32_t q = a / b, r = a % b;
    if (r < 0) {
        q -= 1;
        r += b;
    }
    if (2 * r > b || (2 * r == b && (q & 1)))
        q++;
    return q;
}

/* (acc + 2^(shift-1)) >> shift in 64 bits (ADD's common shift): shift 0
 * the sum itself, 63 zero; saturated as rt_rq_slow. */
int32_t rt_round_shift64(int64_t acc, uint32_t shift);

/* tab[q + 128] = clamp(zp_out + rq(q - zp_in), lo, hi) for the 256 int8
 * q: an element-wise requantization as one table lookup. Team-shared
 * (a pi_cl_team_fork entry's body): this core's entries. */
void rt_table_share(int8_t *tab, const nn_record_t *r, int32_t zp_in, int32_t zp_out,
                    int32_t lo, int32_t hi);

/* This core's share [first, last) of n items. */
static inline void rt_share(int n, int *first, int *last)
{
    int cores = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    *first = n * i / cores;
    *last = n * (i + 1) / cores;
}

/* ---- The tile pipeline (kernels.c) ------------------------------------ */

/* One layer's tiles through two L1 buffer sets: while the team computes
 * tile t from set t&1, the DMA brings tile t+1 into the other set, and
 * writes tile t back after (double buffering, DORY §III-B). Core 0 runs
 * the loop and issues every DMA command: commands complete in the order
 * they were queued, so waiting for a group's last command waits for the
 * group. */
typedef struct rt_pipe rt_pipe_t;
struct rt_pipe {
    int n_tiles;
    int nbuf; /* 2, or 1 when one set is all L1 holds */
    /* Core 0: queue tile t's loads into set b (and fill what the DMA does
     * not bring); called before the team computes tile t-1. */
    void (*load)(rt_pipe_t *p, int t, int b);
    /* Core 0, once tile t's loads are done, before its compute. */
    void (*ready)(rt_pipe_t *p, int t, int b);
    /* The team's entry (pi_cl_team_fork): computes tile p->t from set p->b. */
    void (*compute)(void *p);
    /* Core 0: queue tile t's write-back from set b. */
    void (*store)(rt_pipe_t *p, int t, int b);
    volatile int t, b;
    pi_cl_dma_cmd_t ld[2], st[2];
    int ld_pending[2], st_pending[2];
    uint32_t dma_bytes;
    int cur; /* the set the load/store being queued belongs to */
};

void rt_pipe_run(rt_pipe_t *p);

/* DMA commands of the set p->cur: L2 -> L1 (a load) and L1 -> L2 (a
 * store), 1D or 2D (on the L2 side `length` bytes every `stride`). */
void rt_load(rt_pipe_t *p, const void *l2, void *l1, uint32_t size);
void rt_load_2d(rt_pipe_t *p, const void *l2, void *l1, uint32_t size, uint32_t stride,
                uint32_t length);
void rt_store(rt_pipe_t *p, void *l2, const void *l1, uint32_t size);
void rt_store_2d(rt_pipe_t *p, void *l2, const void *l1, uint32_t size, uint32_t stride,
                 uint32_t length);

/* Fills n bytes with v (core 0). */
void rt_fill(int8_t *dst, int8_t v, uint32_t n);

/* ---- The layer kinds (conv.c, pool.c, eltwise.c) ---------------------- */

int rt_conv(nn_job_t *j);  /* CONV and DENSE */
int rt_pool(nn_job_t *j);  /* MAXPOOL, AVGPOOL */
int rt_gap(nn_job_t *j);
int rt_add(nn_job_t *j);
int rt_map(nn_job_t *j);   /* REQUANT, LUT */
int rt_concat(nn_job_t *j);

#endif
