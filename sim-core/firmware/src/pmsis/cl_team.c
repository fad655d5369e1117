/*
 * The cluster cores' side: core 0, the master, takes tasks from the FC's
 * mailbox, asleep on the mailbox event between them; cores 1..N-1 wait on
 * the event unit's dispatch FIFO for the forks. A fork dispatches (entry,
 * arg) to the team, runs the master's share, then meets the team at the
 * barrier (docs/CLUSTER.md, EU).
 */
#include <picolibc.h> /* defines PICOLIBC_TLS, which picotls.h needs */
#include <picotls.h>

#include "pmsis_internal.h"

struct pi_cluster_task *volatile __pi_cl_current_task;
/* The size of the team of the fork under way, 0 outside a fork. Written by
 * core 0 before it dispatches, so the workers read it after their pop. */
static volatile int team_size;

static void __attribute__((noreturn)) master_loop(void)
{
    for (;;) {
        struct pi_cluster_task *task;
        /* Between tasks core 0 sleeps, clock-gated, until the FC's write to
         * MAILBOX raises the mailbox event (DESIGN.md §12: an idle core
         * costs no dynamic energy). A task sent while core 0 was busy left
         * the event in the buffer: the first wait returns at once, the
         * loop finds the mailbox empty and waits again. */
        while ((task = (struct pi_cluster_task *)cl_read(CL_CTRL_BASE, CL_CTRL_MAILBOX)) == 0)
            (void)cl_read(CL_EU_BASE, CL_EU_EVT_WAIT_CLR);
        cl_write(CL_CTRL_BASE, CL_CTRL_MAILBOX, 0); /* taken: the FC may send the next */
        __pi_cl_current_task = task;
        task->entry(task->arg);
        __pi_cl_current_task = NULL;
        cl_write(CL_CTRL_BASE, CL_CTRL_FC_EVENT, 1);
    }
}

static void __attribute__((noreturn)) worker_loop(void)
{
    for (;;) {
        /* Both pops sleep, clock-gated, until core 0 forks. */
        void (*entry)(void *) = (void (*)(void *))cl_read(CL_EU_BASE, CL_EU_DISPATCH_POP);
        void *arg = (void *)cl_read(CL_EU_BASE, CL_EU_DISPATCH_POP);
        entry(arg);
        pi_cl_team_barrier();
    }
}

void __pi_cl_main(uint32_t core)
{
    if (__pi_cl_tls[core]) {
        _init_tls(__pi_cl_tls[core]);
        _set_tls(__pi_cl_tls[core]);
    }
    /* The DMA's completions wake this core in pi_cl_dma_cmd_wait, and
     * core 0 also wakes on a task in the mailbox. Both waits look at their
     * condition again after a wake-up, so each tolerates the other's
     * event. */
    cl_write(CL_EU_BASE, CL_EU_EVT_MASK,
             1u << CL_EVT_DMA | (core == 0 ? 1u << CL_EVT_MAILBOX : 0));
    if (core == 0)
        master_loop();
    worker_loop();
}

void pi_cl_team_fork(int nb_cores, void (*entry)(void *), void *arg)
{
    if (pi_is_fc() || pi_core_id() != 0 || team_size != 0)
        __pi_fatal("pi_cl_team_fork: only core 0 forks, and not inside a fork");
    int all = (int)__pi_cl_nb_cores;
    struct pi_cluster_task *task = __pi_cl_current_task;
    if (nb_cores <= 0)
        nb_cores = task && task->nb_cores > 0 ? task->nb_cores : all;
    if (nb_cores > all)
        nb_cores = all;
    uint32_t team = (1u << nb_cores) - 1;
    team_size = nb_cores;
    cl_write(CL_EU_BASE, CL_EU_BARRIER_SETUP, team);
    if (nb_cores > 1) {
        cl_write(CL_EU_BASE, CL_EU_TEAM_CONFIG, team & ~1u);
        cl_write(CL_EU_BASE, CL_EU_DISPATCH_PUSH, (uint32_t)entry);
        cl_write(CL_EU_BASE, CL_EU_DISPATCH_PUSH, (uint32_t)arg);
    }
    entry(arg);
    pi_cl_team_barrier();
    team_size = 0;
}

int pi_cl_team_nb_cores(void)
{
    int n = team_size;
    return n ? n : (int)__pi_cl_nb_cores;
}
