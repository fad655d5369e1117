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

/* `static inline T name(T acc, A a, B b)`: acc updated by one instruction
 * that reads and writes its destination. */
#define XCV_ACC_OP(name, insn, T, A, B)                              \
    static inline T name(T acc, A a, B b)                            \
    {                                                                \
        __asm__(insn " %0, %1, %2" : "+r"(acc) : "r"(a), "r"(b));  \
        return acc;                                                  \
    }
/* acc + a[0]*b[0] + ... + a[3]*b[3], signed bytes. */
XCV_ACC_OP(xcv_sdotsp_b, "cv.sdotsp.b", int32_t, uint32_t, uint32_t)
/* acc + a[0]*b[0] + a[1]*b[1], signed halfwords. */
XCV_ACC_OP(xcv_sdotsp_h, "cv.sdotsp.h", int32_t, uint32_t, uint32_t)
/* a unsigned bytes times b signed bytes, accumulated. */
XCV_ACC_OP(xcv_sdotusp_b, "cv.sdotusp.b", int32_t, uint32_t, uint32_t)
/* Unsigned bytes, accumulated. */
XCV_ACC_OP(xcv_sdotup_b, "cv.sdotup.b", uint32_t, uint32_t, uint32_t)
/* acc + a * b. */
XCV_ACC_OP(xcv_mac, "cv.mac", int32_t, int32_t, int32_t)

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
