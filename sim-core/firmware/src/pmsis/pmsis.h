/*
 * pmsis.h: the PMSIS names of DESIGN.md §12 for the simulated GAP8 (FC +
 * cluster, docs/CLUSTER.md). The one header a program includes
 * (-I sim-core/firmware/src/pmsis); names and signatures follow GreenWaves'
 * PMSIS API (gap_sdk rtos/pmsis/pmsis_api) so AI-deck code ports with
 * little change. What differs is listed in docs/CLUSTER.md, "The runtime".
 */
#ifndef PMSIS_H
#define PMSIS_H

#include <stddef.h>
#include <stdint.h>

#include "cluster_regs.h"
#include "pulp_builtins.h"

/* ---- Devices and tasks ------------------------------------------------ */

struct pi_device {
    void *config; /* what pi_open_from_conf was given */
    void *data;   /* the driver's state once opened */
};

struct pi_cluster_conf {
    int id; /* cluster id: 0, the only cluster */
};

/* A completion the FC can wait on (PMSIS's pi_task_t, event kind only). */
typedef struct pi_task {
    volatile int done;
    struct pi_task *next; /* the runtime's queue of pending completions */
    /* A HyperRAM transfer's (pi_ram_*_async): the µDMA's count of queued
     * transfers after its own, 0 for a cluster task (pmsis/udma_regs.h). */
    uint32_t ram_ticket;
} pi_task_t;

struct pi_cluster_task {
    void (*entry)(void *arg); /* runs on core 0, the master */
    void *arg;
    /* Stack sizes in bytes; 0 = the defaults below. Stacks live in L1. */
    uint32_t stack_size;       /* core 0 */
    uint32_t slave_stack_size; /* cores 1..N-1 */
    int nb_cores;              /* cores a fork with n = 0 uses; 0 = all */
    /* The runtime's: the FC's completion for this task. */
    pi_task_t *done;
};

#define PI_CL_MASTER_STACK_SIZE 2048u
#define PI_CL_SLAVE_STACK_SIZE 1024u

void pi_cluster_conf_init(struct pi_cluster_conf *conf);
void pi_open_from_conf(struct pi_device *device, void *conf);
/* Powers the cluster on and boots its cores; 0, or -1 if it cannot. */
int pi_cluster_open(struct pi_device *device);
/* Waits for the tasks in flight, then powers the cluster off. */
int pi_cluster_close(struct pi_device *device);

static inline struct pi_cluster_task *pi_cluster_task(struct pi_cluster_task *task,
                                                      void (*entry)(void *), void *arg)
{
    task->entry = entry;
    task->arg = arg;
    task->stack_size = 0;
    task->slave_stack_size = 0;
    task->nb_cores = 0;
    task->done = NULL;
    return task;
}

/* Runs the task's entry on core 0 and returns when it has returned. */
int pi_cluster_send_task_to_cl(struct pi_device *device, struct pi_cluster_task *task);
/* Queues the task and returns; `done` completes when its entry returned.
 * One task runs and one waits in the mailbox: a third waits here until the
 * first is done. */
int pi_cluster_send_task_to_cl_async(struct pi_device *device, struct pi_cluster_task *task,
                                     pi_task_t *done);
/* gap_sdk's newer spellings. */
#define pi_cluster_send_task pi_cluster_send_task_to_cl
#define pi_cluster_send_task_async pi_cluster_send_task_to_cl_async

pi_task_t *pi_task_block(pi_task_t *task);
void pi_task_wait_on(pi_task_t *task);

/* ---- Identity ---------------------------------------------------------- */

static inline uint32_t pi_hart_id(void)
{
    uint32_t id;
    __asm__ volatile("csrr %0, mhartid" : "=r"(id));
    return id;
}

static inline uint32_t pi_core_id(void) { return pi_hart_id() & 0x1f; }
static inline uint32_t pi_cluster_id(void) { return pi_hart_id() >> 5; }
static inline int pi_is_fc(void) { return pi_cluster_id() == CL_FC_CLUSTER_ID; }

/* ---- Team (cluster side) ---------------------------------------------- */

/* Runs entry(arg) on cores 0..n-1 (n = 0: the task's nb_cores, or every
 * core), core 0 being the caller; returns when all have returned. */
void pi_cl_team_fork(int nb_cores, void (*entry)(void *), void *arg);
/* The cores of the current team: inside a fork its size, else every core.
 * Declared without a prototype, as the SDK declares it. */
int pi_cl_team_nb_cores();

/* Declared without a prototype, as the SDK declares it (cl_team.h:
 * `void pi_cl_team_barrier();`), so code written for the SDK that passes
 * an argument (PULP-NN's `pi_cl_team_barrier(0)`) builds; the macro drops
 * the argument, as the SDK's barrier ignores it, without clang's warning
 * about calls to a function without a prototype. */
static inline void pi_cl_team_barrier()
{
    (void)cl_read(CL_EU_BASE, CL_EU_BARRIER_WAIT);
}
#define pi_cl_team_barrier(...) (pi_cl_team_barrier)()

static inline void pi_cl_team_critical_enter(void)
{
    (void)cl_read(CL_EU_BASE, CL_EU_MUTEX_LOCK);
}

static inline void pi_cl_team_critical_exit(void)
{
    cl_write(CL_EU_BASE, CL_EU_MUTEX_UNLOCK, 0);
}

/* ---- Cluster DMA (cluster side) --------------------------------------- */

typedef enum {
    PI_CL_DMA_DIR_LOC2EXT = 0, /* L1 -> L2 (gap_sdk's values) */
    PI_CL_DMA_DIR_EXT2LOC = 1, /* L2 -> L1 */
} pi_cl_dma_dir_e;

typedef struct pi_cl_dma_cmd_s {
    int id;
} pi_cl_dma_cmd_t;

typedef struct pi_cl_dma_copy_s {
    uint32_t ext;
    uint32_t loc;
    uint32_t id;
    uint32_t size;
    pi_cl_dma_dir_e dir;
    uint8_t merge; /* accepted and ignored: every command has its own id */
    uint32_t stride;
    uint32_t length;
} pi_cl_dma_copy_t;

typedef pi_cl_dma_copy_t pi_cl_dma_copy_2d_t;

void pi_cl_dma_cmd(uint32_t ext, uint32_t loc, uint32_t size, pi_cl_dma_dir_e dir,
                   pi_cl_dma_cmd_t *cmd);
/* 2D: on the L2 side `length` bytes every `stride` bytes, packed in L1. */
void pi_cl_dma_cmd_2d(uint32_t ext, uint32_t loc, uint32_t size, uint32_t stride,
                      uint32_t length, pi_cl_dma_dir_e dir, pi_cl_dma_cmd_t *cmd);
/* Sleeps (clock-gated) until the command completed. */
void pi_cl_dma_cmd_wait(pi_cl_dma_cmd_t *cmd);
void pi_cl_dma_memcpy(pi_cl_dma_copy_t *copy);
void pi_cl_dma_memcpy_2d(pi_cl_dma_copy_2d_t *copy);
void pi_cl_dma_wait(void *copy);

/* ---- Memory ----------------------------------------------------------- */

/* L1 (64 KiB TCDM) of an opened cluster: first fit, 8-byte aligned;
 * NULL when no free block is large enough. From the FC, or from a cluster
 * core (then under the team's mutex); not from both at once. */
void *pi_l1_malloc(struct pi_device *device, uint32_t size);
void pi_l1_free(struct pi_device *device, void *chunk, uint32_t size);
/* L2 (FC side): picolibc's heap; NULL when exhausted. */
void *pi_l2_malloc(uint32_t size);
void pi_l2_free(void *chunk, uint32_t size);
/* gap_sdk's cluster-side spellings of the L1 allocator. */
#define pi_cl_l1_malloc pi_l1_malloc
#define pi_cl_l1_free pi_l1_free

/* ---- External RAM (FC side; gap_sdk pmsis_bsp bsp/ram.h) -------------- */

/* The AI deck's HyperRAM (L3) behind the µDMA: transfers between it and L2,
 * queued by the FC and carried while the FC and the cluster run. The
 * synchronous calls return when the bytes have moved; an _async call
 * returns at once and its task completes (pi_task_wait_on) when they have.
 * Transfers complete in the order they were queued. */
struct pi_ram_conf {
    void *api; /* the SDK's driver table: unused, one RAM */
};

struct pi_hyperram_conf {
    struct pi_ram_conf ram;
    int skip_pads_config;
    int hyper_itf;
    int hyper_cs;
    int ram_start;
    int ram_size;
};

void pi_hyperram_conf_init(struct pi_hyperram_conf *conf);
/* 0, or -1 if already open. */
int32_t pi_ram_open(struct pi_device *device);
void pi_ram_close(struct pi_device *device);
void pi_ram_read(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size);
void pi_ram_write(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size);
void pi_ram_copy(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size,
                 int ext2loc);
void pi_ram_read_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                       uint32_t size, pi_task_t *task);
void pi_ram_write_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                        uint32_t size, pi_task_t *task);
void pi_ram_copy_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                       uint32_t size, int ext2loc, pi_task_t *task);

/* ---- Performance counters (per core) ---------------------------------- */

typedef enum {
    PI_PERF_ACTIVE_CYCLES = 0, /* mcycle: cycles the core was awake */
    PI_PERF_INSTR = 1,         /* minstret */
    PI_PERF_CYCLES = 16,       /* wall cycles of the core's clock */
} pi_perf_event_e;

void pi_perf_conf(unsigned events); /* mask of 1 << event */
void pi_perf_reset(void);
void pi_perf_start(void);
void pi_perf_stop(void);
unsigned int pi_perf_read(int event);

#endif
