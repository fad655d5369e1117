/*
 * The int8 kernels (docs/NN_KERNELS.md "On the cluster"), each a team-shared tile
 * entry (conv.h):
 * - conv_tile_share(_chw): the general kernel. Work item: two output
 *   pixels (consecutive in raster order) by four output channels: per
 *   word of the window, 2 input loads and 4 weight loads feed 8
 *   cv.sdotsp.b (32 MACs), the register-blocking of PULP-NN's kernels
 *   (Garofalo et al. 2020, §4: "4x2" output blocks) on HWC data, where one
 *   row of a 3x3 window is 3*cin contiguous bytes in the input and in the
 *   weights;
 * - pw_tile_share: the same blocking for 1x1 layers, walked pair by pair;
 * - dw_tile_share: the depthwise kernel (a channel's rows over its own CHW
 *   plane), which also runs a 3x3 layer over one input plane (conv1).
 */
#include "conv.h"

#include <pmsis.h>

#include "../xcv.h"

/* Output pixel (y, x): its window's offset in the input and its element
 * offset in the output. */
typedef struct {
    int in, out;
} pixel_t;

static inline pixel_t pixel(const conv_tile_t *t, int y, int x)
{
    return (pixel_t){y * t->in_ystep + x * t->in_pix, (y * t->out_row + x) * t->out_pix};
}

/* One word of the two windows times one word of the four channels. */
#define STEP_2x4()                                                             \
    do {                                                                       \
        uint32_t v0 = xcv_lw_inc(x0, 4), v1 = xcv_lw_inc(x1, 4);               \
        uint32_t q0 = xcv_lw_inc(k0, 4), q1 = xcv_lw_inc(k1, 4);               \
        uint32_t q2 = xcv_lw_inc(k2, 4), q3 = xcv_lw_inc(k3, 4);               \
        a[0] = xcv_sdotsp_b(a[0], v0, q0);                                     \
        a[1] = xcv_sdotsp_b(a[1], v0, q1);                                     \
        a[2] = xcv_sdotsp_b(a[2], v0, q2);                                     \
        a[3] = xcv_sdotsp_b(a[3], v0, q3);                                     \
        a[4] = xcv_sdotsp_b(a[4], v1, q0);                                     \
        a[5] = xcv_sdotsp_b(a[5], v1, q1);                                     \
        a[6] = xcv_sdotsp_b(a[6], v1, q2);                                     \
        a[7] = xcv_sdotsp_b(a[7], v1, q3);                                     \
    } while (0)

/* Two windows (input offsets i0, i1) by channels c..c+3 into a[0..3]
 * (first pixel) and a[4..7]. Six pointers walk the rows a word at a time
 * (post-increment loads, cv.lw); a channel's weights are contiguous
 * ([ky][kx][ci]), so the weight pointers run on from row to row and only
 * the input pointers jump to the next row. Four words per iteration when
 * the row allows (conv3-head), else two (conv2's 6; an odd count starts
 * with one): the loop's counter and taken branch (3 cycles) spread over
 * more dot products, as the core has no hardware loops here
 * (docs/CLUSTER.md). A word of conv1's 3-byte rows may be misaligned: the
 * CV32E40P loads it in two cycles (docs/CLUSTER.md "Instructions",
 * xcvmem), its fourth byte meets a zero weight. */
static inline __attribute__((always_inline)) void dot_2x4(const conv_tile_t *t, int i0, int i1,
                                                          int c, int32_t a[8])
{
    int rw = t->row_words, wch = t->k * rw, skip = t->in_row - 4 * rw;
    const uint32_t *k0 = t->w + c * wch, *k1 = k0 + wch, *k2 = k1 + wch, *k3 = k2 + wch;
    const uint32_t *x0 = (const uint32_t *)(t->in + i0), *x1 = (const uint32_t *)(t->in + i1);
#pragma clang loop unroll(full)
    for (int j = 0; j < 8; j++)
        a[j] = 0;
    if (rw == 1 && t->k == 3) {
        /* conv1 (3x3 over one channel): three words, no loop. */
#pragma clang loop unroll(full)
        for (int ky = 0; ky < 3; ky++) {
            STEP_2x4();
            x0 = (const uint32_t *)((const int8_t *)x0 + skip);
            x1 = (const uint32_t *)((const int8_t *)x1 + skip);
        }
        return;
    }
    for (int ky = 0; ky < t->k; ky++) {
        if ((rw & 3) == 0) {
            for (int j = rw >> 2; j > 0; j--) {
                STEP_2x4();
                STEP_2x4();
                STEP_2x4();
                STEP_2x4();
            }
        } else {
            if (rw & 1)
                STEP_2x4();
            for (int j = rw >> 1; j > 0; j--) {
                STEP_2x4();
                STEP_2x4();
            }
        }
        x0 = (const uint32_t *)((const int8_t *)x0 + skip);
        x1 = (const uint32_t *)((const int8_t *)x1 + skip);
    }
}

/* Items [first, last) of the tile (item = pair * quads + quad: a core's
 * consecutive items reuse the same two input windows). `out16`, `mode`
 * and `chw` are constants at each call: the int16 or int8 output, the
 * requantization's form (NN_RQ_*), a CHW output (for a depthwise layer)
 * or HWC; inlined, each call is its own loop without those tests. */
static inline __attribute__((always_inline)) void items(const conv_tile_t *t, int first,
                                                        int last, const int out16,
                                                        const int mode, const int chw)
{
    int pixels = t->out_w * t->out_h, quads = t->channels / 4;
    int pair = first / quads, quad = first - pair * quads;
    /* (y, x) of the pair's first pixel, advanced without dividing. */
    int y = 2 * pair / t->out_w, x = 2 * pair - y * t->out_w;
    for (int it = first; it < last; it++) {
        int has1 = 2 * pair + 1 < pixels;
        pixel_t q0 = pixel(t, y, x);
        pixel_t q1 = x + 1 < t->out_w ? pixel(t, y, x + 1) : pixel(t, y + 1, 0);
        if (!has1)
            q1 = q0;
        int c = 4 * quad;
        int32_t a[8];
        dot_2x4(t, q0.in, q1.in, c, a);
        /* Channel c's output offset: c (HWC) or c planes on (CHW). */
        int oc = chw ? c * t->out_cstep : c, cs = chw ? t->out_cstep : 1;
#pragma clang loop unroll(full)
        for (int j = 0; j < 4; j++) {
            const nn_rq_t *r = &t->rq[c + j];
            int32_t v0, v1;
            if (mode == NN_RQ_CLIP) {
                v0 = nn_requant_clip(a[j], r, t->shift);
                v1 = nn_requant_clip(a[4 + j], r, t->shift);
            } else {
                int32_t b = r->add, m = r->mult;
                v0 = mode == NN_RQ_FAST ? nn_requant_fast(a[j] + b, m, t->shift, t->lo, t->hi)
                                        : nn_requant(a[j] + b, m, t->shift, t->lo, t->hi);
                v1 = mode == NN_RQ_FAST ? nn_requant_fast(a[4 + j] + b, m, t->shift, t->lo, t->hi)
                                        : nn_requant(a[4 + j] + b, m, t->shift, t->lo, t->hi);
            }
            if (out16) {
                ((int16_t *)t->out)[q0.out + c + j] = (int16_t)v0;
                if (has1)
                    ((int16_t *)t->out)[q1.out + c + j] = (int16_t)v1;
            } else {
                ((int8_t *)t->out)[q0.out + oc + j * cs] = (int8_t)v0;
                if (has1)
                    ((int8_t *)t->out)[q1.out + oc + j * cs] = (int8_t)v1;
            }
        }
        if (++quad == quads) {
            quad = 0;
            pair++;
            x += 2;
            if (x >= t->out_w) {
                x -= t->out_w;
                y++;
            }
        }
    }
}

/* This core's items of n_items: [n_items*i/n, n_items*(i+1)/n) for core i
 * of the team's n. */
static inline __attribute__((always_inline)) void share(int n_items, int *first, int *last)
{
    int n = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    *first = n_items * i / n;
    *last = n_items * (i + 1) / n;
}

void conv_tile_share(void *arg)
{
    /* A private copy: the stores cannot alias it, so its fields stay in
     * registers. */
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    /* The shared descriptor, not the copy: its address must not escape. */
    nn_zero_share((const conv_tile_t *)arg);
    int first, last;
    share((t->out_w * t->out_h + 1) / 2 * (t->channels / 4), &first, &last);
    if (t->out_int16) {
        if (t->mode == NN_RQ_CLIP)
            items(t, first, last, 1, NN_RQ_CLIP, 0);
        else if (t->mode == NN_RQ_FAST)
            items(t, first, last, 1, NN_RQ_FAST, 0);
        else
            items(t, first, last, 1, NN_RQ_GENERAL, 0);
    } else if (t->mode == NN_RQ_CLIP)
        items(t, first, last, 0, NN_RQ_CLIP, 0);
    else if (t->mode == NN_RQ_FAST)
        items(t, first, last, 0, NN_RQ_FAST, 0);
    else
        items(t, first, last, 0, NN_RQ_GENERAL, 0);
}

/* A separate entry for the CHW output (int8), so that the HWC layers'
 * code is what it was without it (measured: one function for both cost
 * the base network 2 % of its cycles). */
void conv_tile_share_chw(void *arg)
{
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    /* The shared descriptor, not the copy: its address must not escape. */
    nn_zero_share((const conv_tile_t *)arg);
    int first, last;
    share((t->out_w * t->out_h + 1) / 2 * (t->channels / 4), &first, &last);
    if (t->mode == NN_RQ_CLIP)
        items(t, first, last, 0, NN_RQ_CLIP, 1);
    else if (t->mode == NN_RQ_FAST)
        items(t, first, last, 0, NN_RQ_FAST, 1);
    else
        items(t, first, last, 0, NN_RQ_GENERAL, 1);
}

/*
 * Pointwise (1x1, stride 1, no pad; every layer of the depthwise-separable
 * network after a depthwise one, and the heads): the same 2x4 blocking,
 * but a window is one pixel's cin bytes, so the general items' per-item
 * work (the two windows' offsets from (y, x) by multiplication, the
 * row loop, the odd-pixel tests) weighed as much as the dot product on
 * short windows (16 input channels: 4 words). Here a core walks its items
 * pair by pair: the two pixels' pointers advance with the pair, the
 * channel quads' weights and records follow one another, and a pair
 * missing its second pixel (an odd pixel count) computes the first twice
 * and stores it twice, without a test per store. Needs cin % 16 == 0 (the
 * dot loop takes 4 words per iteration).
 */
static inline __attribute__((always_inline)) void pw_items(const conv_tile_t *t, int first,
                                                           int last, const int out16,
                                                           const int chw)
{
    const int quads = t->channels / 4, rw = t->row_words, ow = t->out_w;
    const int pixels = ow * t->out_h, cs = chw ? t->out_cstep : 1;
    int pair = first / quads, quad = first - pair * quads;
    int y = 2 * pair / ow, x = 2 * pair - y * ow;
    for (int left = last - first; left > 0; pair++) {
        int yb = y, xb = x + 1;
        if (xb == ow) {
            xb = 0;
            yb++;
        }
        if (2 * pair + 1 == pixels) {
            xb = x;
            yb = y;
        }
        const int8_t *in0 = t->in + y * t->in_ystep + x * t->in_pix;
        const int8_t *in1 = t->in + yb * t->in_ystep + xb * t->in_pix;
        int o0 = (y * t->out_row + x) * t->out_pix, o1 = (yb * t->out_row + xb) * t->out_pix;
        int n = quads - quad < left ? quads - quad : left;
        left -= n;
        const uint32_t *k = t->w + 4 * quad * rw;
        const nn_rq_t *r = t->rq + 4 * quad;
        int oc = chw ? 4 * quad * t->out_cstep : 4 * quad;
        for (; n > 0; n--) {
            const uint32_t *x0 = (const uint32_t *)in0, *x1 = (const uint32_t *)in1;
            const uint32_t *k0 = k, *k1 = k0 + rw, *k2 = k1 + rw, *k3 = k2 + rw;
            int32_t a[8] = {0, 0, 0, 0, 0, 0, 0, 0};
            for (int j = rw >> 2; j > 0; j--) {
                STEP_2x4();
                STEP_2x4();
                STEP_2x4();
                STEP_2x4();
            }
            k = k3; /* the loads advanced k3 by a channel: the next quad's first */
#pragma clang loop unroll(full)
            for (int j = 0; j < 4; j++) {
                int32_t v0 = nn_requant_clip(a[j], &r[j], t->shift);
                int32_t v1 = nn_requant_clip(a[4 + j], &r[j], t->shift);
                if (out16) {
                    ((int16_t *)t->out)[o0 + oc + j] = (int16_t)v0;
                    ((int16_t *)t->out)[o1 + oc + j] = (int16_t)v1;
                } else {
                    ((int8_t *)t->out)[o0 + oc + j * cs] = (int8_t)v0;
                    ((int8_t *)t->out)[o1 + oc + j * cs] = (int8_t)v1;
                }
            }
            r += 4;
            oc += 4 * cs;
        }
        quad = 0;
        x += 2;
        if (x >= ow) {
            x -= ow;
            y++;
        }
    }
}

void pw_tile_share(void *arg)
{
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    /* The shared descriptor, not the copy: its address must not escape. */
    nn_zero_share((const conv_tile_t *)arg);
    int first, last;
    share((t->out_w * t->out_h + 1) / 2 * (t->channels / 4), &first, &last);
    if (t->out_int16)
        pw_items(t, first, last, 1, 0);
    else if (t->out_cstep != 1)
        pw_items(t, first, last, 0, 1);
    else
        pw_items(t, first, last, 0, 0);
}

/*
 * Depthwise (docs/NN.md "Depthwise-separable"): cv.sdotsp.b sums 4
 * products into one accumulator, so over HWC data, where a word holds 4
 * channels of one tap, it would mix channels. The layer before a depthwise
 * one therefore writes CHW (items' chw), and here a word holds 4 taps of
 * one channel's row: a 3x3 window is 3 loads and 3 cv.sdotsp.b against the
 * channel's 3 weight words (taps 0-2 and a zero byte, which meets the
 * row's fourth byte). The loads are often misaligned (x * stride + kx),
 * which the CV32E40P does in two cycles (docs/CLUSTER.md, xcvmem). An
 * item is one channel's output row: its weights and requantization
 * constants stay in registers along the row, the three row pointers
 * advance by the stride with post-increment loads. The output is HWC for
 * the pointwise layer after.
 */
static inline __attribute__((always_inline)) void dw_items(const conv_tile_t *t, int first,
                                                           int last, const int stride,
                                                           const int mode)
{
    /* Item = c * out_h + y; (c, y) advanced without dividing. */
    int c = first / t->out_h, y = first - c * t->out_h;
    for (int it = first; it < last; it++, y++) {
        if (y == t->out_h) {
            y = 0;
            c++;
        }
        const uint32_t *w = t->w + 3 * c;
        uint32_t w0 = w[0], w1 = w[1], w2 = w[2];
        const nn_rq_t r = t->rq[c];
        const int8_t *r0 = t->in + c * t->in_plane + y * stride * t->in_row;
        const int8_t *r1 = r0 + t->in_row, *r2 = r1 + t->in_row;
        int8_t *o = (int8_t *)t->out + y * t->out_row * t->out_pix + c * t->out_cstep;
        for (int x = t->out_w; x > 0; x--) {
            int32_t a = mode == NN_RQ_CLIP ? 0 : r.add;
            /* cv.lw's increment is an immediate: one loop per stride. */
            if (stride == 2) {
                a = xcv_sdotsp_b(a, xcv_lw_inc(r0, 2), w0);
                a = xcv_sdotsp_b(a, xcv_lw_inc(r1, 2), w1);
                a = xcv_sdotsp_b(a, xcv_lw_inc(r2, 2), w2);
            } else {
                a = xcv_sdotsp_b(a, xcv_lw_inc(r0, 1), w0);
                a = xcv_sdotsp_b(a, xcv_lw_inc(r1, 1), w1);
                a = xcv_sdotsp_b(a, xcv_lw_inc(r2, 1), w2);
            }
            *o = (int8_t)(mode == NN_RQ_CLIP   ? nn_requant_clip(a, &r, t->shift)
                          : mode == NN_RQ_FAST ? nn_requant_fast(a, r.mult, t->shift, t->lo, t->hi)
                                               : nn_requant(a, r.mult, t->shift, t->lo, t->hi));
            o += t->out_pix;
        }
    }
}

/* A layer over one input plane (conv1: in_plane 0, every channel reads
 * the same rows), clip-first: an item is two channels' output row, so
 * each loaded input word feeds both channels' dot products (3 loads for
 * 6 cv.sdotsp.b where dw_items takes 3 for 3). */
static inline __attribute__((always_inline)) void plane_items(const conv_tile_t *t, int first,
                                                              int last, const int stride)
{
    /* Item = (c / 2) * out_h + y. */
    int c = 2 * (first / t->out_h), y = first - c / 2 * t->out_h;
    for (int it = first; it < last; it++, y++) {
        if (y == t->out_h) {
            y = 0;
            c += 2;
        }
        const uint32_t *w = t->w + 3 * c;
        uint32_t w0 = w[0], w1 = w[1], w2 = w[2], w3 = w[3], w4 = w[4], w5 = w[5];
        const nn_rq_t ra = t->rq[c], rb = t->rq[c + 1];
        const int8_t *r0 = t->in + y * stride * t->in_row;
        const int8_t *r1 = r0 + t->in_row, *r2 = r1 + t->in_row;
        int8_t *oa = (int8_t *)t->out + y * t->out_row * t->out_pix + c * t->out_cstep;
        int8_t *ob = oa + t->out_cstep;
        for (int x = t->out_w; x > 0; x--) {
            uint32_t a0, a1, a2;
            if (stride == 2) {
                a0 = xcv_lw_inc(r0, 2);
                a1 = xcv_lw_inc(r1, 2);
                a2 = xcv_lw_inc(r2, 2);
            } else {
                a0 = xcv_lw_inc(r0, 1);
                a1 = xcv_lw_inc(r1, 1);
                a2 = xcv_lw_inc(r2, 1);
            }
            int32_t sa = xcv_sdotsp_b(0, a0, w0), sb = xcv_sdotsp_b(0, a0, w3);
            sa = xcv_sdotsp_b(sa, a1, w1);
            sb = xcv_sdotsp_b(sb, a1, w4);
            sa = xcv_sdotsp_b(sa, a2, w2);
            sb = xcv_sdotsp_b(sb, a2, w5);
            *oa = (int8_t)nn_requant_clip(sa, &ra, t->shift);
            *ob = (int8_t)nn_requant_clip(sb, &rb, t->shift);
            oa += t->out_pix;
            ob += t->out_pix;
        }
    }
}

/* A stride-1 depthwise layer, clip-first: an item is two output rows of
 * one channel, which share two of their three input rows, so 4 loads feed
 * 6 cv.sdotsp.b where dw_items takes 6 for 6. An odd out_h leaves each
 * channel a last item of one row. */
static inline __attribute__((always_inline)) void dw_rows2(const conv_tile_t *t, int first,
                                                           int last)
{
    const int pairs = (t->out_h + 1) / 2;
    /* Item = c * pairs + row pair. */
    int c = first / pairs, yp = first - c * pairs;
    for (int it = first; it < last; it++, yp++) {
        if (yp == pairs) {
            yp = 0;
            c++;
        }
        const uint32_t *w = t->w + 3 * c;
        uint32_t w0 = w[0], w1 = w[1], w2 = w[2];
        const nn_rq_t r = t->rq[c];
        int y = 2 * yp;
        const int8_t *r0 = t->in + c * t->in_plane + y * t->in_row;
        const int8_t *r1 = r0 + t->in_row, *r2 = r1 + t->in_row, *r3 = r2 + t->in_row;
        int8_t *oa = (int8_t *)t->out + y * t->out_row * t->out_pix + c * t->out_cstep;
        if (y + 1 == t->out_h) {
            for (int x = t->out_w; x > 0; x--) {
                int32_t sa = xcv_sdotsp_b(0, xcv_lw_inc(r0, 1), w0);
                sa = xcv_sdotsp_b(sa, xcv_lw_inc(r1, 1), w1);
                sa = xcv_sdotsp_b(sa, xcv_lw_inc(r2, 1), w2);
                *oa = (int8_t)nn_requant_clip(sa, &r, t->shift);
                oa += t->out_pix;
            }
            continue;
        }
        int8_t *ob = oa + t->out_row * t->out_pix;
        for (int x = t->out_w; x > 0; x--) {
            uint32_t a0 = xcv_lw_inc(r0, 1), a1 = xcv_lw_inc(r1, 1);
            uint32_t a2 = xcv_lw_inc(r2, 1), a3 = xcv_lw_inc(r3, 1);
            int32_t sa = xcv_sdotsp_b(0, a0, w0), sb = xcv_sdotsp_b(0, a1, w0);
            sa = xcv_sdotsp_b(sa, a1, w1);
            sb = xcv_sdotsp_b(sb, a2, w1);
            sa = xcv_sdotsp_b(sa, a2, w2);
            sb = xcv_sdotsp_b(sb, a3, w2);
            *oa = (int8_t)nn_requant_clip(sa, &r, t->shift);
            *ob = (int8_t)nn_requant_clip(sb, &r, t->shift);
            oa += t->out_pix;
            ob += t->out_pix;
        }
    }
}

void dw_tile_share(void *arg)
{
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    /* The shared descriptor, not the copy: its address must not escape. */
    nn_zero_share((const conv_tile_t *)arg);
    int first, last;
    if (t->in_plane == 0 && t->mode == NN_RQ_CLIP) {
        /* One plane for every channel (network.c one_plane): channels in
         * pairs (a tile has a multiple of 4). */
        share(t->channels / 2 * t->out_h, &first, &last);
        if (t->stride == 2)
            plane_items(t, first, last, 2);
        else
            plane_items(t, first, last, 1);
        return;
    }
    if (t->stride == 1 && t->mode == NN_RQ_CLIP) {
        share(t->channels * ((t->out_h + 1) / 2), &first, &last);
        dw_rows2(t, first, last);
        return;
    }
    share(t->channels * t->out_h, &first, &last);
    if (t->stride == 2) {
        if (t->mode == NN_RQ_CLIP)
            dw_items(t, first, last, 2, NN_RQ_CLIP);
        else if (t->mode == NN_RQ_FAST)
            dw_items(t, first, last, 2, NN_RQ_FAST);
        else
            dw_items(t, first, last, 2, NN_RQ_GENERAL);
    } else if (t->mode == NN_RQ_FAST) /* stride 1, clip-first: dw_rows2 above */
        dw_items(t, first, last, 1, NN_RQ_FAST);
    else
        dw_items(t, first, last, 1, NN_RQ_GENERAL);
}
