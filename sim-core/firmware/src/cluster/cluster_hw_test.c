/* The cluster hardware's test program (sim-core/tests/cluster_hw.rs reads
 * the `results` structure by symbol): boot through CTRL, mhartid, the
 * event unit (dispatch, barrier with staggered arrivals, mutex,
 * wait/trigger), L1 bank conflicts, DMA 1D/2D both ways and its overlap
 * with compute. No libc on the cluster cores (picolibc's TLS is the FC's);
 * the FC prints a summary on the semihosting console. */
#include <stdio.h>
#include <string.h>
#include "cluster_regs.h"

#define MAX_CORES 8
#define HAMMER 64 /* loads per core in the bank test */
#define COUNT 100 /* mutex increments per core */

struct results {
    uint32_t ncores;
    uint32_t hartid[MAX_CORES];
    uint32_t dispatched[MAX_CORES];
    uint32_t arrive[MAX_CORES], leave[MAX_CORES];
    uint32_t counter;
    uint32_t woke_value, trig_time, woke_time;
    uint32_t same_bank[MAX_CORES], own_bank[MAX_CORES];
    uint32_t dma_start, dma_end, dma_ok_1d, dma_ok_2d, dma_ok_back;
    uint32_t overlap_start, overlap_cmd_done, overlap_end, compute_only;
    uint32_t gated_instret_before, gated_instret_after;
    uint32_t fc_hartid;
    /* mcycle around one load from L1 and from L2: by the FC, by core 0. */
    uint32_t fc_l1, fc_l2, core_l1, core_l2;
    /* What core 0's last poll of MAILBOX read (the FC's write). */
    uint32_t mailbox_seen;
};
volatile struct results results;

/* L2 buffers for the DMA. */
static uint8_t src[2048] __attribute__((aligned(8)));
static uint8_t back[2048] __attribute__((aligned(8)));
#define L1_BUF ((volatile uint8_t *)(L1_BASE + 0x1000))
#define L1_BUF2 ((volatile uint8_t *)(L1_BASE + 0x2000))
#define L1_BUF3 ((volatile uint8_t *)(L1_BASE + 0x4000))

uint32_t stacks[MAX_CORES][256];

void cl_entry(void);
__asm__(".text\n.globl cl_entry\ncl_entry:\n"
        ".option push\n.option norelax\nla gp, __global_pointer$\n.option pop\n"
        "csrr a0, mhartid\nandi a0, a0, 31\n"
        "la sp, stacks\naddi t0, a0, 1\nslli t0, t0, 10\nadd sp, sp, t0\n"
        "call cl_main\n"
        "li t0, 0x1020001C\nsw zero, 0(t0)\n1: j 1b\n");

static void barrier(void) { (void)EU_BARRIER_WAIT; }

/* mcycle around one load of `p` (its result unused: no load-use stall). */
static uint32_t one_load(volatile uint32_t *p)
{
    uint32_t a, b;
    __asm__ volatile("csrr %0, mcycle\n"
                     "lw t1, 0(%2)\n"
                     "csrr %1, mcycle\n"
                     : "=&r"(a), "=&r"(b)
                     : "r"(p)
                     : "t1", "memory");
    return b - a;
}

static volatile uint32_t l2_word;

/* mcycle around HAMMER back-to-back loads of `p`. */
static uint32_t hammer(volatile uint32_t *p)
{
    uint32_t a, b;
    __asm__ volatile("csrr %0, mcycle\n"
                     ".rept 64\nlw t1, 0(%2)\n.endr\n"
                     "csrr %1, mcycle\n"
                     : "=&r"(a), "=&r"(b)
                     : "r"(p)
                     : "t1", "memory");
    return b - a;
}

static void dma(uint32_t ext, uint32_t loc, uint32_t size, uint32_t cmd)
{
    DMA_EXT = ext;
    DMA_LOC = loc;
    DMA_SIZE = size;
    DMA_CMD = cmd;
}

static void dma_wait(void)
{
    EU_EVT_MASK = 1u << EVT_DMA;
    (void)EU_EVT_WAIT_CLR;
}

static void dma_tests(void)
{
    /* 1D L2 -> L1, timed from the CMD store to the wake-up. */
    DMA_EXT = (uint32_t)src;
    DMA_LOC = (uint32_t)L1_BUF;
    DMA_SIZE = 1024;
    uint32_t t0 = now_cycles();
    DMA_CMD = DMA_EXT2LOC;
    dma_wait();
    uint32_t t1 = now_cycles();
    results.dma_start = t0;
    results.dma_end = t1;
    uint32_t ok = 1;
    for (int i = 0; i < 1024; i++)
        ok &= L1_BUF[i] == src[i];
    results.dma_ok_1d = ok;
    /* 2D: 8 lines of 16 bytes every 64 bytes of L2, packed in L1. */
    DMA_STRIDE = 64;
    DMA_LENGTH = 16;
    dma((uint32_t)src, (uint32_t)L1_BUF2, 128, DMA_EXT2LOC | DMA_2D);
    dma_wait();
    ok = 1;
    for (int l = 0; l < 8; l++)
        for (int j = 0; j < 16; j++)
            ok &= L1_BUF2[l * 16 + j] == src[l * 64 + j];
    results.dma_ok_2d = ok;
    /* L1 -> L2: 1D of the first copy, and 2D back into the strided shape. */
    dma((uint32_t)back, (uint32_t)L1_BUF, 1024, DMA_LOC2EXT);
    dma((uint32_t)back + 1024, (uint32_t)L1_BUF2, 128, DMA_LOC2EXT | DMA_2D);
    (void)EU_EVT_WAIT_CLR; /* both commands signal the same event */
    while (DMA_STATUS != 0)
        ;
    ok = memcmp(back, src, 1024) == 0;
    for (int l = 0; l < 8; l++)
        ok &= memcmp(back + 1024 + l * 64, src + l * 64, 16) == 0;
    results.dma_ok_back = ok;
    /* Overlap: 8 KiB (1024 transfer cycles) while computing ~1000 cycles. */
    uint32_t s = now_cycles();
    dma((uint32_t)src, (uint32_t)L1_BUF3, 2048, DMA_EXT2LOC);
    dma((uint32_t)src, (uint32_t)L1_BUF3 + 2048, 2048, DMA_EXT2LOC);
    dma((uint32_t)src, (uint32_t)L1_BUF3 + 4096, 2048, DMA_EXT2LOC);
    dma((uint32_t)src, (uint32_t)L1_BUF3 + 6144, 2048, DMA_EXT2LOC);
    uint32_t c0 = now_cycles();
    for (volatile int i = 0; i < 100; i++)
        ;
    uint32_t c1 = now_cycles();
    while (DMA_STATUS != 0)
        ;
    results.overlap_start = s;
    results.overlap_end = now_cycles();
    results.compute_only = c1 - c0;
    EU_EVT_CLEAR = 1u << EVT_DMA;
}

void cl_main(uint32_t id)
{
#ifdef BAD_DMA
    /* A command past the end of L1: the CMD store faults (no handler on
     * the cluster core: the run ends with a clear error). */
    if (id == 0)
        dma((uint32_t)src, L1_BASE + 0xff00, 1024, DMA_EXT2LOC);
#endif
    uint32_t n = CTRL_NB_CORES;
    results.hartid[id] = hartid();
    if (id == 0) {
        results.core_l1 = one_load((volatile uint32_t *)(L1_BASE + 0x8000));
        results.core_l2 = one_load(&l2_word);
    }
    /* Dispatch: core 0 pushes one word per core; each pops its own. */
    if (id == 0) {
        EU_TEAM_CONFIG = (1u << n) - 1;
        for (uint32_t i = 0; i < n; i++)
            EU_DISPATCH_PUSH = 0x100 + i;
    }
    uint32_t w = 0;
    for (uint32_t i = 0; i <= id; i++)
        w = EU_DISPATCH_POP;
    results.dispatched[id] = w;
    barrier();
    /* Barrier with staggered arrivals: core i arrives ~200 i cycles late;
     * core 0 arrives last of all. */
    uint32_t start = now_cycles();
    uint32_t delay = id == 0 ? 200 * n : 200 * id;
    while (now_cycles() - start < delay)
        ;
    results.arrive[id] = now_cycles();
    barrier();
    results.leave[id] = now_cycles();
    /* Mutex: a counter incremented under the mutex by every core. */
    for (int k = 0; k < COUNT; k++) {
        (void)EU_MUTEX_LOCK;
        uint32_t c = results.counter;
        results.counter = c + 1;
        EU_MUTEX_UNLOCK = 0;
    }
    barrier();
    /* Bank conflicts: core 0 arrives last at the barrier (so cores 1..n-1
     * leave it in the same cycle), then they load one word HAMMER times:
     * all in bank 0, then each in its own bank. */
    volatile uint32_t *l1 = (volatile uint32_t *)L1_BASE;
    if (id == 0) {
        uint32_t t = now_cycles();
        while (now_cycles() - t < 500)
            ;
    }
    barrier();
    if (id != 0)
        results.same_bank[id] = hammer(&l1[16 * id]); /* bank 0 */
    if (id == 0) {
        uint32_t t = now_cycles();
        while (now_cycles() - t < 2000)
            ;
    }
    barrier();
    if (id != 0)
        results.own_bank[id] = hammer(&l1[id]); /* bank id */
    barrier();
    /* Wait/trigger and gated cores: core 1 sleeps on event 3, the others
     * but core 0 on the barrier; core 0 works, then triggers. */
    if (id == 1) {
        EU_EVT_MASK = 1u << 3;
        uint32_t before;
        __asm__ volatile("csrr %0, minstret" : "=r"(before));
        results.gated_instret_before = before;
        results.woke_value = EU_EVT_WAIT_CLR;
        results.woke_time = now_cycles();
        uint32_t after;
        __asm__ volatile("csrr %0, minstret" : "=r"(after));
        results.gated_instret_after = after;
    } else if (id == 0) {
        dma_tests();
        results.trig_time = now_cycles();
        EU_SW_EVT_TRIG(3) = 1u << 1;
    }
    barrier();
    if (id == 0) {
        CTRL_FC_EVENT = 1;
        /* A core polling a plain CTRL register while the FC works: idle
         * skipping jumps it to the FC's write, exactly
         * (sim-core/tests/cluster_idle.rs). The PMSIS runtime no longer
         * polls (its core 0 sleeps on the mailbox event); a user's may. */
        uint32_t m;
        while ((m = CTRL_MAILBOX) == 0)
            ;
        results.mailbox_seen = m;
    }
}

/* REPEAT > 1 (the kernel test's variant): run the whole test that many
 * times, powering the cluster on and off each time, so that several 1 ms
 * power samples see it. */
#ifndef REPEAT
#define REPEAT 1
#endif

int main(void)
{
    for (int i = 0; i < 2048; i++)
        src[i] = (uint8_t)(i * 7 + 3);
    __asm__ volatile("csrr %0, mhartid" : "=r"(results.fc_hartid));
    results.fc_l1 = one_load((volatile uint32_t *)(L1_BASE + 0x8000));
    results.fc_l2 = one_load(&l2_word);
    for (int rep = 0; rep < REPEAT; rep++) {
        CTRL_POWER = 1;
        results.ncores = CTRL_NB_CORES;
        uint32_t all = (1u << results.ncores) - 1;
        CTRL_BOOT_ADDR = (uint32_t)cl_entry;
        CTRL_FETCH_EN = all;
        while (CTRL_FC_EVENT == 0)
            ;
        for (volatile int k = 0; k < 2000; k++) /* the FC works a while */
            ;
        CTRL_MAILBOX = (uint32_t)rep + 1;
        while (CTRL_RUNNING != 0)
            ;
        CTRL_MAILBOX = 0;
        CTRL_POWER = 0;
    }
    printf("cluster: %lu cores, counter %lu, dma %lu cycles\n",
           (unsigned long)results.ncores, (unsigned long)results.counter,
           (unsigned long)(results.dma_end - results.dma_start));
    return 0;
}
