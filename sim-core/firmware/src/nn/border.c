/*
 * The zero borders of the activations (docs/NN_KERNELS.md "On the cluster"): a
 * layer's output carries a one-pixel zero border, the next layer's
 * padding, which the kernels never write. The buffers are reused by
 * layers of other shapes, so every layer zeroes its output's border; the
 * team does it at the start of each tile's fork (nn_zero_share), each core
 * its share, beside the kernels that write only the interior: on core 0
 * alone, while the other seven waited, it took 120,000 of the depthwise-
 * separable network's 663,000 cycles (measured on the ISS).
 */
#include <pmsis.h>

#include "conv.h"

/* n zero bytes: words while 4 remain from an aligned address (every row
 * and side of an HWC border with a multiple of 4 channels), bytes
 * otherwise. Not memset: picolibc's, called per border piece, cost about
 * 6 cycles a byte here; no_builtin keeps clang from turning these loops
 * back into memset calls. */
__attribute__((no_builtin("memset"))) static void zero(int8_t *p, int n)
{
    for (; n > 0 && ((uintptr_t)p & 3); n--)
        *p++ = 0;
    uint32_t *w = (uint32_t *)p;
    for (; n >= 4; n -= 4)
        *w++ = 0;
    for (p = (int8_t *)w; n > 0; n--)
        *p++ = 0;
}

/* Core i of n's share of an HWC activation's border (h x w interior, c
 * channels): the i-th of n word-aligned pieces of the top and of the
 * bottom row, and the two sides of its share of the interior rows, so
 * that every core zeroes about as many bytes (a split by rows gave the
 * top and bottom rows' cores 3-7 times the others' work). */
static void zero_hwc_share(int8_t *a, int h, int w, int c, int i, int n)
{
    int row = (w + 2) * c;
    int p0 = (row / 4 * i / n) * 4, p1 = i + 1 == n ? row : (row / 4 * (i + 1) / n) * 4;
    zero(a + p0, p1 - p0);
    zero(a + (h + 1) * row + p0, p1 - p0);
    for (int y = 1 + h * i / n; y < 1 + h * (i + 1) / n; y++) {
        zero(a + y * row, c);
        zero(a + y * row + (w + 1) * c, c);
    }
}

/* The borders of CHW planes [first, last) (h x w interiors): a plane's
 * bottom row and the next one's top row are one run, so are a row's last
 * byte and the next row's first. no_builtin as for zero, which is inlined
 * here. */
__attribute__((no_builtin("memset"))) static void zero_planes(int8_t *a, int h, int w, int first,
                                                             int last)
{
    if (first >= last)
        return;
    int row = w + 2, plane = (h + 2) * row;
    a += first * plane;
    zero(a, row);
    for (int ch = first; ch < last; ch++, a += plane) {
        for (int y = 1; y <= h; y++) {
            a[y * row] = 0;
            a[y * row + w + 1] = 0;
        }
        zero(a + (h + 1) * row, ch + 1 < last ? 2 * row : row);
    }
}

void nn_zero_share(const conv_tile_t *t)
{
    if (t->zero_h == 0)
        return;
    int n = pi_cl_team_nb_cores(), i = (int)pi_core_id();
    if (t->zero_chw) {
        zero_planes(t->zero_at, t->zero_h, t->zero_w, t->zero_c * i / n,
                    t->zero_c * (i + 1) / n);
    } else {
        zero_hwc_share(t->zero_at, t->zero_h, t->zero_w, t->zero_c, i, n);
    }
}
