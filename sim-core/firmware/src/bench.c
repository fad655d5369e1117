/*
 * CPU-bound benchmark of our own: integer kernels (CRC-32, sorting, matrix
 * multiply, a state machine) over pseudo-random data from a fixed LCG. Each
 * kernel prints its checksum; sim-core's tests recompute them in Rust.
 */
#include <stdint.h>
#include <stdio.h>

#ifndef ROUNDS
#define ROUNDS 4
#endif

#define CRC_LEN 4096
#define SORT_LEN 1024
#define MAT_N 24
#define FSM_LEN 8192

static uint32_t seed;

static uint32_t lcg(void)
{
    /* Numerical Recipes' LCG. */
    seed = seed * 1664525u + 1013904223u;
    return seed;
}

static uint8_t buf[FSM_LEN];
static uint32_t arr[SORT_LEN];
static int32_t ma[MAT_N][MAT_N], mb[MAT_N][MAT_N], mc[MAT_N][MAT_N];

static uint32_t crc32(const uint8_t *p, uint32_t n)
{
    uint32_t crc = 0xffffffffu;
    for (uint32_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xedb88320u & -(crc & 1));
    }
    return ~crc;
}

static void quicksort(uint32_t *a, int lo, int hi)
{
    while (lo < hi) {
        uint32_t pivot = a[(lo + hi) / 2];
        int i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) i++;
            while (a[j] > pivot) j--;
            if (i <= j) {
                uint32_t t = a[i];
                a[i] = a[j];
                a[j] = t;
                i++;
                j--;
            }
        }
        if (j - lo < hi - i) {
            quicksort(a, lo, j);
            lo = i;
        } else {
            quicksort(a, i, hi);
            hi = j;
        }
    }
}

static uint32_t sort_kernel(void)
{
    for (int i = 0; i < SORT_LEN; i++)
        arr[i] = lcg();
    quicksort(arr, 0, SORT_LEN - 1);
    uint32_t sum = 0;
    for (int i = 0; i < SORT_LEN; i++)
        sum = sum * 31u + arr[i];
    return sum;
}

static uint32_t matmul_kernel(void)
{
    for (int i = 0; i < MAT_N; i++)
        for (int j = 0; j < MAT_N; j++) {
            ma[i][j] = (int32_t)(lcg() >> 24) - 128;
            mb[i][j] = (int32_t)(lcg() >> 24) - 128;
        }
    for (int i = 0; i < MAT_N; i++)
        for (int j = 0; j < MAT_N; j++) {
            int32_t s = 0;
            for (int k = 0; k < MAT_N; k++)
                s += ma[i][k] * mb[k][j];
            mc[i][j] = s;
        }
    uint32_t sum = 0;
    for (int i = 0; i < MAT_N; i++)
        for (int j = 0; j < MAT_N; j++)
            sum = sum * 33u ^ (uint32_t)mc[i][j];
    return sum;
}

/* A little tokenizer: counts numbers, words and other symbols in a stream of
 * pseudo-random bytes, with a division to exercise the divider. */
static uint32_t fsm_kernel(void)
{
    for (int i = 0; i < FSM_LEN; i++)
        buf[i] = (uint8_t)(lcg() >> 24);
    enum { IDLE, NUMBER, WORD } state = IDLE;
    uint32_t numbers = 0, words = 0, others = 0, value = 0, acc = 0;
    for (int i = 0; i < FSM_LEN; i++) {
        uint8_t c = buf[i];
        int digit = c < 40;
        int letter = c >= 40 && c < 160;
        switch (state) {
        case IDLE:
            if (digit) {
                state = NUMBER;
                value = c;
            } else if (letter) {
                state = WORD;
            } else {
                others++;
            }
            break;
        case NUMBER:
            if (digit) {
                value = value * 10 + c;
            } else {
                numbers++;
                acc += value / (c + 1u) + value % 7u;
                state = letter ? WORD : IDLE;
            }
            break;
        case WORD:
            if (!letter) {
                words++;
                state = digit ? NUMBER : IDLE;
                value = c;
            }
            break;
        }
    }
    return numbers * 1000003u ^ words * 10007u ^ others * 101u ^ acc;
}

int main(void)
{
    uint32_t crc = 0, sorted = 0, mat = 0, fsm = 0;
    seed = 12345;
    for (int r = 0; r < ROUNDS; r++) {
        for (int i = 0; i < CRC_LEN; i++)
            buf[i] = (uint8_t)(lcg() >> 16);
        crc ^= crc32(buf, CRC_LEN);
        sorted ^= sort_kernel();
        mat ^= matmul_kernel();
        fsm ^= fsm_kernel();
    }
    printf("crc32 %08lx\n", (unsigned long)crc);
    printf("sort %08lx\n", (unsigned long)sorted);
    printf("matmul %08lx\n", (unsigned long)mat);
    printf("fsm %08lx\n", (unsigned long)fsm);
    printf("checksum %08lx\n", (unsigned long)(crc ^ sorted ^ mat ^ fsm));
    return 0;
}
