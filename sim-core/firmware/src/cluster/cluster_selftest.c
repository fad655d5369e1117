/*
 * Self-test of the PMSIS runtime (src/pmsis/) on the cluster hardware
 * (docs/CLUSTER.md): forks of 1/2/4/8 cores, the barrier, the critical
 * section, DMA 1D and 2D round trips through the API (from one core and
 * from all at once), the performance counters, the allocators (out of
 * memory gives NULL), asynchronous tasks, core 0 asleep between tasks and
 * the FC asleep while it waits for one.
 * Every check runs on the FC or on core 0 (the harness's counters are not
 * shared); the other cores record what they saw. Prints one summary line;
 * exit status = failures.
 */
#include <pmsis.h>
#include <stdio.h>
#include <string.h>

#include "../selfcheck.h"

static struct pi_device cluster;

/* ---- fork, barrier, critical section ---------------------------------- */

static volatile uint32_t seen_mask, seen_team;

static void record(void *arg)
{
    (void)arg;
    pi_cl_team_critical_enter();
    seen_mask |= 1u << pi_core_id();
    seen_team |= (uint32_t)pi_cl_team_nb_cores() << (4 * pi_core_id());
    pi_cl_team_critical_exit();
}

static void test_fork(void)
{
    int all = pi_cl_team_nb_cores();
    for (int n = 1; n <= 8; n *= 2) {
        if (n > all)
            break;
        seen_mask = 0;
        seen_team = 0;
        pi_cl_team_fork(n, record, NULL);
        char name[32];
        snprintf(name, sizeof name, "fork %d: cores", n);
        check(name, seen_mask, (1u << n) - 1);
        uint32_t team = 0;
        for (int i = 0; i < n; i++)
            team |= (uint32_t)n << (4 * i);
        snprintf(name, sizeof name, "fork %d: team sizes", n);
        check(name, seen_team, team);
    }
    seen_mask = 0;
    pi_cl_team_fork(0, record, NULL);
    check("fork 0: every core", seen_mask, (1u << all) - 1);
    check("outside a fork: nb_cores", (uint32_t)pi_cl_team_nb_cores(), (uint32_t)all);
}

/* Three phases separated by barriers: each core reads what its neighbour
 * wrote in the phase before, which only a working barrier guarantees. */
static volatile uint32_t phase_value[8], phase_errors;

static void phases(void *arg)
{
    (void)arg;
    uint32_t me = pi_core_id(), n = (uint32_t)pi_cl_team_nb_cores();
    uint32_t next = (me + 1) % n;
    for (uint32_t p = 1; p <= 3; p++) {
        phase_value[me] = p * 100 + me;
        pi_cl_team_barrier();
        if (phase_value[next] != p * 100 + next) {
            pi_cl_team_critical_enter();
            phase_errors++;
            pi_cl_team_critical_exit();
        }
        pi_cl_team_barrier();
    }
}

/* A non-atomic read-modify-write that only the mutex keeps exact. */
static volatile uint32_t counter;
#define INCREMENTS 200

static void count(void *arg)
{
    (void)arg;
    for (int i = 0; i < INCREMENTS; i++) {
        pi_cl_team_critical_enter();
        uint32_t v = counter;
        __asm__ volatile("nop; nop; nop"); /* widen the window */
        counter = v + 1;
        pi_cl_team_critical_exit();
    }
}

static void test_barrier_and_critical(void)
{
    int all = pi_cl_team_nb_cores();
    phase_errors = 0;
    pi_cl_team_fork(0, phases, NULL);
    check("barrier: neighbour's value of the phase", phase_errors, 0);
    counter = 0;
    pi_cl_team_fork(0, count, NULL);
    check("critical: counter", counter, (uint32_t)(all * INCREMENTS));
}

/* ---- DMA -------------------------------------------------------------- */

#define ROWS 12
#define STRIDE 40
#define LINE 24
#define LEN1D 1000

static uint8_t l2_src[ROWS * STRIDE], l2_dst[ROWS * STRIDE];

static uint32_t count_diffs(const uint8_t *a, const uint8_t *b, uint32_t n)
{
    uint32_t d = 0;
    for (uint32_t i = 0; i < n; i++)
        d += a[i] != b[i];
    return d;
}

static void test_dma(void)
{
    uint8_t *l1 = pi_l1_malloc(&cluster, LEN1D);
    check("dma: L1 buffer", l1 != NULL, 1);
    if (!l1)
        return;
    check("dma: L1 buffer in L1", (uint32_t)l1 - CL_L1_BASE < CL_L1_SIZE, 1);
    for (uint32_t i = 0; i < sizeof l2_src; i++)
        l2_src[i] = (uint8_t)(i * 7 + 3);

    /* 1D: L2 -> L1 (odd size), change in L1, L1 -> L2. */
    pi_cl_dma_cmd_t cmd;
    memset(l2_dst, 0, sizeof l2_dst);
    pi_cl_dma_cmd((uint32_t)l2_src, (uint32_t)l1, 475, PI_CL_DMA_DIR_EXT2LOC, &cmd);
    pi_cl_dma_cmd_wait(&cmd);
    check("dma 1D in: bytes", count_diffs(l1, l2_src, 475), 0);
    for (int i = 0; i < 475; i++)
        l1[i] ^= 0x5a;
    pi_cl_dma_copy_t copy = {
        .ext = (uint32_t)l2_dst, .loc = (uint32_t)l1, .size = 475, .dir = PI_CL_DMA_DIR_LOC2EXT};
    pi_cl_dma_memcpy(&copy);
    pi_cl_dma_wait(&copy);
    uint32_t bad = 0;
    for (int i = 0; i < 475; i++)
        bad += l2_dst[i] != (uint8_t)(l2_src[i] ^ 0x5a);
    check("dma 1D out: bytes", bad, 0);
    check("dma 1D out: nothing past the end", l2_dst[475], 0);

    /* 2D: a 12x24 window of a 12x40 image into packed L1, and back to
     * another image at the same place. */
    memset(l2_dst, 0xee, sizeof l2_dst);
    memset(l1, 0, LEN1D);
    pi_cl_dma_cmd_2d((uint32_t)(l2_src + 8), (uint32_t)l1, ROWS * LINE, STRIDE, LINE,
                     PI_CL_DMA_DIR_EXT2LOC, &cmd);
    pi_cl_dma_cmd_wait(&cmd);
    bad = 0;
    for (int r = 0; r < ROWS; r++)
        bad += count_diffs(l1 + r * LINE, l2_src + r * STRIDE + 8, LINE);
    check("dma 2D in: packed window", bad, 0);
    pi_cl_dma_copy_2d_t copy2 = {.ext = (uint32_t)(l2_dst + 8),
                                 .loc = (uint32_t)l1,
                                 .size = ROWS * LINE,
                                 .dir = PI_CL_DMA_DIR_LOC2EXT,
                                 .stride = STRIDE,
                                 .length = LINE};
    pi_cl_dma_memcpy_2d(&copy2);
    pi_cl_dma_wait(&copy2);
    bad = 0;
    for (int r = 0; r < ROWS; r++)
        for (int c = 0; c < STRIDE; c++) {
            uint8_t want = c >= 8 && c < 8 + LINE ? l2_src[r * STRIDE + c] : 0xee;
            bad += l2_dst[r * STRIDE + c] != want;
        }
    check("dma 2D out: window, gaps untouched", bad, 0);

    /* Two commands in flight, waited in the other order. */
    pi_cl_dma_cmd_t a, b;
    pi_cl_dma_cmd((uint32_t)l2_src, (uint32_t)l1, 300, PI_CL_DMA_DIR_EXT2LOC, &a);
    pi_cl_dma_cmd((uint32_t)(l2_src + 300), (uint32_t)(l1 + 300), 180, PI_CL_DMA_DIR_EXT2LOC, &b);
    check("dma: two commands, two ids", a.id != b.id, 1);
    pi_cl_dma_cmd_wait(&b);
    pi_cl_dma_cmd_wait(&a);
    check("dma: both copied", count_diffs(l1, l2_src, 480), 0);
    pi_l1_free(&cluster, l1, LEN1D);
}

/* Every core copies its own slice in and out at once. */
static uint8_t *slices;
static volatile uint32_t slice_errors;
#define SLICE 64

static void dma_slices(void *arg)
{
    (void)arg;
    uint32_t me = pi_core_id();
    uint8_t *loc = slices + me * SLICE;
    pi_cl_dma_cmd_t cmd;
    pi_cl_dma_cmd((uint32_t)(l2_src + me * SLICE % sizeof l2_src), (uint32_t)loc, SLICE,
                  PI_CL_DMA_DIR_EXT2LOC, &cmd);
    pi_cl_dma_cmd_wait(&cmd);
    uint32_t bad = count_diffs(loc, l2_src + me * SLICE % sizeof l2_src, SLICE);
    if (bad) {
        pi_cl_team_critical_enter();
        slice_errors += bad;
        pi_cl_team_critical_exit();
    }
}

static void test_dma_all_cores(void)
{
    slices = pi_l1_malloc(&cluster, 8 * SLICE);
    check("dma all cores: L1 buffer", slices != NULL, 1);
    if (!slices)
        return;
    slice_errors = 0;
    pi_cl_team_fork(0, dma_slices, NULL);
    check("dma all cores: bytes", slice_errors, 0);
    pi_l1_free(&cluster, slices, 8 * SLICE);
}

/* ---- performance counters --------------------------------------------- */

static void test_perf(void)
{
    /* 500 iterations of addi + bnez: 1000 instructions, plus the few of
     * pi_perf_stop before it samples. */
    uint32_t n = 500;
    pi_perf_conf(1u << PI_PERF_CYCLES | 1u << PI_PERF_INSTR | 1u << PI_PERF_ACTIVE_CYCLES);
    pi_perf_reset();
    pi_perf_start();
    __asm__ volatile("1: addi %0, %0, -1\n bnez %0, 1b" : "+r"(n));
    pi_perf_stop();
    uint32_t instr = pi_perf_read(PI_PERF_INSTR);
    uint32_t cycles = pi_perf_read(PI_PERF_CYCLES);
    uint32_t active = pi_perf_read(PI_PERF_ACTIVE_CYCLES);
    check("perf: instructions of the loop (+ < 40)", instr >= 1000 && instr < 1040, 1);
    check("perf: cycles >= instructions", cycles >= instr, 1);
    check("perf: active cycles <= cycles", active <= cycles && active >= instr, 1);
    check("perf: an event not configured reads 0", (pi_perf_conf(1u << PI_PERF_INSTR),
                                                     pi_perf_read(PI_PERF_CYCLES)), 0);
    pi_perf_reset();
    check("perf: reset", pi_perf_read(PI_PERF_INSTR), 0);
}

/* ---- allocators ------------------------------------------------------- */

static void test_l1_alloc(void)
{
    /* Take 1 KiB blocks until NULL, give them back, take them again: the
     * same count (the free list coalesces). */
    static void *blocks[64];
    int n = 0;
    while (n < 64 && (blocks[n] = pi_l1_malloc(&cluster, 1024)) != NULL)
        n++;
    check("l1: some 1 KiB blocks", n > 16 && n < 64, 1);
    check("l1: out of memory gives NULL", pi_l1_malloc(&cluster, 1024) == NULL, 1);
    int in_l1 = 1;
    for (int i = 0; i < n; i++)
        in_l1 &= (uint32_t)blocks[i] - CL_L1_BASE <= CL_L1_SIZE - 1024;
    check("l1: blocks inside L1", in_l1, 1);
    for (int i = 0; i < n; i += 2)
        pi_l1_free(&cluster, blocks[i], 1024);
    for (int i = 1; i < n; i += 2)
        pi_l1_free(&cluster, blocks[i], 1024);
    void *big = pi_l1_malloc(&cluster, (uint32_t)n * 1024);
    check("l1: freed blocks merge into one", big != NULL, 1);
    pi_l1_free(&cluster, big, (uint32_t)n * 1024);
    check("l1: larger than L1 gives NULL", pi_l1_malloc(&cluster, CL_L1_SIZE + 8) == NULL, 1);
    check("l1: size 0 gives NULL", pi_l1_malloc(&cluster, 0) == NULL, 1);
}

static void cluster_tests(void *arg)
{
    (void)arg;
    check("core 0 runs the task", pi_core_id(), 0);
    check("cluster id", pi_cluster_id(), 0);
    test_fork();
    test_barrier_and_critical();
    test_dma();
    test_dma_all_cores();
    test_perf();
    test_l1_alloc();
}

/* ---- asynchronous tasks ----------------------------------------------- */

static volatile uint32_t order[3], order_n;

static void note(void *arg)
{
    order[order_n++] = (uint32_t)arg;
}

static void test_async(void)
{
    struct pi_cluster_task tasks[3];
    pi_task_t done[3];
    order_n = 0;
    for (uint32_t i = 0; i < 3; i++)
        check("async: send", pi_cluster_send_task_to_cl_async(
                                 &cluster, pi_cluster_task(&tasks[i], note, (void *)(i + 1)),
                                 pi_task_block(&done[i])),
              0);
    pi_task_wait_on(&done[2]);
    check("async: the last done means all done", done[0].done && done[1].done, 1);
    check("async: in order", order[0] << 16 | order[1] << 8 | order[2], 1 << 16 | 2 << 8 | 3);
}

/* ---- an idle core 0 sleeps between tasks --------------------------------- */

/* Core 0's wall cycles (`time`) and awake cycles (mcycle) at the start of
 * two tasks the FC sends a while apart. */
static volatile uint32_t stamp_wall[2], stamp_awake[2];

static void stamp(void *arg)
{
    uint32_t i = (uint32_t)arg, wall, awake;
    __asm__ volatile("csrr %0, time" : "=r"(wall));
    __asm__ volatile("csrr %0, mcycle" : "=r"(awake));
    stamp_wall[i] = wall;
    stamp_awake[i] = awake;
}

static void test_idle_core_sleeps(void)
{
    struct pi_cluster_task task;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, stamp, (void *)0));
    /* The FC works a while (about 100,000 of its cycles): core 0, between
     * tasks, must be clock-gated meanwhile (DESIGN.md §12), not polling. */
    for (volatile uint32_t i = 0; i < 10000; i++)
        ;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, stamp, (void *)1));
    uint32_t wall = stamp_wall[1] - stamp_wall[0], awake = stamp_awake[1] - stamp_awake[0];
    check("idle: the FC's work lasted (> 20,000 cluster cycles)", wall > 20000, 1);
    /* Awake: the end of the first task, the wake-up, taking the second
     * (a few hundred cycles at most). */
    check("idle: core 0 slept between the tasks (awake < 2 % of them)", awake * 50 < wall, 1);
}

/* ---- the FC sleeps while it waits for a task ------------------------------ */

static void busy(void *arg)
{
    (void)arg;
    uint32_t t0, t;
    __asm__ volatile("csrr %0, time" : "=r"(t0));
    do
        __asm__ volatile("csrr %0, time" : "=r"(t));
    while (t - t0 < 50000);
}

static void test_fc_sleeps_while_waiting(void)
{
    struct pi_cluster_task task;
    uint32_t wall0, awake0, wall1, awake1;
    __asm__ volatile("csrr %0, time" : "=r"(wall0));
    __asm__ volatile("csrr %0, mcycle" : "=r"(awake0));
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, busy, NULL));
    __asm__ volatile("csrr %0, time" : "=r"(wall1));
    __asm__ volatile("csrr %0, mcycle" : "=r"(awake1));
    uint32_t wall = wall1 - wall0, awake = awake1 - awake0;
    /* 50,000 cluster cycles at 175 MHz: about 71,000 FC cycles at 250. */
    check("fc wait: the task lasted (> 50,000 FC cycles)", wall > 50000, 1);
    /* Awake: sending, the wake-up, the completion (a few hundred cycles). */
    check("fc wait: the FC slept through it (awake < 2 % of it)", awake * 50 < wall, 1);
}

int main(void)
{
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;

    check("fc: cluster id", pi_cluster_id(), CL_FC_CLUSTER_ID);
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    check("open", (uint32_t)pi_cluster_open(&cluster), 0);
    check("open twice fails", (uint32_t)pi_cluster_open(&cluster), (uint32_t)-1);
    check("send", (uint32_t)pi_cluster_send_task_to_cl(
                      &cluster, pi_cluster_task(&task, cluster_tests, NULL)),
          0);
    test_async();
    test_idle_core_sleeps();
    test_fc_sleeps_while_waiting();
    pi_cluster_task(&task, note, NULL);
    task.stack_size = 1u << 20;
    check("task with a stack larger than the cluster's",
          (uint32_t)pi_cluster_send_task_to_cl(&cluster, &task), (uint32_t)-1);
    check("l2: out of memory gives NULL", pi_l2_malloc(1u << 30) == NULL, 1);
    void *p = pi_l2_malloc(4096);
    check("l2: 4 KiB", p != NULL && (uint32_t)p - 0x1c000000u < 512u * 1024u, 1);
    pi_l2_free(p, 4096);
    check("close", (uint32_t)pi_cluster_close(&cluster), 0);
    check("close twice fails", (uint32_t)pi_cluster_close(&cluster), (uint32_t)-1);
    return summary("cluster_selftest");
}
