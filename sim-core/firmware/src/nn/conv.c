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

/* The 8 results of an item: channels c..c+3 of pixels at out offsets o0, o1
 * (o1 < 0: none, an odd count's last item), T the output's element type. */
#define STORE_8(T, REQUANT, t, o0, o1, c, a)                                       \
    do {                                                                             \
        T *out_ = (T *)(t)->out;                                                     \
        for (int j = 0; j < 4; j++) {                                                \
            int32_t b = (t)->bias[(c) + j], m = (t)->mult[(c) + j];                  \
            out_[(o0) + (c) + j] = (T)REQUANT((a)[j] + b, m, (t)->shift, (t)->lo, (t)->hi); \
            if ((o1) >= 0)                                                           \
                out_[(o1) + (c) + j] =                                               \
                    (T)REQUANT((a)[4 + j] + b, m, (t)->shift, (t)->lo, (t)->hi);     \
        }                                                                            \
    } while (0)

/* Two windows (input offsets i0, i1) by channels c..c+3. Window rows are
 * `in_row` apart in the input and `row_words` words apart in the weights;
 * six pointers walk a row a word at a time (post-increment loads). A word
 * of conv1's 3-byte rows may be misaligned: the CV32E40P loads it in two
 * cycles (docs/CLUSTER.md "Instructions", xcvmem), its fourth byte meets a
 * zero weight. */
static inline void dot_2x4(const conv_tile_t *t, int i0, int i1, int c, int32_t a[8])
{
    int rw = t->row_words, wch = t->k * rw;
    const uint32_t *w0 = t->w + c * wch;
    int32_t a00 = 0, a01 = 0, a02 = 0, a03 = 0, a10 = 0, a11 = 0, a12 = 0, a13 = 0;
    if (rw == 1 && t->k == 3) {
        /* conv1 (3x3 over one channel): the three rows unrolled, no loop. */
#pragma clang loop unroll(full)
        for (int ky = 0; ky < 3; ky++) {
            uint32_t v0 = *(const uint32_t *)(t->in + i0 + ky * t->in_row);
            uint32_t v1 = *(const uint32_t *)(t->in + i1 + ky * t->in_row);
            uint32_t q0 = w0[ky], q1 = w0[3 + ky], q2 = w0[6 + ky], q3 = w0[9 + ky];
            a00 = xcv_sdotsp_b(a00, v0, q0);
            a01 = xcv_sdotsp_b(a01, v0, q1);
            a02 = xcv_sdotsp_b(a02, v0, q2);
            a03 = xcv_sdotsp_b(a03, v0, q3);
            a10 = xcv_sdotsp_b(a10, v1, q0);
            a11 = xcv_sdotsp_b(a11, v1, q1);
            a12 = xcv_sdotsp_b(a12, v1, q2);
            a13 = xcv_sdotsp_b(a13, v1, q3);
        }
        a[0] = a00, a[1] = a01, a[2] = a02, a[3] = a03;
        a[4] = a10, a[5] = a11, a[6] = a12, a[7] = a13;
        return;
    }
    for (int ky = 0; ky < t->k; ky++) {
        const uint32_t *x0 = (const uint32_t *)(t->in + i0 + ky * t->in_row);
        const uint32_t *x1 = (const uint32_t *)(t->in + i1 + ky * t->in_row);
        const uint32_t *k0 = w0 + ky * rw, *k1 = k0 + wch, *k2 = k1 + wch, *k3 = k2 + wch;
        for (int j = rw; j > 0; j--) {
            uint32_t v0 = *x0++, v1 = *x1++;
            uint32_t q0 = *k0++, q1 = *k1++, q2 = *k2++, q3 = *k3++;
            a00 = xcv_sdotsp_b(a00, v0, q0);
            a01 = xcv_sdotsp_b(a01, v0, q1);
            a02 = xcv_sdotsp_b(a02, v0, q2);
            a03 = xcv_sdotsp_b(a03, v0, q3);
            a10 = xcv_sdotsp_b(a10, v1, q0);
            a11 = xcv_sdotsp_b(a11, v1, q1);
            a12 = xcv_sdotsp_b(a12, v1, q2);
            a13 = xcv_sdotsp_b(a13, v1, q3);
        }
    }
    a[0] = a00, a[1] = a01, a[2] = a02, a[3] = a03;
    a[4] = a10, a[5] = a11, a[6] = a12, a[7] = a13;
}

void conv_tile_share(void *arg)
{
    /* A private copy: the stores below cannot alias it, so its fields stay
     * in registers. */
    const conv_tile_t tile = *(const conv_tile_t *)arg, *t = &tile;
    int pixels = t->out_w * t->out_h;
    int pairs = (pixels + 1) / 2, quads = t->channels / 4;
    int items = pairs * quads;
    int n = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    int first = items * i / n, last = items * (i + 1) / n;
    /* Item = pair * quads + quad: a core's consecutive items reuse the
     * same two input windows. */
    int pair = first / quads, quad = first - pair * quads;
    /* (y, x) of the pair's first pixel, advanced without dividing. */
    int y = 2 * pair / t->out_w, x = 2 * pair - y * t->out_w;
    for (int it = first; it < last; it++) {
        int32_t a[8];
        int has1 = 2 * pair + 1 < pixels;
        pixel_t q0 = pixel(t, y, x);
        pixel_t q1 = x + 1 < t->out_w ? pixel(t, y, x + 1) : pixel(t, y + 1, 0);
        if (!has1)
            q1 = q0;
        dot_2x4(t, q0.in, q1.in, 4 * quad, a);
        int o1 = has1 ? q1.out : -1;
        if (t->shift < 15 && t->out_int16)
            STORE_8(int16_t, nn_requant, t, q0.out, o1, 4 * quad, a);
        else if (t->shift < 15)
            STORE_8(int8_t, nn_requant, t, q0.out, o1, 4 * quad, a);
        else if (t->out_int16)
            STORE_8(int16_t, nn_requant_fast, t, q0.out, o1, 4 * quad, a);
        else
            STORE_8(int8_t, nn_requant_fast, t, q0.out, o1, 4 * quad, a);
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
