/*
 * The runtime's cluster side: the L1 area, the tile pipeline, the DMA
 * helpers, the requantization's slow forms, and the layer task that
 * dispatches on the layer's kind.
 */
#include "rt.h"

int8_t *nn_l1_tiles;
uint32_t nn_l1_tiles_bytes;
int8_t *nn_l1_scratch;

static void *l1_block;
static uint32_t l1_block_bytes, l1_budget;

int nn_l1_setup(struct pi_device *cluster, uint32_t budget)
{
    if (budget == 0 || budget > CL_L1_SIZE)
        budget = CL_L1_SIZE;
    if (l1_block && budget == l1_budget)
        return 0;
    if (l1_block)
        pi_l1_free(cluster, l1_block, l1_block_bytes);
    l1_block = NULL;
    /* The budget the host planned for, and the tables' scratch; when L1
     * has less (the stacks take their share), what it has: the layers
     * then shrink their tiles to fit (conv.c, pool.c). */
    uint32_t size = budget + NN_SCRATCH_BYTES;
    for (; size >= NN_SCRATCH_BYTES + 1024; size -= 256)
        if ((l1_block = pi_l1_malloc(cluster, size)) != NULL)
            break;
    if (!l1_block)
        return -1;
    l1_block_bytes = size;
    l1_budget = budget;
    nn_l1_tiles = l1_block;
    nn_l1_tiles_bytes = (size - NN_SCRATCH_BYTES) & ~7u;
    nn_l1_scratch = nn_l1_tiles + nn_l1_tiles_bytes;
    return 0;
}

/* ---- Requantization ---------------------------------------------------- */

#define SAT (1 << 24)

static int32_t sat64(int64_t v)
{
    return v > SAT ? SAT : v < -SAT ? -SAT : (int32_t)v;
}

int32_t rt_rq_slow(int32_t acc, int32_t mult, uint32_t shift)
{
    int64_t p = (int64_t)acc * mult;
    if (shift == 0)
        return sat64(p);
    if (shift >= 63)
        return 0;
    return sat64((p + ((int64_t)1 << (shift - 1))) >> shift);
}

int32_t rt_round_shift64(int64_t acc, uint32_t shift)
{
    if (shift == 0)
        return sat64(acc);
    if (shift >= 63)
        return 0;
    return sat64((acc + ((int64_t)1 << (shift - 1))) >> shift);
}

void rt_table_share(int8_t *tab, const nn_record_t *r, int32_t zp_in, int32_t zp_out,
                    int32_t lo, int32_t hi)
{
    int first, last;
    rt_share(256, &first, &last);
    nn_record_t rec = *r;
    for (int k = first; k < last; k++)
        tab[k] = (int8_t)rt_out(k - 128 - zp_in, &rec, zp_out, lo, hi);
}

/* ---- DMA --------------------------------------------------------------- */

void rt_load(rt_pipe_t *p, const void *l2, void *l1, uint32_t size)
{
    if (!size)
        return;
    pi_cl_dma_cmd((uint32_t)l2, (uint32_t)l1, size, PI_CL_DMA_DIR_EXT2LOC, &p->ld[p->cur]);
    p->ld_pending[p->cur] = 1;
    p->dma_bytes += size;
}

void rt_load_2d(rt_pipe_t *p, const void *l2, void *l1, uint32_t size, uint32_t stride,
                uint32_t length)
{
    if (!size)
        return;
    if (length == stride) {
        rt_load(p, l2, l1, size);
        return;
    }
    pi_cl_dma_cmd_2d((uint32_t)l2, (uint32_t)l1, size, stride, length, PI_CL_DMA_DIR_EXT2LOC,
                     &p->ld[p->cur]);
    p->ld_pending[p->cur] = 1;
    p->dma_bytes += size;
}

void rt_store(rt_pipe_t *p, void *l2, const void *l1, uint32_t size)
{
    if (!size)
        return;
    pi_cl_dma_cmd((uint32_t)l2, (uint32_t)l1, size, PI_CL_DMA_DIR_LOC2EXT, &p->st[p->cur]);
    p->st_pending[p->cur] = 1;
    p->dma_bytes += size;
}

void rt_store_2d(rt_pipe_t *p, void *l2, const void *l1, uint32_t size, uint32_t stride,
                 uint32_t length)
{
    if (!size)
        return;
    if (length == stride) {
        rt_store(p, l2, l1, size);
        return;
    }
    pi_cl_dma_cmd_2d((uint32_t)l2, (uint32_t)l1, size, stride, length, PI_CL_DMA_DIR_LOC2EXT,
                     &p->st[p->cur]);
    p->st_pending[p->cur] = 1;
    p->dma_bytes += size;
}

void rt_fill(int8_t *dst, int8_t v, uint32_t n)
{
    uint32_t word = (uint8_t)v * 0x01010101u;
    while (n && ((uint32_t)dst & 3)) {
        *dst++ = v;
        n--;
    }
    uint32_t *d = (uint32_t *)dst;
    for (; n >= 4; n -= 4)
        *d++ = word;
    dst = (int8_t *)d;
    while (n--)
        *dst++ = v;
}

/* ---- The pipeline ------------------------------------------------------ */

/* A wait on a command: commands complete in queue order and an id names
 * one queued command at most, so the wait also covers every command
 * queued before it (pmsis cl_dma.c). */
static void wait_ld(rt_pipe_t *p, int b)
{
    if (p->ld_pending[b]) {
        pi_cl_dma_cmd_wait(&p->ld[b]);
        p->ld_pending[b] = 0;
    }
}

static void wait_st(rt_pipe_t *p, int b)
{
    if (p->st_pending[b]) {
        pi_cl_dma_cmd_wait(&p->st[b]);
        p->st_pending[b] = 0;
    }
}

void rt_pipe_run(rt_pipe_t *p)
{
    p->ld_pending[0] = p->ld_pending[1] = 0;
    p->st_pending[0] = p->st_pending[1] = 0;
    if (p->n_tiles <= 0)
        return;
    p->cur = 0;
    p->load(p, 0, 0);
    for (int t = 0; t < p->n_tiles; t++) {
        int b = p->nbuf == 2 ? t & 1 : 0;
        wait_ld(p, b);
        if (p->ready)
            p->ready(p, t, b);
        /* The other set's inputs were read by tile t-1, whose fork has
         * returned: tile t+1 may land there while the team computes. */
        if (p->nbuf == 2 && t + 1 < p->n_tiles) {
            p->cur = 1 - b;
            p->load(p, t + 1, 1 - b);
        }
        /* This set's output was tile t-2's (t-1's with one set): written
         * back before the team overwrites it. */
        wait_st(p, b);
        p->t = t;
        p->b = b;
        pi_cl_team_fork(0, p->compute, p);
        p->cur = b;
        if (p->store)
            p->store(p, t, b);
        if (p->nbuf == 1 && t + 1 < p->n_tiles) {
            p->cur = 0;
            p->load(p, t + 1, 0);
        }
    }
    wait_st(p, 0);
    wait_st(p, 1);
}

/* ---- The layer task ---------------------------------------------------- */

static inline uint32_t cluster_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

void nn_layer_task(void *arg)
{
    nn_job_t *j = arg;
    uint32_t t0 = cluster_now();
    j->dma_bytes = 0;
    int st;
    switch (j->layer->kind) {
    case NN_CONV:
    case NN_DENSE:
        st = rt_conv(j);
        break;
    case NN_MAXPOOL:
    case NN_AVGPOOL:
        st = rt_pool(j);
        break;
    case NN_GAP:
        st = rt_gap(j);
        break;
    case NN_ADD:
        st = rt_add(j);
        break;
    case NN_CONCAT:
        st = rt_concat(j);
        break;
    case NN_REQUANT:
    case NN_LUT:
        st = rt_map(j);
        break;
    default:
        st = NN_E_LAYER;
    }
    j->status = st;
    j->cycles = cluster_now() - t0;
}
