/*
 * The allocators: L1 (a first-fit free list over the cluster's TCDM, set up
 * when the cluster is opened) and L2 (picolibc's heap). First fit with the
 * size given back at free is PMSIS's own scheme (gap_sdk rt_alloc), which
 * keeps no header in front of a block: a 64-byte request takes 64 bytes.
 */
#include <stdlib.h>

#include "pmsis_internal.h"

#define ALIGN 8u

static uint32_t round_up(uint32_t size)
{
    return (size + ALIGN - 1) & ~(ALIGN - 1);
}

void __pi_alloc_init(struct pi_alloc *a, void *base, uint32_t size)
{
    struct pi_alloc_block *b = base;
    size &= ~(ALIGN - 1);
    a->first = NULL;
    if (size == 0)
        return;
    b->size = size;
    b->next = NULL;
    a->first = b;
}

void *__pi_alloc(struct pi_alloc *a, uint32_t size)
{
    if (size == 0 || size > 0x7fffffffu)
        return NULL;
    size = round_up(size);
    struct pi_alloc_block **link = &a->first;
    for (struct pi_alloc_block *b = *link; b; link = &b->next, b = b->next) {
        if (b->size < size)
            continue;
        if (b->size == size) {
            *link = b->next;
        } else {
            /* Keep the front free (its link stays valid), hand out the end. */
            b->size -= size;
            return (char *)b + b->size;
        }
        return b;
    }
    return NULL;
}

void __pi_alloc_free(struct pi_alloc *a, void *chunk, uint32_t size)
{
    if (!chunk || size == 0)
        return;
    size = round_up(size);
    struct pi_alloc_block *c = chunk;
    struct pi_alloc_block *prev = NULL, *next = a->first;
    /* The list is sorted by address, so neighbours merge. */
    while (next && (char *)next < (char *)c) {
        prev = next;
        next = next->next;
    }
    c->size = size;
    c->next = next;
    if (next && (char *)c + c->size == (char *)next) {
        c->size += next->size;
        c->next = next->next;
    }
    if (prev && (char *)prev + prev->size == (char *)c) {
        prev->size += c->size;
        prev->next = c->next;
    } else if (prev) {
        prev->next = c;
    } else {
        a->first = c;
    }
}

/* The L1 heap of the (only) cluster; cluster.c initialises it at open. */
extern struct pi_alloc __pi_l1_heap;

void *pi_l1_malloc(struct pi_device *device, uint32_t size)
{
    if (!device || !device->data)
        return NULL;
    int locked = !pi_is_fc();
    if (locked)
        pi_cl_team_critical_enter();
    void *p = __pi_alloc(&__pi_l1_heap, size);
    if (locked)
        pi_cl_team_critical_exit();
    return p;
}

void pi_l1_free(struct pi_device *device, void *chunk, uint32_t size)
{
    if (!device || !device->data)
        return;
    int locked = !pi_is_fc();
    if (locked)
        pi_cl_team_critical_enter();
    __pi_alloc_free(&__pi_l1_heap, chunk, size);
    if (locked)
        pi_cl_team_critical_exit();
}

void *pi_l2_malloc(uint32_t size)
{
    return size ? malloc(size) : NULL;
}

void pi_l2_free(void *chunk, uint32_t size)
{
    (void)size;
    free(chunk);
}
