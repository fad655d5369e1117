/*
 * The cluster benchmark (DESIGN.md §12): C = A · B, int8 × int8 → int32,
 * 64×64×64, with every operand in L1, on 1, 2, 4 and 8 cores (fewer if the
 * cluster has fewer). The inner product uses cv.sdotsp.b (CV32E40P v2
 * manual, "SIMD dot product": rD += Σ rs1.b[i] · rs2.b[i], signed, 4 MACs
 * per instruction) on a 2×2 block of outputs, the scheme of PULP-NN's
 * matmul kernels (Garofalo et al. 2020, §4), with B transposed so both
 * operands are read a word at a time. The FC checks every output against a
 * plain C reference and prints, per core count: cycles of the fork
 * (PI_PERF_CYCLES on core 0), MAC/cycle, speedup over one core, checksum.
 *
 * Built with clang-19 -march=rv32imc_xcv... (the Makefile's xcvprogram).
 * With -DBENCH_REPS=R it is the variant `cosim bench cluster` runs once
 * per core count: the kernel R times on every core the platform has, with
 * no FC reference (this program's plain build checks the results).
 */
#include <pmsis.h>
#include <stdio.h>
#include <string.h>

#include "../xcv.h"

#define N 64
#define MACS ((uint32_t)N * N * N)

/* L2 copies (the FC fills and checks them) and the L1 working set. */
static int8_t a_l2[N * N], bt_l2[N * N]; /* A row-major, B transposed */
static int32_t c_l2[N * N];

struct work {
    const int8_t *a, *bt; /* in L1 */
    int32_t *c;           /* in L1 */
    int cores;
};

/* Rows [first, first + rows) of C, two rows by two columns at a time: per
 * word of k, 4 loads feed 4 dot products (16 MACs). */
static void rows_2x2(const struct work *w, int first, int rows)
{
    for (int i = first; i < first + rows; i += 2) {
        const uint32_t *a0 = (const uint32_t *)(w->a + i * N);
        const uint32_t *a1 = (const uint32_t *)(w->a + (i + 1) * N);
        for (int j = 0; j < N; j += 2) {
            const uint32_t *b0 = (const uint32_t *)(w->bt + j * N);
            const uint32_t *b1 = (const uint32_t *)(w->bt + (j + 1) * N);
            int32_t c00 = 0, c01 = 0, c10 = 0, c11 = 0;
#pragma clang loop unroll(full)
            for (int k = 0; k < N / 4; k++) {
                uint32_t x0 = a0[k], x1 = a1[k], y0 = b0[k], y1 = b1[k];
                c00 = xcv_sdotsp_b(c00, x0, y0);
                c01 = xcv_sdotsp_b(c01, x0, y1);
                c10 = xcv_sdotsp_b(c10, x1, y0);
                c11 = xcv_sdotsp_b(c11, x1, y1);
            }
            w->c[i * N + j] = c00;
            w->c[i * N + j + 1] = c01;
            w->c[(i + 1) * N + j] = c10;
            w->c[(i + 1) * N + j + 1] = c11;
        }
    }
}

static void share(void *arg)
{
    const struct work *w = arg;
    int per_core = N / w->cores;
    rows_2x2(w, (int)pi_core_id() * per_core, per_core);
}

static struct work work;
static uint32_t cycles_of[9], sum_of[9];

static uint32_t checksum(const int32_t *c)
{
    uint32_t sum = 0;
    for (int i = 0; i < N * N; i++)
        sum = sum * 31 + (uint32_t)c[i];
    return sum;
}

/* One measured run on n cores: cycles of the fork(s) on core 0's clock
 * (the dispatch and the closing barrier included, as a caller sees it). */
static void measure(int n, int reps)
{
    memset(work.c, 0, N * N * 4);
    work.cores = n;
    pi_perf_conf(1u << PI_PERF_CYCLES);
    pi_perf_reset();
    pi_perf_start();
    for (int r = 0; r < reps; r++)
        pi_cl_team_fork(n, share, &work);
    pi_perf_stop();
    cycles_of[n] = pi_perf_read(PI_PERF_CYCLES);
    sum_of[n] = checksum(work.c);
    /* Each run's result goes back to L2; the FC checks the last. */
    pi_cl_dma_cmd_t cc;
    pi_cl_dma_cmd((uint32_t)c_l2, (uint32_t)work.c, N * N * 4, PI_CL_DMA_DIR_LOC2EXT, &cc);
    pi_cl_dma_cmd_wait(&cc);
}

static void bench(void *arg)
{
    struct pi_device *cluster = arg;
    int8_t *a = pi_l1_malloc(cluster, N * N);
    int8_t *bt = pi_l1_malloc(cluster, N * N);
    int32_t *c = pi_l1_malloc(cluster, N * N * 4);
    if (!a || !bt || !c) {
        printf("cluster_matmul: not enough L1\n");
        return;
    }
    pi_cl_dma_cmd_t ca, cb;
    pi_cl_dma_cmd((uint32_t)a_l2, (uint32_t)a, N * N, PI_CL_DMA_DIR_EXT2LOC, &ca);
    pi_cl_dma_cmd((uint32_t)bt_l2, (uint32_t)bt, N * N, PI_CL_DMA_DIR_EXT2LOC, &cb);
    pi_cl_dma_cmd_wait(&ca);
    pi_cl_dma_cmd_wait(&cb);
    work = (struct work){.a = a, .bt = bt, .c = c};
#ifdef BENCH_REPS
    measure(pi_cl_team_nb_cores(), BENCH_REPS);
#else
    for (int n = 1; n <= pi_cl_team_nb_cores(); n *= 2)
        measure(n, 1);
#endif
}

/* Deterministic operands over the full int8 range, −128 included. */
static void fill(void)
{
    uint32_t s = 0x2545f491u;
    for (int i = 0; i < N * N; i++) {
        s = s * 1664525u + 1013904223u; /* Numerical Recipes' LCG */
        a_l2[i] = (int8_t)(s >> 24);
        s = s * 1664525u + 1013904223u;
        bt_l2[i] = (int8_t)(s >> 24);
    }
    a_l2[0] = bt_l2[0] = -128; /* the edge product −128·−128 */
}

/* Opens the cluster, runs bench() on it; the cluster's core count. */
static int run_on_cluster(void)
{
    struct pi_device cluster;
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster) != 0) {
        printf("cluster_matmul: cannot open the cluster\n");
        return 0;
    }
    int all = (int)cl_read(CL_CTRL_BASE, CL_CTRL_NB_CORES);
    printf("cluster_matmul: int8 %dx%dx%d in L1, cv.sdotsp.b 2x2, %d cores at %lu MHz\n", N, N,
           N, all, (unsigned long)(cl_read(CL_CTRL_BASE, CL_CTRL_FREQ_HZ) / 1000000u));
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, bench, &cluster));
    pi_cluster_close(&cluster);
    return all;
}

#ifdef BENCH_REPS
int main(void)
{
    fill();
    int all = run_on_cluster();
    if (!all)
        return 1;
    printf("bench cores %d reps %d cycles %lu checksum %08lx\n", all, BENCH_REPS,
           (unsigned long)cycles_of[all], (unsigned long)sum_of[all]);
    return 0;
}
#else
static int32_t c_ref[N * N];

int main(void)
{
    fill();
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            int32_t acc = 0;
            for (int k = 0; k < N; k++)
                acc += a_l2[i * N + k] * bt_l2[j * N + k];
            c_ref[i * N + j] = acc;
        }
    uint32_t ref_sum = checksum(c_ref);
    int all = run_on_cluster();
    if (!all)
        return 1;

    uint32_t wrong = 0, bad_sums = 0;
    for (int i = 0; i < N * N; i++)
        wrong += c_l2[i] != c_ref[i];
    printf("cores cycles MAC/cycle speedup checksum\n");
    for (int n = 1; n <= all; n *= 2) {
        uint32_t cyc = cycles_of[n];
        uint32_t mpc = cyc ? (uint32_t)((uint64_t)MACS * 100 / cyc) : 0;
        uint32_t sp = cyc ? (uint32_t)((uint64_t)cycles_of[1] * 100 / cyc) : 0;
        bad_sums += sum_of[n] != ref_sum;
        printf("%d %lu %lu.%02lu %lu.%02lu %08lx\n", n, (unsigned long)cyc,
               (unsigned long)(mpc / 100), (unsigned long)(mpc % 100), (unsigned long)(sp / 100),
               (unsigned long)(sp % 100), (unsigned long)sum_of[n]);
    }
    int fail = wrong != 0 || bad_sums != 0;
    printf("reference checksum %08lx (plain C on the FC); %lu outputs of the last run differ: %s\n",
           (unsigned long)ref_sum, (unsigned long)wrong, fail ? "FAIL" : "PASS");
    return fail;
}
#endif
