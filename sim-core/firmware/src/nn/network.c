/*
 * The network on the cluster: L1 layout, weight tiles, the DMA pipeline
 * (docs/NN.md "On the cluster").
 *
 * L1 holds two activation buffers (a layer reads one and writes the
 * other), each activation HWC with a one-pixel zero border, so the kernel
 * needs no bounds checks (the border is the reference's zero padding).
 * The weights do not fit in L1 (71 KB against 64 KB), so they come from L2
 * as tiles of whole output channels, with their biases and multipliers,
 * into two slots: while the team computes tile i from one slot, the DMA
 * fills the other with tile i+1, across layer boundaries too. Everything
 * is derived from weights.h's descriptors; only the slot size is ours.
 */
#include "network.h"

#include <pmsis.h>
#include <stdio.h>
#include <string.h>

#include "conv.h"

/* Bytes of weights per slot: a tile is the largest multiple of 4 output
 * channels (the kernel's quads) dividing out_c whose weights fit. 9 KiB
 * gives conv6 (576 bytes per channel) 16-channel tiles and leaves L1 room
 * for the two activation buffers and the 8 cores' stacks. */
#define NN_SLOT_BYTES 9216

typedef struct {
    uint32_t *w;
    int32_t *bias, *mult;
    pi_cl_dma_cmd_t cmd[3];
} slot_t;

static inline uint32_t cluster_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

/* Bytes of one padded activation (h + 2) x (w + 2) x c. */
static int padded(int h, int w, int c) { return (h + 2) * (w + 2) * c; }

/* A layer's weight row (one ky of a channel) in bytes as the layer stores
 * it, and in kernel words: k*cin bytes, used in place when they are whole
 * words; rows of at most 4 bytes (conv1: 3x1) are repacked one per word,
 * the spare bytes zero. 0: not supported. */
static int row_words(const nn_layer_t *l)
{
    int row = l->k * l->in_c;
    if (row % 4 == 0)
        return row / 4;
    return row <= 4 ? 1 : 0;
}

static int tile_channels(const nn_layer_t *l)
{
    int ch = l->k * l->k * l->in_c;
    for (int t = l->out_c; t >= 4; t--)
        if (l->out_c % t == 0 && t % 4 == 0 && t * ch <= NN_SLOT_BYTES)
            return t;
    return 0;
}

/* Tiles in network order: (layer, first channel); the tile after the last
 * of a layer is the next layer's first. */
typedef struct {
    int layer, c0, n;
} tile_t;

static tile_t tiles[64];
static int n_tiles;

static int plan(void)
{
    n_tiles = 0;
    for (int i = 0; i < NN_N_LAYERS; i++) {
        const nn_layer_t *l = &nn_layers[i];
        int t = tile_channels(l);
        if (!t || !row_words(l) || l->pad > 1 || l->shift < 1 || l->shift > 31)
            return -1;
        for (int c = 0; c < l->out_c; c += t) {
            if (n_tiles == (int)(sizeof tiles / sizeof tiles[0]))
                return -1;
            tiles[n_tiles++] = (tile_t){i, c, t};
        }
    }
    return 0;
}

static void fetch(const tile_t *t, slot_t *s)
{
    const nn_layer_t *l = &nn_layers[t->layer];
    uint32_t ch = (uint32_t)l->k * l->k * l->in_c;
    pi_cl_dma_cmd((uint32_t)(l->w + t->c0 * ch), (uint32_t)s->w, t->n * ch,
                  PI_CL_DMA_DIR_EXT2LOC, &s->cmd[0]);
    pi_cl_dma_cmd((uint32_t)(l->bias + t->c0), (uint32_t)s->bias, t->n * 4,
                  PI_CL_DMA_DIR_EXT2LOC, &s->cmd[1]);
    pi_cl_dma_cmd((uint32_t)(l->mult + t->c0), (uint32_t)s->mult, t->n * 4,
                  PI_CL_DMA_DIR_EXT2LOC, &s->cmd[2]);
}

static void wait_slot(slot_t *s)
{
    for (int i = 0; i < 3; i++)
        pi_cl_dma_cmd_wait(&s->cmd[i]);
}

/* The zero border of a padded activation. */
static void zero_border(int8_t *a, int h, int w, int c)
{
    int row = (w + 2) * c;
    memset(a, 0, row);
    memset(a + (h + 1) * row, 0, row);
    for (int y = 1; y <= h; y++) {
        memset(a + y * row, 0, c);
        memset(a + y * row + (w + 1) * c, 0, c);
    }
}

/* Rows of k bytes (k*cin <= 4) one per word, spare bytes zero. */
static void repack(uint32_t *dst, const uint32_t *src_words, int channels, int k, int row)
{
    const int8_t *src = (const int8_t *)src_words;
    int8_t *d = (int8_t *)dst;
    for (int i = 0; i < channels * k; i++)
        for (int b = 0; b < 4; b++)
            d[4 * i + b] = b < row ? src[i * row + b] : 0;
}

/* The L1 working set, allocated at the first inference and kept while the
 * cluster stays open (the allocation is not part of an inference). */
static struct {
    int ready;
    int act_bytes, max_tile, repack_words, head_bytes;
    int8_t *act[2];
    int16_t *head;
    uint32_t *packed;
    slot_t slot[2];
} l1;

static int setup(struct pi_device *cl)
{
    if (plan() != 0) {
        printf("nn: a layer of weights.h does not fit the kernel (pad <= 1, shift 1-31) or a %d-byte slot\n",
               NN_SLOT_BYTES);
        return -1;
    }
    const nn_layer_t *first = &nn_layers[0], *last = &nn_layers[NN_N_LAYERS - 1];
    l1.act_bytes = padded(first->in_h, first->in_w, first->in_c);
    for (int i = 0; i < n_tiles; i++) {
        const nn_layer_t *l = &nn_layers[tiles[i].layer];
        int out = padded(l->out_h, l->out_w, l->out_c);
        l1.act_bytes = l1.act_bytes > out ? l1.act_bytes : out;
        l1.max_tile = l1.max_tile > tiles[i].n ? l1.max_tile : tiles[i].n;
        if ((l->k * l->in_c) % 4 && l->k * tiles[i].n > l1.repack_words)
            l1.repack_words = l->k * tiles[i].n;
    }
    l1.head_bytes = last->out_h * last->out_w * last->out_c * 2;
    int ok = 1;
    for (int s = 0; s < 2; s++) {
        ok &= (l1.act[s] = pi_l1_malloc(cl, l1.act_bytes)) != NULL;
        ok &= (l1.slot[s].w = pi_l1_malloc(cl, NN_SLOT_BYTES)) != NULL;
        ok &= (l1.slot[s].bias = pi_l1_malloc(cl, l1.max_tile * 4)) != NULL;
        ok &= (l1.slot[s].mult = pi_l1_malloc(cl, l1.max_tile * 4)) != NULL;
    }
    ok &= (l1.head = pi_l1_malloc(cl, l1.head_bytes)) != NULL;
    if (l1.repack_words)
        ok &= (l1.packed = pi_l1_malloc(cl, l1.repack_words * 4)) != NULL;
    if (!ok) {
        printf("nn: not enough L1 (two %d-byte activations, two %d-byte slots)\n", l1.act_bytes,
               NN_SLOT_BYTES);
        return -1;
    }
    l1.ready = 1;
    return 0;
}

void nn_network_release(void) { l1.ready = 0; }

/* The kernel's view of tile `ti` with its weights at `w`, its biases and
 * multipliers in slot `s`. */
static conv_tile_t tile_args(const tile_t *ti, const uint32_t *w, const slot_t *s)
{
    const nn_layer_t *l = &nn_layers[ti->layer];
    int in_row = (l->in_w + 2) * l->in_c, off = 1 - l->pad;
    conv_tile_t t = {
        .in = l1.act[ti->layer & 1] + off * in_row + off * l->in_c,
        .in_row = in_row,
        .in_pix = l->stride * l->in_c,
        .in_ystep = l->stride * in_row,
        .k = l->k,
        .row_words = row_words(l),
        .w = w,
        .bias = s->bias,
        .mult = s->mult,
        .shift = l->shift,
        .lo = l->out_min,
        .hi = l->out_max,
        .channels = ti->n,
        .out_w = l->out_w,
        .out_h = l->out_h,
        .out_pix = l->out_c,
        .out_int16 = l->out_max > 127,
    };
    if (ti->layer == NN_N_LAYERS - 1) {
        /* The head: unpadded, to be copied to L2 as it is. */
        t.out = l1.head + ti->c0;
        t.out_row = l->out_w;
    } else {
        t.out = l1.act[(ti->layer + 1) & 1] + ((l->out_w + 2) + 1) * l->out_c + ti->c0;
        t.out_row = l->out_w + 2;
    }
    return t;
}

void nn_network_run(void *arg)
{
    nn_job_t *job = arg;
    job->status = -1;
    if (!l1.ready && setup(job->cluster) != 0)
        return;
    uint32_t start = cluster_now();
    const nn_layer_t *first = &nn_layers[0];
    pi_cl_dma_cmd_t input;
    pi_cl_dma_cmd((uint32_t)job->input, (uint32_t)l1.act[0],
                  padded(first->in_h, first->in_w, first->in_c), PI_CL_DMA_DIR_EXT2LOC, &input);
    fetch(&tiles[0], &l1.slot[0]);
    pi_cl_dma_cmd_wait(&input);
    uint32_t layer_start = cluster_now();
    for (int i = 0; i < n_tiles; i++) {
        const tile_t *ti = &tiles[i];
        const nn_layer_t *l = &nn_layers[ti->layer];
        slot_t *s = &l1.slot[i & 1];
        wait_slot(s);
        /* Double buffering: tile i+1 arrives while the team computes tile i. */
        if (i + 1 < n_tiles)
            fetch(&tiles[i + 1], &l1.slot[(i + 1) & 1]);
        if (ti->c0 == 0 && ti->layer != NN_N_LAYERS - 1)
            zero_border(l1.act[(ti->layer + 1) & 1], l->out_h, l->out_w, l->out_c);
        const uint32_t *w = s->w;
        if ((l->k * l->in_c) % 4) {
            repack(l1.packed, s->w, ti->n, l->k, l->k * l->in_c);
            w = l1.packed;
        }
        conv_tile_t t = tile_args(ti, w, s);
        pi_cl_team_fork(0, conv_tile_share, &t);
        if (i + 1 == n_tiles || tiles[i + 1].layer != ti->layer) {
            uint32_t now = cluster_now();
            job->layer_cycles[ti->layer] = now - layer_start;
            layer_start = now;
        }
    }
    pi_cl_dma_cmd_t back;
    pi_cl_dma_cmd((uint32_t)job->head, (uint32_t)l1.head, l1.head_bytes, PI_CL_DMA_DIR_LOC2EXT,
                  &back);
    pi_cl_dma_cmd_wait(&back);
    job->cycles = cluster_now() - start;
    job->status = 0;
}
