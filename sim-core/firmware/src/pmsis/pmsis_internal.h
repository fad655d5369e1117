/* What the runtime's files share (not for programs). */
#ifndef PMSIS_INTERNAL_H
#define PMSIS_INTERNAL_H

#include "pmsis.h"

/* A first-fit allocator over one region, PMSIS style: the caller gives the
 * size back at free, so blocks carry no header; the free list lives in the
 * free blocks themselves (8-byte units). */
struct pi_alloc_block {
    uint32_t size;
    struct pi_alloc_block *next;
};

struct pi_alloc {
    struct pi_alloc_block *first;
};

void __pi_alloc_init(struct pi_alloc *a, void *base, uint32_t size);
void *__pi_alloc(struct pi_alloc *a, uint32_t size);
void __pi_alloc_free(struct pi_alloc *a, void *chunk, uint32_t size);

/* Shared by the FC's open and the cluster cores' boot (cl_boot.S). */
extern uint32_t __pi_cl_stack_top[CL_MAX_CORES];
extern void *__pi_cl_tls[CL_MAX_CORES];
extern volatile uint32_t __pi_cl_nb_cores;
/* The task core 0 runs (its nb_cores is the default team). */
extern struct pi_cluster_task *volatile __pi_cl_current_task;

void __pi_cl_boot(void);
void __pi_cl_main(uint32_t core) __attribute__((noreturn));

/* Prints "pmsis: <what>" on stderr and exits with status 1. */
void __pi_fatal(const char *what) __attribute__((noreturn));

#endif
