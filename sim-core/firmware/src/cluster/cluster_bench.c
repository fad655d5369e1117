/* Host-speed benchmark of the cluster simulation (docs/CLUSTER.md
 * "Speed"): every core (or, with -DONLY_CORE0, core 0 alone while the
 * others sleep in the barrier) runs the same L1 kernel: ITER passes of a
 * multiply-accumulate over its own 256 words of L1, plus an L2 table read
 * per pass. `sim-core run-elf --stats --cluster-cores N` on it. */
#include <stdio.h>
#include "cluster_regs.h"

#ifndef ITER
#define ITER 20000
#endif

uint32_t stacks[8][256];
volatile uint32_t sums[8];
static const uint32_t table[16] = {1, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53};

void cl_entry(void);
__asm__(".text\n.globl cl_entry\ncl_entry:\n"
        ".option push\n.option norelax\nla gp, __global_pointer$\n.option pop\n"
        "csrr a0, mhartid\nandi a0, a0, 31\n"
        "la sp, stacks\naddi t0, a0, 1\nslli t0, t0, 10\nadd sp, sp, t0\n"
        "call cl_main\n"
        "li t0, 0x1020001C\nsw zero, 0(t0)\n1: j 1b\n");

void cl_main(uint32_t id)
{
    volatile uint32_t *a = (volatile uint32_t *)(L1_BASE + id * 1024);
#ifdef ONLY_CORE0
    int works = id == 0;
#else
    int works = 1;
#endif
    if (works) {
        for (int i = 0; i < 256; i++)
            a[i] = i * (id + 1);
        uint32_t s = 0;
        for (int it = 0; it < ITER; it++) {
            uint32_t k = table[it & 15];
            for (int i = 0; i < 256; i++)
                s += a[i] * k;
        }
        sums[id] = s;
    }
    (void)EU_BARRIER_WAIT;
    if (id == 0)
        CTRL_FC_EVENT = 1;
}

int main(void)
{
    CTRL_POWER = 1;
    uint32_t n = CTRL_NB_CORES;
    CTRL_BOOT_ADDR = (uint32_t)cl_entry;
    CTRL_FETCH_EN = (1u << n) - 1;
    while (CTRL_FC_EVENT == 0)
        ;
    while (CTRL_RUNNING != 0)
        ;
    printf("bench: %lu cores, sum[0] %lu\n", (unsigned long)n, (unsigned long)sums[0]);
    return 0;
}
