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

/* Start of output pixel p's window. */
static inline const int8_t *window(const conv_tile_t *t, int p)
{
    int y = p / t->out_w, x = p - y * t->out_w;
    return t->in + y * t->in_ystep + x * t->in_pix;
}

static inline void store(const conv_tile_t *t, int p, int c, int32_t acc)
{
    int y = p / t->out_w, x = p - y * t->out_w;
    int i = (y * t->out_row + x) * t->out_pix + c;
    int32_t v = nn_requant(acc + t->bias[c], t->mult[c], t->shift, t->lo, t->hi);
    if (t->out_int16)
        ((int16_t *)t->out)[i] = (int16_t)v;
    else
        ((int8_t *)t->out)[i] = (int8_t)v;
}

/* Pixels p0 and p1 (p1 may equal p0: an odd count's last item) by
 * channels c..c+3. Window rows are `in_row` apart in the input and
 * `row_words` words apart in the weights. A word of conv1's 3-byte rows
 * may be misaligned: the CV32E40P loads it in two cycles (docs/CLUSTER.md
 * "Instructions", xcvmem), its fourth byte meets a zero weight. */
static void item(const conv_tile_t *t, int p0, int p1, int c)
{
    const int8_t *in0 = window(t, p0), *in1 = window(t, p1);
    int rw = t->row_words, wch = t->k * rw;
    const uint32_t *w0 = t->w + c * wch;
    int32_t a00 = 0, a01 = 0, a02 = 0, a03 = 0, a10 = 0, a11 = 0, a12 = 0, a13 = 0;
    for (int ky = 0; ky < t->k; ky++) {
        const uint32_t *x0 = (const uint32_t *)(in0 + ky * t->in_row);
        const uint32_t *x1 = (const uint32_t *)(in1 + ky * t->in_row);
        const uint32_t *w = w0 + ky * rw;
        for (int j = 0; j < rw; j++) {
            uint32_t v0 = x0[j], v1 = x1[j];
            uint32_t k0 = w[j], k1 = w[j + wch], k2 = w[j + 2 * wch], k3 = w[j + 3 * wch];
            a00 = xcv_sdotsp_b(a00, v0, k0);
            a01 = xcv_sdotsp_b(a01, v0, k1);
            a02 = xcv_sdotsp_b(a02, v0, k2);
            a03 = xcv_sdotsp_b(a03, v0, k3);
            a10 = xcv_sdotsp_b(a10, v1, k0);
            a11 = xcv_sdotsp_b(a11, v1, k1);
            a12 = xcv_sdotsp_b(a12, v1, k2);
            a13 = xcv_sdotsp_b(a13, v1, k3);
        }
    }
    store(t, p0, c, a00);
    store(t, p0, c + 1, a01);
    store(t, p0, c + 2, a02);
    store(t, p0, c + 3, a03);
    if (p1 != p0) {
        store(t, p1, c, a10);
        store(t, p1, c + 1, a11);
        store(t, p1, c + 2, a12);
        store(t, p1, c + 3, a13);
    }
}

void conv_tile_share(void *arg)
{
    const conv_tile_t *t = arg;
    int pixels = t->out_w * t->out_h;
    int pairs = (pixels + 1) / 2, quads = t->channels / 4;
    int items = pairs * quads;
    int n = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    int first = items * i / n, last = items * (i + 1) / n;
    /* Item = pair * quads + quad: a core's consecutive items reuse the
     * same two input windows. */
    for (int it = first; it < last; it++) {
        int pair = it / quads, quad = it - pair * quads;
        int p0 = 2 * pair, p1 = p0 + 1 < pixels ? p0 + 1 : p0;
        item(t, p0, p1, 4 * quad);
    }
}
