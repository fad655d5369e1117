/* Fixed-point helpers: see fixmath.h. */
#include "fixmath.h"

/* round(16384 * sin(k * pi / 128)) for k = 0..64 (a quarter wave), computed
 * with: python3 -c "import math; print([round(16384*math.sin(k*math.pi/128))
 * for k in range(65)])". */
static const uint16_t sin_quarter[65] = {
    0,     402,   804,   1205,  1606,  2006,  2404,  2801,  3196,  3590,  3981,  4370,  4756,
    5139,  5520,  5897,  6270,  6639,  7005,  7366,  7723,  8076,  8423,  8765,  9102,  9434,
    9760,  10080, 10394, 10702, 11003, 11297, 11585, 11866, 12140, 12406, 12665, 12916, 13160,
    13395, 13623, 13842, 14053, 14256, 14449, 14635, 14811, 14978, 15137, 15286, 15426, 15557,
    15679, 15791, 15893, 15986, 16069, 16143, 16207, 16261, 16305, 16340, 16364, 16379, 16384,
};

/* sin on [0, quarter]: a in 0..16384, 256 angle units per table step. */
static int32_t sin_first_quarter(uint32_t a)
{
    uint32_t k = a >> 8, f = a & 255;
    if (k >= 64)
        return sin_quarter[64];
    int32_t lo = sin_quarter[k], hi = sin_quarter[k + 1];
    return lo + (((hi - lo) * (int32_t)f + 128) >> 8);
}

int32_t fx_sin(uint16_t a)
{
    uint32_t q = a >> 14, r = a & 0x3fff;
    switch (q) {
    case 0:
        return sin_first_quarter(r);
    case 1:
        return sin_first_quarter(FX_BAM_QUARTER - r);
    case 2:
        return -sin_first_quarter(r);
    default:
        return -sin_first_quarter(FX_BAM_QUARTER - r);
    }
}

int32_t fx_cos(uint16_t a) { return fx_sin((uint16_t)(a + FX_BAM_QUARTER)); }

/* 65536 / (2 pi 1000) = 10.430378 BAM per mrad, as 683565 / 2^16. */
uint16_t fx_mrad_to_bam(int32_t mrad)
{
    int64_t v = (int64_t)mrad * 683565;
    return (uint16_t)((v + (1 << 15)) >> 16);
}

/* 2 pi 1000 / 65536 = 0.095873799 mrad per BAM, as 6283185 / 2^16 / 1000. */
int32_t fx_bam_to_mrad(uint16_t a)
{
    int32_t s = (int16_t)a; /* (-pi, pi) as signed */
    int64_t v = (int64_t)s * 6283185;
    return (int32_t)(v >= 0 ? (v + 32768000) / 65536000 : -((-v + 32768000) / 65536000));
}

uint16_t fx_cdeg_to_bam(uint32_t cdeg)
{
    return (uint16_t)(((uint64_t)cdeg * 65536 + 18000) / 36000);
}

uint32_t fx_isqrt(uint32_t v)
{
    uint32_t r = 0, bit = 1u << 30;
    while (bit > v)
        bit >>= 2;
    while (bit) {
        if (v >= r + bit) {
            v -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r;
}

int32_t fx_mrad_diff(int32_t a, int32_t b)
{
    /* 2 pi in mrad, rounded; the wrap error (0.18 mrad per turn) does not
     * matter for the scan's accumulated turn. */
    const int32_t two_pi = 6283;
    int32_t d = (a - b) % two_pi;
    if (d > two_pi / 2)
        d -= two_pi;
    else if (d <= -two_pi / 2)
        d += two_pi;
    return d;
}
