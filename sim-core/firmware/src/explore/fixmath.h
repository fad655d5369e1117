/*
 * Fixed-point helpers for the exploration firmware. The core is RV32IMC
 * without F (DESIGN.md §4): soft-float costs tens of cycles per operation, so
 * the per-cell work of the mapping and the planner is integer only.
 *
 * Angles are binary angles ("BAM"): a uint16_t where 65536 is one turn, so
 * wrap-around is free. Sines and cosines are Q14 (16384 = 1.0).
 */
#ifndef EXPLORE_FIXMATH_H
#define EXPLORE_FIXMATH_H

#include <stdint.h>

#define FX_Q14 16384
#define FX_BAM_TURN 65536L
#define FX_BAM_QUARTER 16384u

/* sin and cos of a binary angle, Q14; error below 1.5e-4 (table of 65
 * quarter-wave samples, linear interpolation). */
int32_t fx_sin(uint16_t a);
int32_t fx_cos(uint16_t a);

/* Milliradians (any value, wraps) to a binary angle, rounded. */
uint16_t fx_mrad_to_bam(int32_t mrad);
/* Binary angle to milliradians in (-pi, pi]. */
int32_t fx_bam_to_mrad(uint16_t a);
/* Centidegrees to a binary angle, rounded. */
uint16_t fx_cdeg_to_bam(uint32_t cdeg);

/* Floor of the square root. */
uint32_t fx_isqrt(uint32_t v);

/* Smallest angle difference a - b in milliradians, in (-pi, pi]. */
int32_t fx_mrad_diff(int32_t a, int32_t b);

static inline int32_t fx_abs(int32_t v) { return v < 0 ? -v : v; }
static inline int32_t fx_min(int32_t a, int32_t b) { return a < b ? a : b; }
static inline int32_t fx_max(int32_t a, int32_t b) { return a > b ? a : b; }
static inline int32_t fx_clamp(int32_t v, int32_t lo, int32_t hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}
/* Division rounding to nearest, halves away from zero (d > 0). */
static inline int32_t fx_div_round(int32_t n, int32_t d)
{
    return n >= 0 ? (n + d / 2) / d : -((-n + d / 2) / d);
}

#endif
