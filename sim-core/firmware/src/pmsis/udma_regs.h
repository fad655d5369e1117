/*
 * The µDMA's HyperRAM channel as the simulator maps it (sim-core's
 * peripherals/hyperram.rs): the AI deck's 8 MiB HyperRAM (L3), which no
 * core addresses, reached by L2 <-> L3 transfers the FC queues. The base
 * is GAP8's µDMA (SoC peripherals at 0x1A10_0000, µDMA at +0x2000); the
 * offsets are the model's own, not GAP8's channel layout. Only the
 * runtime (ram.c) uses these; programs go through pmsis.h's pi_ram_*.
 */
#ifndef PMSIS_UDMA_REGS_H
#define PMSIS_UDMA_REGS_H

#include <stdint.h>

#define UDMA_HYPER_BASE 0x1a102000u

#define UDMA_HYPER_L2_ADDR 0x00 /* L2 side of the next transfer */
#define UDMA_HYPER_L3_ADDR 0x04 /* HyperRAM side, 0 .. 8 MiB */
#define UDMA_HYPER_SIZE 0x08    /* bytes */
/* Write: queues the transfer staged in the three registers above; they
 * run one after another (sim-core's peripherals/hyperram.rs). */
#define UDMA_HYPER_CMD 0x0C
#define UDMA_HYPER_DONE 0x10   /* read: transfers completed since reset */
#define UDMA_HYPER_ISSUED 0x14 /* read: transfers queued since reset */

#define UDMA_HYPER_CMD_READ 1u  /* L3 -> L2 */
#define UDMA_HYPER_CMD_WRITE 2u /* L2 -> L3 */

/* The HyperRAM: Cypress S27KS0642, 64 Mbit. */
#define UDMA_HYPER_RAM_BYTES (8u << 20)

static inline uint32_t udma_hyper_read(uint32_t off)
{
    return *(volatile uint32_t *)(UDMA_HYPER_BASE + off);
}

static inline void udma_hyper_write(uint32_t off, uint32_t v)
{
    *(volatile uint32_t *)(UDMA_HYPER_BASE + off) = v;
}

/* Transfers complete in queue order, so a transfer is done once DONE has
 * reached the ISSUED count read after its CMD (its ticket). The counts
 * wrap at 2^32: compared by their difference. */
static inline int udma_hyper_done(uint32_t ticket)
{
    return (int32_t)(udma_hyper_read(UDMA_HYPER_DONE) - ticket) >= 0;
}

#endif
