/*
 * The int8 convolution kernel (docs/NN.md "On the cluster"). Work item: two
 * output pixels (consecutive in raster order) by four output channels: per
 * word of the window, 2 input loads and 4 weight loads feed 8 cv.sdotsp.b
 * (32 MACs), the register-blocking of PULP-NN's kernels (Garofalo et al.
 * 2020, §4: "4x2" output blocks) on HWC data, where one row of a 3x3
 * window is 3*cin contiguous bytes in the input and in the weights.
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
 * consecutive items reuse the same two input windows). `out16` and `fast`
 * are constants at each call: the int16 or int8 output, nn_requant_fast
 * or nn_requant; inlined, each call is its own loop without those tests. */
static inline __attribute__((always_inline)) void items(const conv_tile_t *t, int first,
                                                        int last, const int out16,
                                                        const int fast)
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
#pragma clang loop unroll(full)
        for (int j = 0; j < 4; j++) {
            int32_t b = t->bias[c + j], m = t->mult[c + j];
            int32_t v0 = fast ? nn_requant_fast(a[j] + b, m, t->shift, t->lo, t->hi)
                              : nn_requant(a[j] + b, m, t->shift, t->lo, t->hi);
            int32_t v1 = fast ? nn_requant_fast(a[4 + j] + b, m, t->shift, t->lo, t->hi)
                              : nn_requant(a[4 + j] + b, m, t->shift, t->lo, t->hi);
            if (out16) {
                ((int16_t *)t->out)[q0.out + c + j] = (int16_t)v0;
                if (has1)
                    ((int16_t *)t->out)[q1.out + c + j] = (int16_t)v1;
            } else {
                ((int8_t *)t->out)[q0.out + c + j] = (int8_t)v0;
                if (has1)
                    ((int8_t *)t->out)[q1.out + c + j] = (int8_t)v1;
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

void conv_tile_share(void *arg)
{
    /* A private copy: the stores cannot alias it, so its fields stay in
     * registers. */
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    int pairs = (t->out_w * t->out_h + 1) / 2;
    int n_items = pairs * (t->channels / 4);
    int n = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    int first = n_items * i / n, last = n_items * (i + 1) / n;
    /* shift >= 15: no int32 overflow in the requantization (conv.h). */
    int fast = t->shift >= 15;
    if (t->out_int16 && fast)
        items(t, first, last, 1, 1);
    else if (t->out_int16)
        items(t, first, last, 1, 0);
    else if (fast)
        items(t, first, last, 0, 1);
    else
        items(t, first, last, 0, 0);
}
