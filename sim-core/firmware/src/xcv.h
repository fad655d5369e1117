/*
 * CORE-V CV32E40P v2 (Xpulp in the CORE-V encodings) from C: the packed-SIMD
 * dot products, MACs and clips that clang-19 does not emit on its own (it
 * has no builtins for them; -O2 emits only the post-increment loads/stores
 * and cv.min/cv.max/cv.minu/cv.maxu). Compile with clang-19 and
 * -march=rv32imc_xcvalu_xcvmac_xcvmem_xcvsimd_xcvbi_xcvbitmanip (the
 * Makefile's xcvprogram rule). Semantics: docs/CLUSTER.md "Instructions".
 */
#ifndef XCV_H
#define XCV_H

#include <stdint.h>

/* acc + a[0]*b[0] + ... + a[3]*b[3], signed bytes (cv.sdotsp.b). */
static inline int32_t xcv_sdotsp_b(int32_t acc, uint32_t a, uint32_t b)
{
    __asm__("cv.sdotsp.b %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));
    return acc;
}
/* acc + a[0]*b[0] + a[1]*b[1], signed halfwords (cv.sdotsp.h). */
static inline int32_t xcv_sdotsp_h(int32_t acc, uint32_t a, uint32_t b)
{
    __asm__("cv.sdotsp.h %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));
    return acc;
}
/* a unsigned bytes times b signed bytes, accumulated (cv.sdotusp.b). */
static inline int32_t xcv_sdotusp_b(int32_t acc, uint32_t a, uint32_t b)
{
    __asm__("cv.sdotusp.b %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));
    return acc;
}
/* Unsigned bytes, accumulated (cv.sdotup.b). */
static inline uint32_t xcv_sdotup_b(uint32_t acc, uint32_t a, uint32_t b)
{
    __asm__("cv.sdotup.b %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));
    return acc;
}
/* acc + a * b (cv.mac). */
static inline int32_t xcv_mac(int32_t acc, int32_t a, int32_t b)
{
    __asm__("cv.mac %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));
    return acc;
}
/* x clipped to the signed range of `bits` bits, [-2^(bits-1), 2^(bits-1)-1]
 * (cv.clip; bits is an immediate, 1..31). */
#define xcv_clip(x, bits)                                              \
    ({                                                                 \
        int32_t xcv_r_;                                                \
        __asm__("cv.clip %0, %1, %2" : "=r"(xcv_r_) : "r"((int32_t)(x)), "i"(bits)); \
        xcv_r_;                                                        \
    })
/* Load a word and advance the pointer by `inc` bytes (cv.lw post-increment). */
#define xcv_lw_inc(p, inc)                                             \
    ({                                                                 \
        uint32_t xcv_v_;                                               \
        __asm__ volatile("cv.lw %0, (%1), %2" : "=r"(xcv_v_), "+r"(p) : "i"(inc) : "memory"); \
        xcv_v_;                                                        \
    })

#endif
