/*
 * pulp_builtins.h: the GCC PULP builtins (__builtin_pulp_*) and vector types
 * (v2s, v2u, v4s, v4u) that GAP8 code written for the GAP SDK's GCC uses
 * (PULP-NN, DORY's generated layers, the SDK's gap8 builtins header),
 * mapped onto CORE-V XCV for clang-19. Included by pmsis.h, as the SDK's
 * pmsis.h makes them visible.
 *
 * clang-19 has no builtins for XCV; each one here is the XCV instruction
 * the PULP builtin stands for, in inline assembly (docs/CLUSTER.md
 * "Instructions"), or plain C where clang emits the XCV instruction itself
 * (cv.min/cv.max). Semantics are GCC's PULP builtins': argument order (the
 * accumulator last in mac/msu/sdot*), lane-width wrap-around in add/sub/avg,
 * fl1/ff1 of 0 = 32, clb of 0 = 0, clip_r(x, b) in [-(b+1), b],
 * clipu_r(x, b) in [0, b], bextract(x, size, off) the `size`-bit field at
 * bit `off` (size and off constants, as GCC requires), bset/bclr taking the
 * mask (bset(x, m) = x | m, bclr(x, m) = x & m, m a contiguous run of ones,
 * resp. zeros, as the SDK's gap8_bitset/gap8_bitclr pass it), the *_r forms
 * the field ((size - 1) << 5) | off in a register.
 * The self-test src/cluster/pulp_builtins_test.c checks every name against
 * plain C on the ISS.
 */
#ifndef PULP_BUILTINS_H
#define PULP_BUILTINS_H

#include <stdint.h>

typedef signed short v2s __attribute__((vector_size(4)));
typedef unsigned short v2u __attribute__((vector_size(4)));
typedef signed char v4s __attribute__((vector_size(4)));
typedef unsigned char v4u __attribute__((vector_size(4)));

#define PULP_INLINE static inline __attribute__((always_inline))

/* A vector's bits as a word and back (lane 0 in the low bits). */
#define PULP_BITS(v) __builtin_bit_cast(uint32_t, (v))

/* One instruction, two register operands. */
#define PULP_RR(name, insn, R, A, B)                                             \
    PULP_INLINE R name(A a, B b)                                                 \
    {                                                                            \
        uint32_t r_;                                                             \
        __asm__(insn " %0, %1, %2" : "=r"(r_) : "r"(PULP_BITS(a)), "r"(PULP_BITS(b))); \
        return __builtin_bit_cast(R, r_);                                        \
    }
/* One instruction, one register operand. */
#define PULP_R(name, insn, R, A)                                                 \
    PULP_INLINE R name(A a)                                                      \
    {                                                                            \
        uint32_t r_;                                                             \
        __asm__(insn " %0, %1" : "=r"(r_) : "r"(PULP_BITS(a)));                  \
        return __builtin_bit_cast(R, r_);                                        \
    }
/* acc updated by an instruction that reads and writes its destination;
 * GCC's argument order: the operands first, the accumulator last. */
#define PULP_ACC(name, insn, R, A, B)                                            \
    PULP_INLINE R name(A a, B b, R acc)                                          \
    {                                                                            \
        uint32_t r_ = __builtin_bit_cast(uint32_t, acc);                         \
        __asm__(insn " %0, %1, %2" : "+r"(r_) : "r"(PULP_BITS(a)), "r"(PULP_BITS(b))); \
        return __builtin_bit_cast(R, r_);                                        \
    }

/* ---- Scalar ALU ---------------------------------------------------------- */

PULP_R(pulp_abs_, "cv.abs", int, int)
#define __builtin_pulp_abs(x) pulp_abs_(x)
/* clang-19 emits cv.min/cv.max/cv.minu/cv.maxu for these on its own. */
PULP_INLINE int pulp_minsi_(int a, int b) { return a < b ? a : b; }
PULP_INLINE int pulp_maxsi_(int a, int b) { return a > b ? a : b; }
#define __builtin_pulp_minsi(a, b) pulp_minsi_(a, b)
#define __builtin_pulp_maxsi(a, b) pulp_maxsi_(a, b)
/* clip(x, lo, hi): x clamped to [lo, hi] (the SDK passes lo = -2^p,
 * hi = 2^p - 1, one cv.clip); clipu(x, 0, hi) likewise. */
PULP_INLINE int pulp_clip_(int x, int lo, int hi) { return x < lo ? lo : (x > hi ? hi : x); }
#define __builtin_pulp_clip(x, lo, hi) pulp_clip_(x, lo, hi)
#define __builtin_pulp_clipu(x, lo, hi) pulp_clip_(x, lo, hi)
/* cv.clipr: [-(b+1), b]; cv.clipur: [0, b]. */
PULP_RR(pulp_clip_r_, "cv.clipr", int, int, int)
PULP_RR(pulp_clipu_r_, "cv.clipur", int, int, int)
#define __builtin_pulp_clip_r(x, b) pulp_clip_r_(x, b)
#define __builtin_pulp_clipu_r(x, b) pulp_clipu_r_(x, b)

/* ---- Multiply-accumulate ------------------------------------------------- */

PULP_ACC(pulp_mac_, "cv.mac", int, int, int)
PULP_ACC(pulp_msu_, "cv.msu", int, int, int)
/* acc + x * y, acc - x * y (GCC: __builtin_pulp_mac(x, y, acc)). */
#define __builtin_pulp_mac(x, y, acc) pulp_mac_(x, y, acc)
#define __builtin_pulp_msu(x, y, acc) pulp_msu_(x, y, acc)

/* ---- Bit manipulation ---------------------------------------------------- */

/* Index of the most / least significant set bit; 32 when x = 0. */
PULP_R(pulp_fl1_, "cv.fl1", int, uint32_t)
PULP_R(pulp_ff1_, "cv.ff1", int, uint32_t)
/* Set bits; leading bits equal to the sign bit minus one (0 when x = 0). */
PULP_R(pulp_cnt_, "cv.cnt", int, uint32_t)
PULP_R(pulp_clb_, "cv.clb", int, int)
#define __builtin_pulp_fl1(x) pulp_fl1_((uint32_t)(x))
#define __builtin_pulp_ff1(x) pulp_ff1_((uint32_t)(x))
#define __builtin_pulp_cnt(x) pulp_cnt_((uint32_t)(x))
#define __builtin_pulp_clb(x) pulp_clb_((int)(x))

/* The `size`-bit field at bit `off`, sign- / zero-extended (constants). */
#define __builtin_pulp_bextract(x, size, off)                                  \
    ({                                                                         \
        int pulp_r_;                                                           \
        __asm__("cv.extract %0, %1, %2, %3"                                    \
                : "=r"(pulp_r_)                                                \
                : "r"((int)(x)), "i"((size) - 1), "i"(off));                   \
        pulp_r_;                                                               \
    })
#define __builtin_pulp_bextractu(x, size, off)                                 \
    ({                                                                         \
        unsigned int pulp_r_;                                                  \
        __asm__("cv.extractu %0, %1, %2, %3"                                   \
                : "=r"(pulp_r_)                                                \
                : "r"((unsigned int)(x)), "i"((size) - 1), "i"(off));          \
        pulp_r_;                                                               \
    })
/* The same with the field ((size - 1) << 5) | off in a register. */
PULP_RR(pulp_bextract_r_, "cv.extractr", int, int, uint32_t)
PULP_RR(pulp_bextractu_r_, "cv.extractur", unsigned int, uint32_t, uint32_t)
#define __builtin_pulp_bextract_r(x, field) pulp_bextract_r_((int)(x), field)
#define __builtin_pulp_bextractu_r(x, field) pulp_bextractu_r_((uint32_t)(x), field)

/* A constant mask's run of ones as cv.bset's immediates: its length - 1
 * and its first bit. */
#define PULP_RUN_LEN1(m) (__builtin_popcount((unsigned int)(m)) - 1)
#define PULP_RUN_OFF(m) __builtin_ctz((unsigned int)(m))
/* x | mask, mask a contiguous run of ones. */
#define __builtin_pulp_bset(x, mask)                                           \
    ({                                                                         \
        unsigned int pulp_r_;                                                  \
        __asm__("cv.bset %0, %1, %2, %3"                                       \
                : "=r"(pulp_r_)                                                \
                : "r"((unsigned int)(x)), "i"(PULP_RUN_LEN1(mask)),            \
                  "i"(PULP_RUN_OFF(mask)));                                    \
        (int)pulp_r_;                                                          \
    })
/* x & notmask, notmask a contiguous run of zeros. */
#define __builtin_pulp_bclr(x, notmask)                                        \
    ({                                                                         \
        unsigned int pulp_r_;                                                  \
        __asm__("cv.bclr %0, %1, %2, %3"                                       \
                : "=r"(pulp_r_)                                                \
                : "r"((unsigned int)(x)), "i"(PULP_RUN_LEN1(~(unsigned int)(notmask))), \
                  "i"(PULP_RUN_OFF(~(unsigned int)(notmask))));                \
        (int)pulp_r_;                                                          \
    })
PULP_RR(pulp_bset_r_, "cv.bsetr", int, uint32_t, uint32_t)
PULP_RR(pulp_bclr_r_, "cv.bclrr", int, uint32_t, uint32_t)
#define __builtin_pulp_bset_r(x, field) pulp_bset_r_((uint32_t)(x), field)
#define __builtin_pulp_bclr_r(x, field) pulp_bclr_r_((uint32_t)(x), field)
/* (dst & not_mask) | ((src << off) & mask), mask a contiguous run of ones
 * starting at bit off (the SDK's gap8_bitinsert). */
#define __builtin_pulp_binsert(dst, not_mask, src, mask, off)                  \
    ({                                                                         \
        unsigned int pulp_r_ = (unsigned int)(dst);                            \
        (void)(not_mask);                                                      \
        __asm__("cv.insert %0, %1, %2, %3"                                     \
                : "+r"(pulp_r_)                                                \
                : "r"((unsigned int)(src)), "i"(PULP_RUN_LEN1(mask)), "i"(off)); \
        (int)pulp_r_;                                                          \
    })
PULP_INLINE int pulp_binsert_r_(uint32_t dst, uint32_t src, uint32_t field)
{
    __asm__("cv.insertr %0, %1, %2" : "+r"(dst) : "r"(src), "r"(field));
    return (int)dst;
}
#define __builtin_pulp_binsert_r(dst, src, field)                              \
    pulp_binsert_r_((uint32_t)(dst), (uint32_t)(src), field)

/* ---- Packed SIMD: 4 bytes, 2 halfwords ------------------------------------ */

/* {x, y, z, t}: x in byte 0 (cv.packlo.b, cv.packhi.b). */
PULP_INLINE v4s pulp_pack4_(int x, int y, int z, int t)
{
    uint32_t r = 0;
    __asm__("cv.packlo.b %0, %1, %2" : "+r"(r) : "r"(y), "r"(x));
    __asm__("cv.packhi.b %0, %1, %2" : "+r"(r) : "r"(t), "r"(z));
    return __builtin_bit_cast(v4s, r);
}
#define __builtin_pulp_pack4(x, y, z, t) pulp_pack4_((int)(x), (int)(y), (int)(z), (int)(t))
/* {x, y}: x in halfword 0 (cv.pack: rs1 to the high half). */
PULP_INLINE v2s pulp_pack2_(int x, int y)
{
    uint32_t r;
    __asm__("cv.pack %0, %1, %2" : "=r"(r) : "r"(y), "r"(x));
    return __builtin_bit_cast(v2s, r);
}
#define __builtin_pulp_pack2(x, y) pulp_pack2_((int)(x), (int)(y))

PULP_RR(pulp_add4_, "cv.add.b", v4s, v4s, v4s)
PULP_RR(pulp_sub4_, "cv.sub.b", v4s, v4s, v4s)
PULP_RR(pulp_avg4_, "cv.avg.b", v4s, v4s, v4s)
PULP_RR(pulp_avgu4_, "cv.avgu.b", v4u, v4u, v4u)
PULP_RR(pulp_max4_, "cv.max.b", v4s, v4s, v4s)
PULP_RR(pulp_maxu4_, "cv.maxu.b", v4u, v4u, v4u)
PULP_RR(pulp_min4_, "cv.min.b", v4s, v4s, v4s)
PULP_RR(pulp_minu4_, "cv.minu.b", v4u, v4u, v4u)
PULP_R(pulp_abs4_, "cv.abs.b", v4s, v4s)
PULP_RR(pulp_shuffleb_, "cv.shuffle.b", v4s, v4s, v4s)
#define __builtin_pulp_add4(x, y) pulp_add4_(x, y)
#define __builtin_pulp_sub4(x, y) pulp_sub4_(x, y)
#define __builtin_pulp_avg4(x, y) pulp_avg4_(x, y)
#define __builtin_pulp_avgu4(x, y) pulp_avgu4_(x, y)
#define __builtin_pulp_max4(x, y) pulp_max4_(x, y)
#define __builtin_pulp_maxu4(x, y) pulp_maxu4_(x, y)
#define __builtin_pulp_min4(x, y) pulp_min4_(x, y)
#define __builtin_pulp_minu4(x, y) pulp_minu4_(x, y)
#define __builtin_pulp_abs4(x) pulp_abs4_(x)
/* Lane i of the result = lane (mask[i] & 3) of x. */
#define __builtin_pulp_shuffleb(x, mask) pulp_shuffleb_(x, mask)

PULP_RR(pulp_add2_, "cv.add.h", v2s, v2s, v2s)
PULP_RR(pulp_sub2_, "cv.sub.h", v2s, v2s, v2s)
PULP_RR(pulp_avg2_, "cv.avg.h", v2s, v2s, v2s)
PULP_RR(pulp_avgu2_, "cv.avgu.h", v2u, v2u, v2u)
PULP_RR(pulp_max2_, "cv.max.h", v2s, v2s, v2s)
PULP_RR(pulp_maxu2_, "cv.maxu.h", v2u, v2u, v2u)
PULP_RR(pulp_min2_, "cv.min.h", v2s, v2s, v2s)
PULP_RR(pulp_minu2_, "cv.minu.h", v2u, v2u, v2u)
PULP_R(pulp_abs2_, "cv.abs.h", v2s, v2s)
PULP_RR(pulp_shuffleh_, "cv.shuffle.h", v2s, v2s, v2s)
#define __builtin_pulp_add2(x, y) pulp_add2_(x, y)
#define __builtin_pulp_sub2(x, y) pulp_sub2_(x, y)
#define __builtin_pulp_avg2(x, y) pulp_avg2_(x, y)
#define __builtin_pulp_avgu2(x, y) pulp_avgu2_(x, y)
#define __builtin_pulp_max2(x, y) pulp_max2_(x, y)
#define __builtin_pulp_maxu2(x, y) pulp_maxu2_(x, y)
#define __builtin_pulp_min2(x, y) pulp_min2_(x, y)
#define __builtin_pulp_minu2(x, y) pulp_minu2_(x, y)
#define __builtin_pulp_abs2(x) pulp_abs2_(x)
#define __builtin_pulp_shuffleh(x, mask) pulp_shuffleh_(x, mask)

/* ---- Dot products ---------------------------------------------------------
 * dot*: the sum of the lanes' products; sdot*: added to the accumulator
 * (last argument). sp: both signed; up: both unsigned; usp: x unsigned,
 * y signed. */
PULP_RR(pulp_dotsp4_, "cv.dotsp.b", int, v4s, v4s)
PULP_RR(pulp_dotup4_, "cv.dotup.b", unsigned int, v4u, v4u)
PULP_RR(pulp_dotusp4_, "cv.dotusp.b", int, v4u, v4s)
PULP_ACC(pulp_sdotsp4_, "cv.sdotsp.b", int, v4s, v4s)
PULP_ACC(pulp_sdotup4_, "cv.sdotup.b", unsigned int, v4u, v4u)
PULP_ACC(pulp_sdotusp4_, "cv.sdotusp.b", int, v4u, v4s)
#define __builtin_pulp_dotsp4(x, y) pulp_dotsp4_(x, y)
#define __builtin_pulp_dotup4(x, y) pulp_dotup4_(x, y)
#define __builtin_pulp_dotusp4(x, y) pulp_dotusp4_(x, y)
#define __builtin_pulp_sdotsp4(x, y, acc) pulp_sdotsp4_(x, y, acc)
#define __builtin_pulp_sdotup4(x, y, acc) pulp_sdotup4_(x, y, acc)
#define __builtin_pulp_sdotusp4(x, y, acc) pulp_sdotusp4_(x, y, acc)

PULP_RR(pulp_dotsp2_, "cv.dotsp.h", int, v2s, v2s)
PULP_RR(pulp_dotup2_, "cv.dotup.h", unsigned int, v2u, v2u)
PULP_RR(pulp_dotusp2_, "cv.dotusp.h", int, v2u, v2s)
PULP_ACC(pulp_sdotsp2_, "cv.sdotsp.h", int, v2s, v2s)
PULP_ACC(pulp_sdotup2_, "cv.sdotup.h", unsigned int, v2u, v2u)
PULP_ACC(pulp_sdotusp2_, "cv.sdotusp.h", int, v2u, v2s)
#define __builtin_pulp_dotsp2(x, y) pulp_dotsp2_(x, y)
#define __builtin_pulp_dotup2(x, y) pulp_dotup2_(x, y)
#define __builtin_pulp_dotusp2(x, y) pulp_dotusp2_(x, y)
#define __builtin_pulp_sdotsp2(x, y, acc) pulp_sdotsp2_(x, y, acc)
#define __builtin_pulp_sdotup2(x, y, acc) pulp_sdotup2_(x, y, acc)
#define __builtin_pulp_sdotusp2(x, y, acc) pulp_sdotusp2_(x, y, acc)

#endif
