/*
 * The network on the cluster: L1 layout, weight tiles, the DMA pipeline
 * (docs/NN_KERNELS.md "On the cluster").
 *
 * L1 holds two activation buffers (a layer reads one and writes the
 * other), each activation HWC with a one-pixel zero border, so the kernel
 * needs no bounds checks (the border is the reference's zero padding); a
 * depthwise layer's input is CHW instead, one padded plane per channel
 * (conv.h).
 * The weights do not fit in L1 (71 KB against 64 KB), so they come from L2
 * as tiles of whole output channels, with their requantization records,
 * into two slots: while the team computes tile i from one slot, the DMA
 * fills the other with tile i+1, across layer boundaries too. Everything
 * is derived from weights.h's descriptors; only the slot size is ours.
 */
#include "network.h"

#include <pmsis.h>
#include <stdio.h>

#include "conv.h"

/* Bytes per slot: a tile is the largest multiple of 4 output channels
 * (the kernel's quads) dividing out_c whose weights and records fit.
 * 9.5 KiB gives the base network's conv5 (288 + 16 bytes per channel)
 * 32-channel tiles and conv6 (576 + 16) 16-channel ones, and leaves L1
 * room for the two activation buffers and the 8 cores' stacks; a network
 * whose activations leave less room (the depthwise-separable one's
 * 40x40x16) takes the largest of the smaller sizes that fits (setup).
 * 6.5 KiB is the depthwise-separable one's: pw7 (192 + 16 bytes) in tiles
 * of 32 channels, 13 pixel pairs x 8 quads = 104 items, 13 per core
 * (6 KiB gave 24 channels, 78 items, 9 or 10 per core). */
static const int slot_sizes[] = {9728, 6656, 6144, 4608, 3072, 2048};

/* A slot holds a tile's weights, then its channels' requantization
 * records (conv.h nn_rq_t). */
typedef struct {
    uint32_t *w;
    pi_cl_dma_cmd_t cmd[2];
} slot_t;

/* Every layer's requantization records in L2, made once from weights.h
 * (nn_rq_make) in the form the layer's kernel uses (rq_mode): the
 * clip-first form when it is exact for every channel, else the 64-bit
 * one (fast when shift >= 15). The DMA brings a tile's with its weights. */
static nn_rq_t rq_store[NN_CHANNELS];
static const nn_rq_t *rq_layer[NN_N_LAYERS];
static int rq_mode[NN_N_LAYERS];
static int rq_ready;

static void make_records(void)
{
    nn_rq_t *r = rq_store;
    for (int i = 0; i < NN_N_LAYERS; i++) {
        const nn_layer_t *l = &nn_layers[i];
        int clip = 1;
        for (int c = 0; c < l->out_c; c++)
            clip &= nn_rq_make(l->bias[c], l->mult[c], l->shift, l->out_min, l->out_max, &r[c]);
        if (!clip)
            for (int c = 0; c < l->out_c; c++)
                r[c] = (nn_rq_t){0, 0, l->mult[c], l->bias[c]};
        rq_mode[i] = clip ? NN_RQ_CLIP : l->shift >= 15 ? NN_RQ_FAST : NN_RQ_GENERAL;
        rq_layer[i] = r;
        r += l->out_c;
    }
    rq_ready = 1;
}

static inline uint32_t cluster_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

/* Bytes of one padded activation (h + 2) x (w + 2) x c. */
static int padded(int h, int w, int c) { return (h + 2) * (w + 2) * c; }

/* Bytes of one kernel row of one channel's weights as weights.c stores
 * them: k*in_c, or a whole word for a depthwise layer (weights.h). */
static int stored_row(const nn_layer_t *l) { return l->depthwise ? 4 : l->k * l->in_c; }

/* Layer i writes CHW planes when a depthwise layer reads them (conv.h). */
static int writes_chw(int i) { return i + 1 < NN_N_LAYERS && nn_layers[i + 1].depthwise; }

/* A layer's weight row (one ky of a channel) in kernel words: its stored
 * bytes used in place when they are whole words; rows of at most 4 bytes
 * (conv1: 3x1) are repacked one per word, the spare bytes zero. 0: not
 * supported. */
static int row_words(const nn_layer_t *l)
{
    int row = stored_row(l);
    if (row % 4 == 0)
        return row / 4;
    return row <= 4 ? 1 : 0;
}

/* Bytes of one output channel in a slot: its weights and its record. */
static int channel_bytes(const nn_layer_t *l) { return l->k * stored_row(l); }

static int tile_channels(const nn_layer_t *l, int slot_bytes)
{
    int ch = channel_bytes(l) + (int)sizeof(nn_rq_t);
    for (int t = l->out_c; t >= 4; t--)
        if (l->out_c % t == 0 && t % 4 == 0 && t * ch <= slot_bytes)
            return t;
    return 0;
}

/* The depthwise kernel's window: 3x3, a one-pixel pad, stride 1 or 2, an
 * int8 output. */
static int planar_3x3(const nn_layer_t *l)
{
    return l->k == 3 && l->pad == 1 && (l->stride == 1 || l->stride == 2) && l->out_max <= 127;
}

/* What the depthwise kernel takes: its window, one channel per channel. */
static int depthwise_ok(const nn_layer_t *l) { return planar_3x3(l) && l->in_c == l->out_c; }

/* A 3x3 layer over one input channel (conv1) is a depthwise layer whose
 * every output channel reads the same plane: the depthwise kernel runs it
 * (conv.c plane_items: two channels' output row per item, their weight
 * words and records in registers, each input word feeding both), where
 * the 2x4 kernel would spend a whole window word on each 3-byte row and
 * recompute the window per channel quad. */
static int one_plane(const nn_layer_t *l)
{
    return !l->depthwise && l->in_c == 1 && planar_3x3(l);
}

/* What the pointwise kernel takes (conv.c "Pointwise"). */
static int pointwise(const nn_layer_t *l, int mode)
{
    return l->k == 1 && l->stride == 1 && l->pad == 0 && l->in_c % 16 == 0 && !l->depthwise &&
           mode == NN_RQ_CLIP;
}

/* Tiles in network order: (layer, first channel); the tile after the last
 * of a layer is the next layer's first. */
typedef struct {
    int layer, c0, n;
} tile_t;

static tile_t tiles[64];
static int n_tiles;

static int plan(int slot_bytes)
{
    n_tiles = 0;
    for (int i = 0; i < NN_N_LAYERS; i++) {
        const nn_layer_t *l = &nn_layers[i];
        int t = tile_channels(l, slot_bytes);
        if (!t || !row_words(l) || l->pad > 1 || l->shift < 1 || l->shift > 31 ||
            (l->depthwise && !depthwise_ok(l)))
            return -1;
        for (int c = 0; c < l->out_c; c += t) {
            if (n_tiles == (int)(sizeof tiles / sizeof tiles[0]))
                return -1;
            tiles[n_tiles++] = (tile_t){i, c, t};
        }
    }
    return 0;
}

/* Where a tile's records lie in its slot: after its weights (n * the
 * channel's bytes, a multiple of 4 as n is). */
static const nn_rq_t *slot_records(const tile_t *t, const slot_t *s)
{
    return (const nn_rq_t *)((const int8_t *)s->w + t->n * channel_bytes(&nn_layers[t->layer]));
}

static void fetch(const tile_t *t, slot_t *s)
{
    const nn_layer_t *l = &nn_layers[t->layer];
    uint32_t ch = (uint32_t)channel_bytes(l);
    pi_cl_dma_cmd((uint32_t)(l->w + t->c0 * ch), (uint32_t)s->w, t->n * ch,
                  PI_CL_DMA_DIR_EXT2LOC, &s->cmd[0]);
    pi_cl_dma_cmd((uint32_t)(rq_layer[t->layer] + t->c0), (uint32_t)slot_records(t, s),
                  t->n * sizeof(nn_rq_t), PI_CL_DMA_DIR_EXT2LOC, &s->cmd[1]);
}

static void wait_slot(slot_t *s)
{
    for (int i = 0; i < 2; i++)
        pi_cl_dma_cmd_wait(&s->cmd[i]);
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
 * cluster stays open (the allocation is not part of an inference). The
 * two activation buffers are sized apart: layer i writes buffer (i+1)&1. */
static struct {
    int ready;
    int act_bytes[2], repack_words, head_bytes;
    int8_t *act[2];
    int16_t *head;
    uint32_t *packed;
    slot_t slot[2];
} l1;

/* Every L1 block of the working set, (pointer, bytes), for a retry with a
 * smaller slot. */
static void *l1_blocks[16];
static int l1_sizes[16], n_l1_blocks;

static void *l1_alloc(struct pi_device *cl, int bytes)
{
    void *p = pi_l1_malloc(cl, bytes);
    if (p) {
        l1_blocks[n_l1_blocks] = p;
        l1_sizes[n_l1_blocks++] = bytes;
    }
    return p;
}

static void l1_free_all(struct pi_device *cl)
{
    while (n_l1_blocks > 0) {
        n_l1_blocks--;
        pi_l1_free(cl, l1_blocks[n_l1_blocks], l1_sizes[n_l1_blocks]);
    }
}

/* Plans the tiles for `slot_bytes` and allocates the working set: 0, or -1
 * (nothing left allocated) when a layer does not fit the kernels or the
 * set does not fit in L1. */
static int try_setup(struct pi_device *cl, int slot_bytes)
{
    if (plan(slot_bytes) != 0)
        return -1;
    const nn_layer_t *first = &nn_layers[0], *last = &nn_layers[NN_N_LAYERS - 1];
    l1.act_bytes[0] = padded(first->in_h, first->in_w, first->in_c);
    l1.act_bytes[1] = 0;
    l1.repack_words = 0;
    for (int i = 0; i < n_tiles; i++) {
        const nn_layer_t *l = &nn_layers[tiles[i].layer];
        int b = (tiles[i].layer + 1) & 1, out = padded(l->out_h, l->out_w, l->out_c);
        if (tiles[i].layer != NN_N_LAYERS - 1 && out > l1.act_bytes[b])
            l1.act_bytes[b] = out;
        if (stored_row(l) % 4 && l->k * tiles[i].n > l1.repack_words)
            l1.repack_words = l->k * tiles[i].n;
    }
    l1.head_bytes = last->out_h * last->out_w * last->out_c * 2;
    int ok = 1;
    n_l1_blocks = 0;
    for (int s = 0; s < 2 && ok; s++) {
        /* + 4: the depthwise kernel's last word of a row may reach 3 bytes
         * past its plane (those bytes meet zero weights). */
        ok &= (l1.act[s] = l1_alloc(cl, l1.act_bytes[s] + 4)) != NULL;
        ok = ok && (l1.slot[s].w = l1_alloc(cl, slot_bytes)) != NULL;
    }
    ok = ok && (l1.head = l1_alloc(cl, l1.head_bytes)) != NULL;
    if (ok && l1.repack_words)
        ok = (l1.packed = l1_alloc(cl, l1.repack_words * 4)) != NULL;
    if (!ok) {
        l1_free_all(cl);
        return -1;
    }
    return 0;
}

static int setup(struct pi_device *cl)
{
    if (!rq_ready)
        make_records();
    for (unsigned i = 0; i < sizeof slot_sizes / sizeof slot_sizes[0]; i++)
        if (try_setup(cl, slot_sizes[i]) == 0) {
            l1.ready = 1;
            return 0;
        }
    printf("nn: the layers of weights.h do not fit the kernels (pad <= 1, shift 1-31, depthwise "
           "3x3) or L1 with a %d-byte weight slot\n",
           slot_sizes[sizeof slot_sizes / sizeof slot_sizes[0] - 1]);
    return -1;
}

void nn_network_release(void) { l1.ready = 0; }

/* The kernel's view of tile `ti` with its weights at `w`, its records in
 * slot `s`. */
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
        .rq = slot_records(ti, s),
        .mode = rq_mode[ti->layer],
        .shift = l->shift,
        .lo = l->out_min,
        .hi = l->out_max,
        .channels = ti->n,
        .out_w = l->out_w,
        .out_h = l->out_h,
        .out_pix = l->out_c,
        .out_cstep = 1,
        .out_int16 = l->out_max > 127,
    };
    if (l->depthwise || one_plane(l)) {
        /* CHW planes in (conv.h; pad 1, so no offset; one plane for all
         * channels when one_plane), HWC or CHW out below. */
        t.in_plane = l->depthwise ? padded(l->in_h, l->in_w, 1) : 0;
        t.in = l1.act[ti->layer & 1] + ti->c0 * t.in_plane;
        t.in_row = l->in_w + 2;
        t.stride = l->stride;
    }
    /* The output's zero border (the next layer's padding), zeroed by the
     * team at the tile's start (conv.h zero_*): a CHW tile's own planes,
     * an HWC layer's whole border with its first tile. */
    t.zero_h = l->out_h;
    t.zero_w = l->out_w;
    if (ti->layer == NN_N_LAYERS - 1) {
        t.zero_h = 0;
    } else if (writes_chw(ti->layer)) {
        t.zero_at = l1.act[(ti->layer + 1) & 1] + ti->c0 * padded(l->out_h, l->out_w, 1);
        t.zero_c = ti->n;
        t.zero_chw = 1;
    } else if (ti->c0 == 0) {
        t.zero_at = l1.act[(ti->layer + 1) & 1];
        t.zero_c = l->out_c;
    } else {
        t.zero_h = 0;
    }
    if (ti->layer == NN_N_LAYERS - 1) {
        /* The head: unpadded, to be copied to L2 as it is. */
        t.out = l1.head + ti->c0;
        t.out_row = l->out_w;
    } else if (writes_chw(ti->layer)) {
        /* Planes for the depthwise layer after: channel c's at c * plane. */
        int plane = padded(l->out_h, l->out_w, 1);
        t.out = l1.act[(ti->layer + 1) & 1] + ti->c0 * plane + (l->out_w + 2) + 1;
        t.out_row = l->out_w + 2;
        t.out_pix = 1;
        t.out_cstep = plane;
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
        const uint32_t *w = s->w;
        if (stored_row(l) % 4) {
            repack(l1.packed, s->w, ti->n, l->k, stored_row(l));
            w = l1.packed;
        }
        conv_tile_t t = tile_args(ti, w, s);
        pi_cl_team_fork(0,
                        l->depthwise || one_plane(l)      ? dw_tile_share
                        : pointwise(l, rq_mode[ti->layer]) ? pw_tile_share
                        : writes_chw(ti->layer) ? conv_tile_share_chw
                                                : conv_tile_share,
                        &t);
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
