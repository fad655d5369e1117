/*
 * Self-test of the GCC PULP builtins (src/pmsis/pulp_builtins.h) on the
 * cluster: every builtin the header defines, on edge-case operands (0, ±1,
 * the 8/16/32-bit limits, mixed lanes), against plain C written from the
 * builtins' documented semantics. The checks run on cluster core 0, the
 * summary on the FC; exit status = failures
 * (sim-core/tests/pulp_builtins.rs).
 */
#include <pmsis.h>
#include <stdio.h>

#include "../selfcheck.h"

static const uint32_t OPS[] = {
    0x00000000, 0x00000001, 0xffffffff, 0x0000007f, 0x00000080, 0x000000ff,
    0x00000100, 0x00007fff, 0x00008000, 0x0000ffff, 0x7fffffff, 0x80000000,
    0x80808080, 0x7f7f7f7f, 0xff00ff00, 0x01ff80fe, 0x12345678, 0xdeadbeef,
    0x80007fff, 0xfffe0001, 0x00030201,
};
#define NOPS (sizeof OPS / sizeof OPS[0])
/* Bounds for the register clips (non-negative, as the builtins take them). */
static const int32_t BOUNDS[] = {0, 1, 127, 255, 0x7fff, 0x7fffffff};

/* ---- plain C references -------------------------------------------------- */

static int32_t sb(uint32_t w, int i) { return (int8_t)(w >> (8 * i)); }
static uint32_t ub(uint32_t w, int i) { return (w >> (8 * i)) & 0xff; }
static int32_t sh(uint32_t w, int i) { return (int16_t)(w >> (16 * i)); }
static uint32_t uh(uint32_t w, int i) { return (w >> (16 * i)) & 0xffff; }

enum lane_op { ADD, SUB, AVG, AVGU, MAX, MAXU, MIN, MINU, ABS, SHUF };

/* One lane of a packed operation: lanes of `bits` bits, results wrapped to
 * the lane (the adders are lane-wide, avg shifts the wrapped sum). */
static uint32_t lane(enum lane_op op, uint32_t a, uint32_t b, int bits, int i)
{
    uint32_t mask = bits == 8 ? 0xff : 0xffff;
    int32_t sa = bits == 8 ? sb(a, i) : sh(a, i), sbv = bits == 8 ? sb(b, i) : sh(b, i);
    uint32_t ua = bits == 8 ? ub(a, i) : uh(a, i), ubv = bits == 8 ? ub(b, i) : uh(b, i);
    int32_t wrapped;
    switch (op) {
    case ADD:
        return (ua + ubv) & mask;
    case SUB:
        return (ua - ubv) & mask;
    case AVG:
        wrapped = (int32_t)((ua + ubv) << (32 - bits)) >> (32 - bits);
        return (uint32_t)(wrapped >> 1) & mask;
    case AVGU:
        return ((ua + ubv) & mask) >> 1;
    case MAX:
        return (uint32_t)(sa > sbv ? sa : sbv) & mask;
    case MAXU:
        return ua > ubv ? ua : ubv;
    case MIN:
        return (uint32_t)(sa < sbv ? sa : sbv) & mask;
    case MINU:
        return ua < ubv ? ua : ubv;
    case ABS:
        return (uint32_t)(sa < 0 ? -sa : sa) & mask;
    case SHUF: {
        int from = (int)(ubv & (bits == 8 ? 3 : 1));
        return bits == 8 ? ub(a, from) : uh(a, from);
    }
    }
    return 0;
}

static uint32_t packed(enum lane_op op, uint32_t a, uint32_t b, int bits)
{
    uint32_t r = 0;
    for (int i = 0; i < 32 / bits; i++)
        r |= lane(op, a, b, bits, i) << (bits * i);
    return r;
}

/* sign: bit 0 = a's lanes signed, bit 1 = b's lanes signed. */
static uint32_t dot(uint32_t a, uint32_t b, int bits, int sign)
{
    uint32_t sum = 0;
    for (int i = 0; i < 32 / bits; i++) {
        int32_t x = (sign & 1) ? (bits == 8 ? sb(a, i) : sh(a, i))
                               : (int32_t)(bits == 8 ? ub(a, i) : uh(a, i));
        int32_t y = (sign & 2) ? (bits == 8 ? sb(b, i) : sh(b, i))
                               : (int32_t)(bits == 8 ? ub(b, i) : uh(b, i));
        sum += (uint32_t)x * (uint32_t)y;
    }
    return sum;
}

static int32_t clamp(int32_t x, int32_t lo, int32_t hi) { return x < lo ? lo : (x > hi ? hi : x); }
/* A loop, not __builtin_clz: clang-19 with xcvbitmanip compiles
 * __builtin_clz to cv.fl1, which is 31 - clz (docs/CLUSTER.md). */
static uint32_t fl1_ref(uint32_t x)
{
    uint32_t i = 32;
    for (int b = 31; b >= 0 && i == 32; b--)
        if ((x >> b) & 1)
            i = (uint32_t)b;
    return i;
}
static uint32_t ff1_ref(uint32_t x) { return x ? (uint32_t)__builtin_ctz(x) : 32u; }
static uint32_t cnt_ref(uint32_t x)
{
    uint32_t n = 0;
    for (; x; x >>= 1)
        n += x & 1;
    return n;
}
static uint32_t clb_ref(uint32_t x)
{
    if (x == 0)
        return 0;
    uint32_t sign = x >> 31, n = 0;
    for (int i = 30; i >= 0 && ((x >> i) & 1) == sign; i--)
        n++;
    return n;
}
/* The field of `size` bits at `off`, its top bit clamped to bit 31. */
static uint32_t field_ref(uint32_t x, int size, int off, int sign)
{
    int top = off + size - 1 > 31 ? 31 : off + size - 1;
    int len = top - off + 1;
    uint32_t f = (x >> off) & (len == 32 ? 0xffffffffu : ((1u << len) - 1));
    if (sign && len < 32 && ((f >> (len - 1)) & 1))
        f |= ~0u << len;
    return f;
}
/* A run of `size` ones from bit `off` (a constant for the immediate forms). */
#define run_mask(size, off) (((size) == 32 ? 0xffffffffu : ((1u << (size)) - 1)) << (off))

#define W(v) __builtin_bit_cast(uint32_t, (v))
#define V4S(w) __builtin_bit_cast(v4s, (uint32_t)(w))
#define V4U(w) __builtin_bit_cast(v4u, (uint32_t)(w))
#define V2S(w) __builtin_bit_cast(v2s, (uint32_t)(w))
#define V2U(w) __builtin_bit_cast(v2u, (uint32_t)(w))

/* ---- the checks ---------------------------------------------------------- */

static char name[64];
#define CHECK(got, want, ...)                                                  \
    do {                                                                       \
        snprintf(name, sizeof name, __VA_ARGS__);                              \
        check(name, (uint32_t)(got), (uint32_t)(want));                        \
    } while (0)

static void unary(uint32_t a)
{
    int32_t s = (int32_t)a;
    CHECK(__builtin_pulp_abs(s), s < 0 ? 0u - a : a, "abs %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_fl1(a), fl1_ref(a), "fl1 %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_ff1(a), ff1_ref(a), "ff1 %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_cnt(a), cnt_ref(a), "cnt %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_clb(s), clb_ref(a), "clb %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_clip(s, -128, 127), clamp(s, -128, 127), "clip8 %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_clip(s, -(1 << 15), (1 << 15) - 1), clamp(s, -32768, 32767),
          "clip16 %08lx", (unsigned long)a);
    CHECK(__builtin_pulp_clipu(s, 0, 255), clamp(s, 0, 255), "clipu %08lx", (unsigned long)a);
    for (unsigned k = 0; k < sizeof BOUNDS / sizeof BOUNDS[0]; k++) {
        int32_t b = (int32_t)opaque((uint32_t)BOUNDS[k]);
        CHECK(__builtin_pulp_clip_r(s, b), clamp(s, -b - 1, b), "clip_r %08lx %ld",
              (unsigned long)a, (long)b);
        CHECK(__builtin_pulp_clipu_r(s, b), clamp(s, 0, b), "clipu_r %08lx %ld",
              (unsigned long)a, (long)b);
    }
    CHECK(W(__builtin_pulp_abs4(V4S(a))), packed(ABS, a, 0, 8), "abs4 %08lx", (unsigned long)a);
    CHECK(W(__builtin_pulp_abs2(V2S(a))), packed(ABS, a, 0, 16), "abs2 %08lx", (unsigned long)a);
    CHECK(W(__builtin_pulp_pack4(sb(a, 0), sb(a, 1), sb(a, 2), sb(a, 3))), a, "pack4 %08lx",
          (unsigned long)a);
    /* pack4 keeps each argument's low byte only. */
    CHECK(W(__builtin_pulp_pack4(a, a >> 8, (int32_t)a >> 16, a >> 24)), a, "pack4 wide %08lx",
          (unsigned long)a);
    CHECK(W(__builtin_pulp_pack2(sh(a, 0), (int32_t)a >> 16)), a, "pack2 %08lx", (unsigned long)a);
}

/* The immediate forms need constants: one block per (size, off). */
#define FIELD(a, size, off)                                                                 \
    do {                                                                                    \
        uint32_t fld_ = ((uint32_t)((size) - 1) << 5) | (off);                              \
        uint32_t m_ = run_mask((size) + (off) > 32 ? 32 - (off) : (size), off);             \
        CHECK(__builtin_pulp_bextract(a, size, off), field_ref(a, size, off, 1),            \
              "bextract %08lx %d %d", (unsigned long)(a), size, off);                       \
        CHECK(__builtin_pulp_bextractu(a, size, off), field_ref(a, size, off, 0),           \
              "bextractu %08lx %d %d", (unsigned long)(a), size, off);                      \
        CHECK(__builtin_pulp_bextract_r(a, opaque(fld_)), field_ref(a, size, off, 1),       \
              "bextract_r %08lx %d %d", (unsigned long)(a), size, off);                     \
        CHECK(__builtin_pulp_bextractu_r(a, opaque(fld_)), field_ref(a, size, off, 0),      \
              "bextractu_r %08lx %d %d", (unsigned long)(a), size, off);                    \
        CHECK(__builtin_pulp_bset_r(a, opaque(fld_)), (a) | m_, "bset_r %08lx %d %d",       \
              (unsigned long)(a), size, off);                                               \
        CHECK(__builtin_pulp_bclr_r(a, opaque(fld_)), (a) & ~m_, "bclr_r %08lx %d %d",      \
              (unsigned long)(a), size, off);                                               \
    } while (0)
/* bset/bclr/binsert: masks as the SDK's gap8_bitset/bitclr/bitinsert build them. */
#define MASKED(a, b, size, off)                                                             \
    do {                                                                                    \
        uint32_t m_ = run_mask(size, off);                                                  \
        CHECK(__builtin_pulp_bset(a, run_mask(size, off)), (a) | m_, "bset %08lx %d %d",     \
              (unsigned long)(a), size, off);                                               \
        CHECK(__builtin_pulp_bclr(a, ~run_mask(size, off)), (a) & ~m_, "bclr %08lx %d %d",   \
              (unsigned long)(a), size, off);                                               \
        CHECK(__builtin_pulp_binsert(a, ~run_mask(size, off), b, run_mask(size, off), off), \
              ((a) & ~m_) | (((b) << (off)) & m_), "binsert %08lx %08lx %d %d",             \
              (unsigned long)(a), (unsigned long)(b), size, off);                           \
        CHECK(__builtin_pulp_binsert_r(a, b, opaque(((uint32_t)((size) - 1) << 5) | (off))), \
              ((a) & ~m_) | (((b) << (off)) & m_), "binsert_r %08lx %08lx %d %d",           \
              (unsigned long)(a), (unsigned long)(b), size, off);                           \
    } while (0)

static void fields(uint32_t a, uint32_t b)
{
    FIELD(a, 1, 0);
    FIELD(a, 1, 31);
    FIELD(a, 4, 4);
    FIELD(a, 8, 24);
    FIELD(a, 5, 27);
    FIELD(a, 16, 8);
    FIELD(a, 32, 0);
    FIELD(a, 8, 28); /* the field runs past bit 31: clamped there */
    MASKED(a, b, 1, 0);
    MASKED(a, b, 4, 4);
    MASKED(a, b, 8, 24);
    MASKED(a, b, 31, 1);
}

static void binary(uint32_t a, uint32_t b)
{
    int32_t sa = (int32_t)a, sbv = (int32_t)b;
    unsigned long la = a, lb = b;
    CHECK(__builtin_pulp_minsi(sa, sbv), sa < sbv ? sa : sbv, "minsi %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_maxsi(sa, sbv), sa > sbv ? sa : sbv, "maxsi %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_mac(sa, sbv, 0x01020304), 0x01020304u + a * b, "mac %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_msu(sa, sbv, 0x01020304), 0x01020304u - a * b, "msu %08lx %08lx", la, lb);

    CHECK(W(__builtin_pulp_add4(V4S(a), V4S(b))), packed(ADD, a, b, 8), "add4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_sub4(V4S(a), V4S(b))), packed(SUB, a, b, 8), "sub4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_avg4(V4S(a), V4S(b))), packed(AVG, a, b, 8), "avg4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_avgu4(V4U(a), V4U(b))), packed(AVGU, a, b, 8), "avgu4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_max4(V4S(a), V4S(b))), packed(MAX, a, b, 8), "max4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_maxu4(V4U(a), V4U(b))), packed(MAXU, a, b, 8), "maxu4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_min4(V4S(a), V4S(b))), packed(MIN, a, b, 8), "min4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_minu4(V4U(a), V4U(b))), packed(MINU, a, b, 8), "minu4 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_shuffleb(V4S(a), V4S(b))), packed(SHUF, a, b, 8), "shuffleb %08lx %08lx", la, lb);

    CHECK(W(__builtin_pulp_add2(V2S(a), V2S(b))), packed(ADD, a, b, 16), "add2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_sub2(V2S(a), V2S(b))), packed(SUB, a, b, 16), "sub2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_avg2(V2S(a), V2S(b))), packed(AVG, a, b, 16), "avg2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_avgu2(V2U(a), V2U(b))), packed(AVGU, a, b, 16), "avgu2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_max2(V2S(a), V2S(b))), packed(MAX, a, b, 16), "max2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_maxu2(V2U(a), V2U(b))), packed(MAXU, a, b, 16), "maxu2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_min2(V2S(a), V2S(b))), packed(MIN, a, b, 16), "min2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_minu2(V2U(a), V2U(b))), packed(MINU, a, b, 16), "minu2 %08lx %08lx", la, lb);
    CHECK(W(__builtin_pulp_shuffleh(V2S(a), V2S(b))), packed(SHUF, a, b, 16), "shuffleh %08lx %08lx", la, lb);

    const int acc = -0x12345;
    CHECK(__builtin_pulp_dotsp4(V4S(a), V4S(b)), dot(a, b, 8, 3), "dotsp4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_dotup4(V4U(a), V4U(b)), dot(a, b, 8, 0), "dotup4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_dotusp4(V4U(a), V4S(b)), dot(a, b, 8, 2), "dotusp4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotsp4(V4S(a), V4S(b), acc), (uint32_t)acc + dot(a, b, 8, 3),
          "sdotsp4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotup4(V4U(a), V4U(b), (unsigned)acc), (uint32_t)acc + dot(a, b, 8, 0),
          "sdotup4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotusp4(V4U(a), V4S(b), acc), (uint32_t)acc + dot(a, b, 8, 2),
          "sdotusp4 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_dotsp2(V2S(a), V2S(b)), dot(a, b, 16, 3), "dotsp2 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_dotup2(V2U(a), V2U(b)), dot(a, b, 16, 0), "dotup2 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_dotusp2(V2U(a), V2S(b)), dot(a, b, 16, 2), "dotusp2 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotsp2(V2S(a), V2S(b), acc), (uint32_t)acc + dot(a, b, 16, 3),
          "sdotsp2 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotup2(V2U(a), V2U(b), (unsigned)acc), (uint32_t)acc + dot(a, b, 16, 0),
          "sdotup2 %08lx %08lx", la, lb);
    CHECK(__builtin_pulp_sdotusp2(V2U(a), V2S(b), acc), (uint32_t)acc + dot(a, b, 16, 2),
          "sdotusp2 %08lx %08lx", la, lb);
}

/* PULP-NN's barrier call, an argument and all, inside a fork. */
static volatile uint32_t arrived;
static void barrier_with_argument(void *arg)
{
    (void)arg;
    pi_cl_team_critical_enter();
    arrived++;
    pi_cl_team_critical_exit();
    pi_cl_team_barrier(0);
    if (pi_core_id() == 0)
        check("barrier(0): every core arrived first", arrived, (uint32_t)pi_cl_team_nb_cores());
}

static void on_core0(void *arg)
{
    (void)arg;
    for (unsigned i = 0; i < NOPS; i++) {
        uint32_t a = opaque(OPS[i]);
        unary(a);
        fields(a, opaque(OPS[(i + 7) % NOPS]));
        for (unsigned j = 0; j < NOPS; j++)
            binary(a, opaque(OPS[j]));
    }
    pi_cl_team_fork(0, barrier_with_argument, NULL);
}

int main(void)
{
    static struct pi_device cluster;
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster)) {
        printf("pulp_builtins_test: cannot open the cluster\n");
        return 1;
    }
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, on_core0, NULL));
    pi_cluster_close(&cluster);
    return summary("pulp_builtins_test");
}
