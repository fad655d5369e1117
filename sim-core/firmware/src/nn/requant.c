/*
 * The requantization's clip-first records (conv.h nn_rq_t, docs/NN_KERNELS.md
 * "Int8 arithmetic"): made once per channel from weights.h at the
 * network's setup (network.c), outside the kernels' loops, so their 64-bit
 * divisions cost nothing per output. Apart from conv.c so that
 * nn_selftest.elf links it without the cluster runtime.
 */
#include "conv.h"

/* floor(n / d), d > 0 (C's / truncates). */
static int64_t floor_div(int64_t n, int64_t d)
{
    int64_t q = n / d;
    return (n % d != 0 && n < 0) ? q - 1 : q;
}

/* docs/NN.md step 2 before the clip, in 64 bits. */
static int64_t scaled(int64_t acc, int32_t mult, int shift)
{
    return (acc * mult + ((int64_t)1 << (shift - 1))) >> shift;
}

int nn_rq_make(int32_t bias, int32_t mult, int shift, int32_t lo, int32_t hi, nn_rq_t *r)
{
    *r = (nn_rq_t){0, 0, mult, bias};
    if (mult <= 0 || lo >= hi || shift < 1 || shift > 31)
        return 0;
    int64_t round = (int64_t)1 << (shift - 1), unit = (int64_t)1 << shift;
    /* A_hi: the smallest acc with acc*mult + round >= hi*2^shift; A_lo: the
     * largest with acc*mult + round < (lo + 1)*2^shift. */
    int64_t a_hi = -floor_div(round - (int64_t)hi * unit, mult);
    int64_t a_lo = floor_div(((int64_t)lo + 1) * unit - round - 1, mult);
    if (scaled(a_lo, mult, shift) != lo || scaled(a_hi, mult, shift) != hi)
        return 0;
    if (a_lo * mult + round < INT32_MIN || a_hi * mult + round > INT32_MAX)
        return 0;
    if (a_lo - bias < INT32_MIN || a_hi - bias > INT32_MAX)
        return 0;
    r->lo = (int32_t)(a_lo - bias);
    r->hi = (int32_t)(a_hi - bias);
    r->add = (int32_t)(uint32_t)((uint64_t)bias * (uint64_t)mult + (uint64_t)round);
    return 1;
}
