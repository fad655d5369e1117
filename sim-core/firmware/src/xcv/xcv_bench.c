/*
 * Host-speed benchmark of an XCV-heavy loop (docs/ARCHITECTURE.md "The
 * ISS's speed"): the NN inner loop, cv.lw post-increment + cv.sdotsp.b,
 * over two 4 KiB int8 vectors, REPS times. Prints the sum (checked by
 * sim-core/tests/iss_xcv.rs against Rust).
 */
#include <stdint.h>
#include <stdio.h>
#include "../xcv.h"

#ifndef REPS
#define REPS 2000
#endif
#define N 4096

static int8_t a[N] __attribute__((aligned(4))), b[N] __attribute__((aligned(4)));

__attribute__((noinline)) static int32_t dot(const int8_t *x, const int8_t *y, int n)
{
    const uint32_t *pa = (const uint32_t *)x, *pb = (const uint32_t *)y;
    int32_t s = 0;
    for (int i = 0; i < n / 4; i++)
        s = xcv_sdotsp_b(s, xcv_lw_inc(pa, 4), xcv_lw_inc(pb, 4));
    return s;
}

int main(void)
{
    for (int i = 0; i < N; i++) {
        a[i] = (int8_t)(i * 7 + 3);
        b[i] = (int8_t)(i * 13 - 100);
    }
    int32_t s = 0;
    for (int r = 0; r < REPS; r++)
        s += dot(a, b, N);
    printf("sum %ld\n", (long)s);
    return 0;
}
