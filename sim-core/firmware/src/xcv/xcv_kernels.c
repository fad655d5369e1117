/*
 * Kernels that clang-19 -O2 compiles with the CORE-V extensions on its own
 * (post-increment loads and stores, cv.min/cv.max), plus the int8 dot
 * product through cv.sdotsp.b (xcv.h). sim-core/tests/iss_xcv.rs runs it on
 * the ISS and checks every printed number against the same arithmetic in
 * Rust. The inputs come from a fixed LCG so the test can rebuild them.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include "../xcv.h"

#define N 256

static int8_t a8[N] __attribute__((aligned(4))), b8[N] __attribute__((aligned(4)));
static int16_t a16[N], b16[N];
static int32_t a32[N], b32[N], y32[N];

static uint32_t seed = 12345;
static uint32_t lcg(void)
{
    seed = seed * 1103515245u + 12345u;
    return seed >> 8;
}

/* Plain C: clang emits cv.lb / cv.lh / cv.lw post-increment loads. */
__attribute__((noinline)) static int32_t dot8(const int8_t *a, const int8_t *b, int n)
{
    int32_t s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}
__attribute__((noinline)) static int32_t dot16(const int16_t *a, const int16_t *b, int n)
{
    int32_t s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}
/* cv.lw post-increment loads and a cv.sw post-increment store. */
__attribute__((noinline)) static void axpy(int32_t *y, const int32_t *x, int32_t k, int n)
{
    for (int i = 0; i < n; i++)
        y[i] += k * x[i];
}
/* cv.min / cv.max. */
__attribute__((noinline)) static int32_t clamp_sum(const int32_t *x, int n)
{
    int32_t s = 0;
    for (int i = 0; i < n; i++) {
        int32_t v = x[i];
        s += v < -128 ? -128 : (v > 127 ? 127 : v);
    }
    return s;
}
/* The NN inner loop: four int8 products per cv.sdotsp.b. */
__attribute__((noinline)) static int32_t dot8_simd(const int8_t *a, const int8_t *b, int n)
{
    const uint32_t *pa = (const uint32_t *)a, *pb = (const uint32_t *)b;
    int32_t s = 0;
    for (int i = 0; i < n / 4; i++)
        s = xcv_sdotsp_b(s, xcv_lw_inc(pa, 4), xcv_lw_inc(pb, 4));
    return s;
}

int main(void)
{
    for (int i = 0; i < N; i++) {
        a8[i] = (int8_t)lcg();
        b8[i] = (int8_t)lcg();
        a16[i] = (int16_t)lcg();
        b16[i] = (int16_t)lcg();
        a32[i] = (int32_t)(lcg() & 0x3ff) - 512;
        b32[i] = (int32_t)lcg();
        y32[i] = (int32_t)lcg();
    }
    /* The edge value of the signed byte products: -128 * -128. */
    a8[0] = -128;
    b8[0] = -128;
    printf("dot8 %ld\n", (long)dot8(a8, b8, N));
    printf("dot8_simd %ld\n", (long)dot8_simd(a8, b8, N));
    printf("dot16 %ld\n", (long)dot16(a16, b16, N));
    axpy(y32, b32, 7, N);
    uint32_t h = 0;
    for (int i = 0; i < N; i++)
        h = h * 31u + (uint32_t)y32[i];
    printf("axpy %lu\n", (unsigned long)h);
    printf("clamp %ld\n", (long)clamp_sum(a32, N));
    printf("clip %ld %ld %ld\n", (long)xcv_clip(a32[0] * 1000, 8), (long)xcv_clip(-100000, 8),
           (long)xcv_clip(99, 8));
    return 0;
}
