/*
 * One int8 convolution tile on the cluster (docs/NN_KERNELS.md "Int8 arithmetic",
 * "On the cluster"): a group of output channels of one layer, every output
 * pixel, all operands in L1. The team shares (pixel pair, channel quad)
 * items; each is 8 accumulators fed by cv.sdotsp.b (4 MACs per instruction).
 */
#ifndef NN_CONV_H
#define NN_CONV_H

#include <stdint.h>

/* One output channel's requantization constants (network.c fills them per
 * layer at setup, the DMA brings a tile's with its weights). `mode`
 * (conv_tile_t) says which form they are for:
 * NN_RQ_CLIP: lo, hi bound the dot product (bias excluded) and add =
 *   bias * mult + 2^(shift-1) (mod 2^32): out = (clip(dot, lo, hi) * mult
 *   + add) >> shift (nn_requant_clip);
 * NN_RQ_FAST, NN_RQ_GENERAL: add = bias, lo and hi unused (nn_requant_fast,
 *   nn_requant). */
typedef struct {
    int32_t lo, hi, mult, add;
} nn_rq_t;

enum { NN_RQ_GENERAL = 0, NN_RQ_FAST = 1, NN_RQ_CLIP = 2 };

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
    /* Weights of this tile's channels, [c][ky][row_words words]; the same
     * channels' requantization constants, in the form `mode` (NN_RQ_*). */
    const uint32_t *w;
    const nn_rq_t *rq;
    int mode;
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
    /* The output border the team zeroes at the tile's start
     * (nn_zero_share; none when zero_h is 0): the whole border of the HWC
     * activation at zero_at (zero_h x zero_w interior, zero_c channels),
     * or, zero_chw, the borders of the zero_c CHW planes from zero_at. */
    int8_t *zero_at;
    int zero_h, zero_w, zero_c, zero_chw;
} conv_tile_t;

/* This core's share of the tile's border zeroing (border.c); every
 * *_tile_share below starts with it. */
void nn_zero_share(const conv_tile_t *t);

/* The team's share of the tile (a pi_cl_team_fork entry): core i of n
 * computes items [items*i/n, items*(i+1)/n). */
void conv_tile_share(void *tile);
/* The same for a tile whose output is CHW (out_cstep != 1, int8). */
void conv_tile_share_chw(void *tile);

/* The same for a pointwise tile (conv.c "Pointwise": k = 1, stride 1, no
 * pad, cin % 16 == 0, the clip-first requantization; HWC, CHW or int16
 * out). */
void pw_tile_share(void *tile);

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

/* The clip-first form of the same (docs/NN_KERNELS.md "Int8 arithmetic", "The
 * requantization, clip first"): with f(acc) = (acc * mult + 2^(shift-1))
 * >> shift non-decreasing (mult > 0), clip(f(acc), lo, hi) =
 * f(clip(acc, A_lo, A_hi)) whenever f(A_lo) = lo and f(A_hi) = hi, and
 * over [A_lo, A_hi] the product fits int32: a min, a max, a mul, an add and
 * a shift, where nn_requant_fast takes a mulh (5 cycles) and a carry. The
 * bias is folded into the record (nn_rq_make): lo, hi bound the dot
 * product, add = bias * mult + 2^(shift-1), the sum taken mod 2^32 (the
 * true value lies in int32, so the wrapped one is it). */
static inline int32_t nn_requant_clip(int32_t dot, const nn_rq_t *r, int shift)
{
    int32_t a = dot < r->lo ? r->lo : dot;
    a = a > r->hi ? r->hi : a;
    return (int32_t)((uint32_t)a * (uint32_t)r->mult + (uint32_t)r->add) >> shift;
}

/* Fills *r for a channel (bias, mult) of a layer (shift, out range [lo,
 * hi]) in the clip-first form and returns 1 when that form is exact for
 * every int32 dot product (the conditions above, checked in 64 bits);
 * else fills the fast/general form (add = bias) and returns 0. */
int nn_rq_make(int32_t bias, int32_t mult, int shift, int32_t lo, int32_t hi, nn_rq_t *r);

#endif
