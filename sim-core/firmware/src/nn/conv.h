/*
 * One int8 convolution tile on the cluster (docs/NN.md "Int8 arithmetic",
 * "On the cluster"): a group of output channels of one layer, every output
 * pixel, all operands in L1. The team shares (pixel pair, channel quad)
 * items; each is 8 accumulators fed by cv.sdotsp.b (4 MACs per instruction).
 */
#ifndef NN_CONV_H
#define NN_CONV_H

#include <stdint.h>

typedef struct {
    /* Input: HWC, zero-padded by one pixel on every side (padded row
     * `in_row` bytes); the window of output (y, x) starts at padded
     * (y*stride + off, x*stride + off) with off = 1 - pad. */
    const int8_t *in;
    int in_row;   /* bytes per padded input row */
    int in_pix;   /* bytes between the windows of two neighbouring outputs (stride * cin) */
    int in_ystep; /* bytes between the windows of two output rows (stride * in_row) */
    int k;        /* kernel rows; each row of the window is `row_words` words */
    int row_words;
    /* Weights of this tile's channels, [c][ky][row_words words]; bias and
     * multipliers of the same channels. */
    const uint32_t *w;
    const int32_t *bias, *mult;
    int shift;
    int32_t lo, hi;
    int channels; /* in this tile, a multiple of 4 */
    /* Output: `out_w` x `out_h` pixels; the tile's channel c goes to
     * out + (y*out_row + x)*out_pix + c (elements, int8 or int16). */
    int out_w, out_h;
    void *out;
    int out_row, out_pix;
    int out_int16;
} conv_tile_t;

/* The team's share of the tile (a pi_cl_team_fork entry): core i of n
 * computes items [items*i/n, items*(i+1)/n). */
void conv_tile_share(void *tile);

/* The requantization of docs/NN.md step 2, exactly as training/int8_ref.py:
 * clip((acc * mult + 2^(shift-1)) >> shift, lo, hi), the product in 64 bits,
 * >> arithmetic. */
static inline int32_t nn_requant(int32_t acc, int32_t mult, int shift, int32_t lo, int32_t hi)
{
    int64_t p = ((int64_t)acc * mult + ((int64_t)1 << (shift - 1))) >> shift;
    if (p < lo)
        return lo;
    if (p > hi)
        return hi;
    return (int32_t)p;
}

#endif
