/*
 * Self-test of the kernels' integer arithmetic on the ISS (docs/NN_KERNELS.md
 * "Int8 arithmetic"), run by tests/tests/e2e/nn_eval.rs: the requantizations
 * of conv.h (the general one, used when a layer's shift is below 15, which
 * no layer of today's weights has, the fast one, and the clip-first one
 * with its records from nn_rq_make) against the plain 64-bit formula, on
 * edge and pseudo-random operands; the rounding's
 * hand-computed cases; the decoding's first-maximum rule; the FC's block
 * means against a byte-by-byte sum.
 */
#include <stdio.h>
#include <string.h>

#include "../selfcheck.h"
#include "conv.h"
#include "decode.h"
#include "frame.h"

/* docs/NN.md step 2 written plainly: 64-bit product, arithmetic shift, clip. */
static int32_t reference(int32_t acc, int32_t mult, int shift, int32_t lo, int32_t hi)
{
    int64_t p = ((int64_t)acc * mult + ((int64_t)1 << (shift - 1))) >> shift;
    return p < lo ? lo : p > hi ? hi : (int32_t)p;
}

static uint32_t lcg = 0x2545f491u;
static uint32_t next(void) { return lcg = lcg * 1664525u + 1013904223u; }

static void requantization(void)
{
    static const int32_t accs[] = {0, 1, -1, 2, -2, 3, -3, 127, -128, 65535, -65536,
                                   1 << 30, -(1 << 30), 2147483647, -2147483647};
    static const int shifts[] = {1, 2, 7, 14, 15, 16, 21, 22, 31};
    static const int32_t ranges[][2] = {{0, 127}, {-32768, 32767}};
    char name[64];
    for (unsigned r = 0; r < 2; r++)
        for (unsigned s = 0; s < sizeof shifts / sizeof shifts[0]; s++)
            for (int k = 0; k < 40; k++) {
                int32_t acc = k < (int)(sizeof accs / sizeof accs[0]) ? accs[k] : (int32_t)next();
                int32_t mult = k % 3 == 0 ? 32767 : k % 3 == 1 ? 1 : (int32_t)(next() % 32767) + 1;
                int sh = shifts[s];
                int32_t lo = ranges[r][0], hi = ranges[r][1];
                int32_t want = reference(acc, mult, sh, lo, hi);
                snprintf(name, sizeof name, "requant acc %ld mult %ld shift %d", (long)acc,
                         (long)mult, sh);
                check(name, (uint32_t)nn_requant((int32_t)opaque((uint32_t)acc), mult, sh, lo, hi),
                      (uint32_t)want);
                if (sh >= 15)
                    check(name, (uint32_t)nn_requant_fast((int32_t)opaque((uint32_t)acc), mult,
                                                          sh, lo, hi),
                          (uint32_t)want);
            }
    /* Half up, as docs/NN.md: 1.5 -> 2, -1.5 -> -1, 2.5 -> 3. */
    check("round 1.5", (uint32_t)nn_requant(3, 1, 1, -100, 100), 2);
    check("round -1.5", (uint32_t)nn_requant(-3, 1, 1, -100, 100), (uint32_t)-1);
    check("round 2.5", (uint32_t)nn_requant_fast(5 << 14, 1, 15, -100, 100), 3);
}

/* The clip-first form (conv.h nn_requant_clip): wherever nn_rq_make says
 * it is exact, it equals the 64-bit formula on the dot products at and
 * around its bounds, at the int32 extremes and at random; where it says
 * not, the record holds the bias and the multiplier. */
static void clip_first(void)
{
    static const int shifts[] = {1, 7, 14, 15, 16, 21, 22, 24, 31};
    static const int32_t ranges[][2] = {{0, 127}, {-128, 127}, {-32768, 32767}};
    char name[96];
    for (unsigned g = 0; g < 3; g++)
        for (unsigned s = 0; s < sizeof shifts / sizeof shifts[0]; s++)
            for (int k = 0; k < 24; k++) {
                int sh = shifts[s];
                int32_t lo = ranges[g][0], hi = ranges[g][1];
                int32_t mult = k == 0 ? 1 : k == 1 ? 32767 : (int32_t)(next() % 32767) + 1;
                int32_t bias = k == 2 ? 0 : (int32_t)(next() % (1u << 22)) - (1 << 21);
                nn_rq_t r;
                int ok = nn_rq_make(bias, mult, sh, lo, hi, &r);
                /* Exact for certain when mult <= 2^shift (steps of at most
                 * 1) and hi * 2^shift < 2^31 (no overflow): the int8
                 * layers' shifts 15-24, the head's 15-16. */
                if (sh >= 15 && sh <= (hi > 127 ? 16 : 24)) {
                    snprintf(name, sizeof name, "record made: mult %ld shift %d range %ld",
                             (long)mult, sh, (long)hi);
                    check(name, (uint32_t)ok, 1);
                }
                if (!ok) {
                    snprintf(name, sizeof name, "fallback record bias %ld mult %ld", (long)bias,
                             (long)mult);
                    check(name, (uint32_t)r.add, (uint32_t)bias);
                    check(name, (uint32_t)r.mult, (uint32_t)mult);
                    continue;
                }
                int32_t dots[24] = {0, 1, -1, INT32_MIN / 2, INT32_MAX / 2};
                for (int d = -3; d <= 3; d++) {
                    dots[5 + (d + 3)] = r.lo + d;
                    dots[12 + (d + 3)] = r.hi + d;
                }
                for (int d = 19; d < 24; d++)
                    dots[d] = (int32_t)next() >> (next() % 24);
                for (int d = 0; d < 24; d++) {
                    int64_t acc = (int64_t)dots[d] + bias;
                    int64_t p = (acc * mult + ((int64_t)1 << (sh - 1))) >> sh;
                    int32_t want = p < lo ? lo : p > hi ? hi : (int32_t)p;
                    snprintf(name, sizeof name, "clip-first dot %ld bias %ld mult %ld shift %d",
                             (long)dots[d], (long)bias, (long)mult, sh);
                    check(name, (uint32_t)nn_requant_clip((int32_t)opaque((uint32_t)dots[d]), &r, sh),
                          (uint32_t)want);
                }
            }
    nn_rq_t r;
    check("conv1's first channel takes the clip-first form", nn_rq_make(7263, 5638, 21, 0, 127, &r),
          1);
    check("zero multiplier falls back", nn_rq_make(5, 0, 21, 0, 127, &r), 0);
    check("overflowing shift falls back", nn_rq_make(5, 32767, 31, 0, 127, &r), 0);
}

#ifdef NN_DECODE_THRESHOLD
/* The nearest rule (weights.h): candidates above the threshold and within
 * the distance limit; the nearest wins, the first on a tie. */
static void decoding(void)
{
    static int16_t head[NN_GRID * NN_GRID * NN_HEAD_CHANNELS];
    const int16_t t = NN_DECODE_THRESHOLD;
    nn_output_t o;
    memset(head, 0, sizeof head);
    /* At the threshold is not above it: none of these (distance 0) counts. */
    for (int i = 0; i < NN_GRID * NN_GRID; i++)
        head[i * NN_HEAD_CHANNELS] = t;
    head[7 * NN_HEAD_CHANNELS] = t + 200; /* the most certain, farther */
    head[7 * NN_HEAD_CHANNELS + 3] = 4321;
    head[18 * NN_HEAD_CHANNELS] = t + 1; /* nearer: wins */
    head[18 * NN_HEAD_CHANNELS + 3] = 3000;
    head[18 * NN_HEAD_CHANNELS + 1] = -16;
    head[20 * NN_HEAD_CHANNELS] = t + 1; /* as near, later in raster order */
    head[20 * NN_HEAD_CHANNELS + 3] = 3000;
    if (NN_DECODE_MAX_DISTANCE_MM < 32767) {
        head[3 * NN_HEAD_CHANNELS] = t + 300; /* beyond the distance limit */
        head[3 * NN_HEAD_CHANNELS + 3] = NN_DECODE_MAX_DISTANCE_MM + 1;
    }
    nn_decode(head, &o);
    check("decode visible", (uint32_t)o.visible, 1);
    check("decode nearest cell x", (uint32_t)o.cell_x, 18 % NN_GRID);
    check("decode nearest cell y", (uint32_t)o.cell_y, 18 / NN_GRID);
    check("decode u", (uint32_t)o.u_q4, 16 * (NN_CELL_PX * (18 % NN_GRID) + NN_CELL_PX / 2) - 16);
    check("decode distance", (uint32_t)o.distance_mm, 3000);
    head[7 * NN_HEAD_CHANNELS] = t;
    head[18 * NN_HEAD_CHANNELS] = t;
    head[20 * NN_HEAD_CHANNELS] = t;
    head[3 * NN_HEAD_CHANNELS] = t;
    head[9 * NN_HEAD_CHANNELS] = t; /* ties: the first maximum, cell 0 */
    nn_decode(head, &o);
    check("decode not visible at the threshold", (uint32_t)o.visible, 0);
    check("decode best cell without a candidate", (uint32_t)(o.cell_x + o.cell_y), 0);
}
#else
static void decoding(void)
{
    static int16_t head[NN_GRID * NN_GRID * NN_HEAD_CHANNELS];
    nn_output_t o;
    memset(head, 0, sizeof head);
    for (int i = 0; i < NN_GRID * NN_GRID; i++)
        head[i * NN_HEAD_CHANNELS] = -50;
    /* Two equal maxima: the first in raster order wins (cell 7 before 18). */
    head[7 * NN_HEAD_CHANNELS] = 9;
    head[18 * NN_HEAD_CHANNELS] = 9;
    head[7 * NN_HEAD_CHANNELS + 1] = -16;
    head[7 * NN_HEAD_CHANNELS + 3] = 4321;
    nn_decode(head, &o);
    check("decode visible", (uint32_t)o.visible, 1);
    check("decode cell x", (uint32_t)o.cell_x, 7 % NN_GRID);
    check("decode cell y", (uint32_t)o.cell_y, 7 / NN_GRID);
    check("decode u", (uint32_t)o.u_q4, 16 * (NN_CELL_PX * (7 % NN_GRID) + NN_CELL_PX / 2) - 16);
    check("decode distance", (uint32_t)o.distance_mm, 4321);
    head[7 * NN_HEAD_CHANNELS] = 0;
    head[18 * NN_HEAD_CHANNELS] = 0;
    nn_decode(head, &o);
    check("decode not visible at 0", (uint32_t)o.visible, 0);
}
#endif

static uint8_t frame[NN_CAMERA * NN_CAMERA] __attribute__((aligned(4)));
static int8_t input[NN_INPUT_PADDED_BYTES] __attribute__((aligned(4)));

static void block_means(void)
{
    for (int i = 0; i < NN_CAMERA * NN_CAMERA; i++)
        frame[i] = (uint8_t)(next() >> 24);
    frame[0] = 255; /* a block of 255s: (16·255 + 8) >> 4 = 255 -> 127 */
    for (int y = 0; y < NN_POOL; y++)
        for (int x = 0; x < NN_POOL; x++)
            frame[y * NN_CAMERA + x] = 255;
    memset(input, 0x55, sizeof input);
    nn_downsample(frame, input);
    uint32_t bad = 0;
    for (int by = -1; by <= NN_INPUT; by++)
        for (int bx = -1; bx <= NN_INPUT; bx++) {
            int32_t want = 0;
            if (by >= 0 && bx >= 0 && by < NN_INPUT && bx < NN_INPUT) {
                uint32_t sum = 8;
                for (int y = 0; y < NN_POOL; y++)
                    for (int x = 0; x < NN_POOL; x++)
                        sum += frame[(by * NN_POOL + y) * NN_CAMERA + bx * NN_POOL + x];
                want = (int32_t)(sum >> 4) - 128;
            }
            bad += input[(by + 1) * (NN_INPUT + 2) + bx + 1] != want;
        }
    check("block means and zero border", bad, 0);
    check("block of 255", (uint32_t)input[NN_INPUT + 3], 127);
}

int main(void)
{
    requantization();
    clip_first();
    decoding();
    block_means();
    return summary("nn_selftest");
}
