/* The core's mcycle CSR as 64 bits (awake cycles: it stops during wfi,
 * docs/SWARM_FIRMWARE.md §4). The high half is read again so a carry
 * between the two reads is never missed. */
#ifndef CYCLES_H
#define CYCLES_H

#include <stdint.h>

static inline uint64_t csr_mcycle64(void)
{
    uint32_t hi, lo, hi2;
    do {
        __asm__ volatile("csrr %0, mcycleh" : "=r"(hi));
        __asm__ volatile("csrr %0, mcycle" : "=r"(lo));
        __asm__ volatile("csrr %0, mcycleh" : "=r"(hi2));
    } while (hi != hi2);
    return (uint64_t)hi << 32 | lo;
}

#endif
