/*
 * The FC's side of the cluster: open (power on, L1 heap, stacks, boot the
 * cores at __pi_cl_boot), tasks through CTRL.MAILBOX and their completion
 * through CTRL.FC_EVENT (docs/CLUSTER.md), close.
 */
#include <picolibc.h> /* defines PICOLIBC_TLS, which picotls.h needs */
#include <picotls.h>
#include <stdio.h>
#include <stdlib.h>

#include "pmsis_internal.h"
#include "udma_regs.h"

struct pi_alloc __pi_l1_heap;
uint32_t __pi_cl_stack_top[CL_MAX_CORES];
void *__pi_cl_tls[CL_MAX_CORES];
volatile uint32_t __pi_cl_nb_cores;

/* The cluster's state on the FC. Completions arrive in the order the tasks
 * were sent (core 0 runs them one after another), so the pending ones form
 * a FIFO. */
static struct cl_state {
    int opened;
    uint32_t master_stack, slave_stack;
    pi_task_t *pending_first, *pending_last;
    pi_task_t sync_done; /* pi_cluster_send_task_to_cl's own completion */
} cl;

void __pi_fatal(const char *what)
{
    fprintf(stderr, "pmsis: %s\n", what);
    exit(1);
}

void pi_cluster_conf_init(struct pi_cluster_conf *conf)
{
    conf->id = 0;
}

void pi_open_from_conf(struct pi_device *device, void *conf)
{
    device->config = conf;
    device->data = NULL;
}

static uint32_t align_up(uint32_t v, uint32_t a)
{
    return (v + a - 1) & ~(a - 1);
}

int pi_cluster_open(struct pi_device *device)
{
    struct pi_cluster_conf *conf = device->config;
    if (!pi_is_fc() || cl.opened || (conf && conf->id != 0))
        return -1;
    cl_write(CL_CTRL_BASE, CL_CTRL_POWER, 1);
    uint32_t n = cl_read(CL_CTRL_BASE, CL_CTRL_NB_CORES);
    if (n == 0 || n > CL_MAX_CORES) {
        cl_write(CL_CTRL_BASE, CL_CTRL_POWER, 0);
        return -1;
    }
    __pi_cl_nb_cores = n;
    __pi_alloc_init(&__pi_l1_heap, (void *)CL_L1_BASE, CL_L1_SIZE);
    device->data = &cl;

    /* Per core: a stack (core 0 the master's size) and picolibc's TLS block
     * (errno), both in L1 where the core reaches them in one cycle. */
    cl.master_stack = PI_CL_MASTER_STACK_SIZE;
    cl.slave_stack = PI_CL_SLAVE_STACK_SIZE;
    uint32_t tls = align_up(_tls_size(), 8);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t stack = i == 0 ? cl.master_stack : cl.slave_stack;
        char *s = pi_l1_malloc(device, stack);
        void *t = tls ? pi_l1_malloc(device, tls) : NULL;
        if (!s || (tls && !t))
            __pi_fatal("no L1 for the cluster's stacks");
        __pi_cl_stack_top[i] = (uint32_t)(s + stack);
        __pi_cl_tls[i] = t;
    }
    cl.pending_first = cl.pending_last = NULL;
    cl_write(CL_CTRL_BASE, CL_CTRL_MAILBOX, 0);
    (void)cl_read(CL_CTRL_BASE, CL_CTRL_FC_EVENT); /* clears stale events */
    /* Pending FC events drive the FC's external interrupt: the FC sleeps
     * in wfi while it waits for a task (pi_task_wait_on). */
    cl_write(CL_CTRL_BASE, CL_CTRL_FC_IRQ, 1);
    cl_write(CL_CTRL_BASE, CL_CTRL_BOOT_ADDR, (uint32_t)&__pi_cl_boot);
    cl_write(CL_CTRL_BASE, CL_CTRL_FETCH_EN, (1u << n) - 1);
    cl.opened = 1;
    return 0;
}

/* `events` FC events arrived: each completes the oldest pending task. */
static void complete(uint32_t events)
{
    for (; events; events--) {
        pi_task_t *t = cl.pending_first;
        if (!t)
            __pi_fatal("an FC event with no task in flight");
        cl.pending_first = t->next;
        if (!cl.pending_first)
            cl.pending_last = NULL;
        t->done = 1;
    }
}

pi_task_t *pi_task_block(pi_task_t *task)
{
    task->done = 0;
    task->next = NULL;
    task->ram_ticket = 0;
    return task;
}

void pi_task_wait_on(pi_task_t *task)
{
    if (task->ram_ticket) {
        /* A HyperRAM transfer (ram.c): done once the µDMA's DONE count
         * reaches its ticket. A polling loop: the ISS skips its idle
         * iterations. */
        while (!udma_hyper_done(task->ram_ticket))
            ;
        task->ram_ticket = 0;
        task->done = 1;
        return;
    }
    while (!task->done) {
        if (!cl.pending_first)
            __pi_fatal("waiting on a task that was never sent");
        /* Asleep, clock-gated, until core 0 posts: with FC_IRQ set a pending
         * FC event raises the FC's external interrupt, which ends a wfi.
         * Interrupts stay off (mstatus.MIE clear: wfi wakes on a pending
         * enabled interrupt without taking it), so a program's own
         * handlers never see the cluster's line. The read clears the count
         * it returns (docs/CLUSTER.md, FC_EVENT and FC_IRQ). */
        uint32_t mstatus, mie, events;
        __asm__ volatile("csrrc %0, mstatus, 8" : "=r"(mstatus));
        __asm__ volatile("csrrs %0, mie, %1" : "=r"(mie) : "r"(1u << 11));
        while ((events = cl_read(CL_CTRL_BASE, CL_CTRL_FC_EVENT)) == 0)
            __asm__ volatile("wfi");
        __asm__ volatile("csrw mie, %0" ::"r"(mie));
        __asm__ volatile("csrs mstatus, %0" ::"r"(mstatus & 8u));
        complete(events);
    }
}

int pi_cluster_send_task_to_cl_async(struct pi_device *device, struct pi_cluster_task *task,
                                     pi_task_t *done)
{
    if (!device || device->data != &cl || !cl.opened || !task || !task->entry || !done)
        return -1;
    if (task->stack_size > cl.master_stack || task->slave_stack_size > cl.slave_stack)
        return -1;
    done->done = 0;
    done->next = NULL;
    done->ram_ticket = 0;
    task->done = done;
    /* The mailbox holds one task: wait until core 0 took the previous. */
    while (cl_read(CL_CTRL_BASE, CL_CTRL_MAILBOX) != 0)
        ;
    if (cl.pending_last)
        cl.pending_last->next = done;
    else
        cl.pending_first = done;
    cl.pending_last = done;
    cl_write(CL_CTRL_BASE, CL_CTRL_MAILBOX, (uint32_t)task);
    return 0;
}

int pi_cluster_send_task_to_cl(struct pi_device *device, struct pi_cluster_task *task)
{
    if (pi_cluster_send_task_to_cl_async(device, task, pi_task_block(&cl.sync_done)) != 0)
        return -1;
    pi_task_wait_on(&cl.sync_done);
    return 0;
}

int pi_cluster_close(struct pi_device *device)
{
    if (!device || device->data != &cl || !cl.opened)
        return -1;
    while (cl.pending_last)
        pi_task_wait_on(cl.pending_last);
    cl_write(CL_CTRL_BASE, CL_CTRL_FC_IRQ, 0);
    cl_write(CL_CTRL_BASE, CL_CTRL_POWER, 0);
    cl.opened = 0;
    device->data = NULL;
    return 0;
}
