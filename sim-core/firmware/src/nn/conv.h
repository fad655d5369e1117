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
     * out + (y*out_row + x)*out_pix + c*out_cstep (elements, int8 or
     * int16): HWC with out_cstep 1, or, for a depthwise layer to read, CHW
     * (out_pix 1, out_cstep the padded plane). */
    int out_w, out_h;
    void *out;
    int out_row, out_pix, out_cstep;
    int out_int16;
    /* Depthwise tiles only (dw_tile_share): the input is CHW, channel c's
     * padded plane at in + c*in_plane, rows in_row bytes apart; `stride`
     * 1 or 2 (in_pix and in_ystep are unused). */
    int in_plane, stride;
} conv_tile_t;

/* The team's share of the tile (a pi_cl_team_fork entry): core i of n
 * computes items [items*i/n, items*(i+1)/n). */
void conv_tile_share(void *tile);
/* The same for a tile whose output is CHW (out_cstep != 1, int8). */
void conv_tile_share_chw(void *tile);

/* The same for a depthwise tile (conv.c "Depthwise"): each of its
 * channels convolves its own input plane; weights one word per kernel row
 * ([c][ky] words of 3 taps and a zero byte), k = 3. */
void dw_tile_share(void *tile);

/* The requantization of docs/NN.md step 2, exactly as training/int8_ref.py:
 * clip((acc * mult + 2^(shift-1)) >> shift, lo, hi), the product in 64 bits,
 * >> arithmetic. On RV32 in 32-bit halves: the 64-bit product from mul and
 * mulh, the shifted value's two words; when the high word is not the low
 * word's sign extension the value lies beyond int32, hence beyond [lo, hi]
 * (both int16), and its sign picks the bound. shift in [1, 31] (network.c
 * checks the descriptors). */
static inline int32_t nn_requant(int32_t acc, int32_t mult, int shift, int32_t lo, int32_t hi)
{
    int64_t p = (int64_t)acc * mult + (uint32_t)(1u << (shift - 1));
    int32_t ph = (int32_t)(p >> 32);
    uint32_t pl = (uint32_t)p;
    int32_t rh = ph >> shift;
    int32_t rl = (int32_t)((pl >> shift) | ((uint32_t)ph << (32 - shift)));
    if (rh != (rl >> 31))
        return ph < 0 ? lo : hi;
    return rl < lo ? lo : rl > hi ? hi : rl;
}

/* The same when shift >= 15: |acc * mult + round| < 2^31 * 2^15 (mult <=
 * 32767, docs/NN.md), so the shifted value fits int32 and the clip is a
 * cv.max and a cv.min, no branch. */
static inline int32_t nn_requant_fast(int32_t acc, int32_t mult, int shift, int32_t lo,
                                      int32_t hi)
{
    int64_t p = (int64_t)acc * mult + (uint32_t)(1u << (shift - 1));
    int32_t r = (int32_t)(((uint32_t)p >> shift) | ((uint32_t)(p >> 32) << (32 - shift)));
    r = r < lo ? lo : r;
    return r > hi ? hi : r;
}

#endif
