/*
 * The cluster's registers as docs/CLUSTER.md maps them (our map, after the
 * GAP8's cluster control unit, event unit and MCHAN DMA; gap_sdk
 * archi/chips/gap/memory_map.h). Only the runtime uses these; programs go
 * through pmsis.h.
 */
#ifndef PMSIS_CLUSTER_REGS_H
#define PMSIS_CLUSTER_REGS_H

#include <stdint.h>

#define CL_L1_BASE 0x10000000u
#define CL_L1_SIZE (64u * 1024u)
#define CL_CTRL_BASE 0x10200000u
#define CL_EU_BASE 0x10200400u
#define CL_DMA_BASE 0x10200800u

/* CTRL: cluster control unit. */
#define CL_CTRL_POWER 0x00
#define CL_CTRL_NB_CORES 0x04
#define CL_CTRL_FREQ_HZ 0x08
#define CL_CTRL_BOOT_ADDR 0x0C
#define CL_CTRL_FETCH_EN 0x10
#define CL_CTRL_RUNNING 0x14
#define CL_CTRL_FC_EVENT 0x18
#define CL_CTRL_HALT 0x1C
#define CL_CTRL_MAILBOX 0x20
#define CL_CTRL_FC_IRQ 0x24

/* EU: event unit, the accessing core's view. */
#define CL_EU_EVT_MASK 0x00
#define CL_EU_EVT_BUFFER 0x04
#define CL_EU_EVT_WAIT 0x08
#define CL_EU_EVT_WAIT_CLR 0x0C
#define CL_EU_EVT_CLEAR 0x10
#define CL_EU_CORE_ID 0x14
#define CL_EU_SW_EVT_TRIG(e) (0x40 + 4 * (e))
#define CL_EU_BARRIER_SETUP 0x80
#define CL_EU_BARRIER_WAIT 0x84
#define CL_EU_MUTEX_LOCK 0x88
#define CL_EU_MUTEX_UNLOCK 0x8C
#define CL_EU_TEAM_CONFIG 0x90
#define CL_EU_DISPATCH_PUSH 0x94
#define CL_EU_DISPATCH_POP 0x98
/* Event bit 8: a DMA command this core enqueued completed. */
#define CL_EVT_DMA 8
/* Event bit 9 (core 0): the FC wrote a task to CTRL's MAILBOX. */
#define CL_EVT_MAILBOX 9

/* DMA: this core's staging registers and the shared queue. */
#define CL_DMA_EXT 0x00
#define CL_DMA_LOC 0x04
#define CL_DMA_SIZE 0x08
#define CL_DMA_STRIDE 0x0C
#define CL_DMA_LENGTH 0x10
#define CL_DMA_CMD 0x14
#define CL_DMA_ID 0x18
#define CL_DMA_STATUS 0x1C
#define CL_DMA_CMD_LOC2EXT 1u /* bit 0: 0 = L2 -> L1, 1 = L1 -> L2 */
#define CL_DMA_CMD_2D 2u

/* mhartid = cluster id << 5 | core id; the FC's cluster id is gap_sdk's
 * ARCHI_FC_CID. */
#define CL_FC_CLUSTER_ID 32u
#define CL_MAX_CORES 8u

static inline uint32_t cl_read(uint32_t base, uint32_t off)
{
    return *(volatile uint32_t *)(base + off);
}

static inline void cl_write(uint32_t base, uint32_t off, uint32_t v)
{
    *(volatile uint32_t *)(base + off) = v;
}

#endif
