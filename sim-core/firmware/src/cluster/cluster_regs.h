/* The cluster's registers (docs/CLUSTER.md, DESIGN.md §12), for the
 * hardware tests; programs use pmsis.h instead. */
#ifndef CLUSTER_REGS_H
#define CLUSTER_REGS_H
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))

/* The map itself is the runtime's (one copy): these are its offsets as
 * lvalues, the short names the hardware tests were written with. */
#include "../pmsis/cluster_regs.h"

#define L1_BASE CL_L1_BASE
#define CTRL_BASE CL_CTRL_BASE
#define EU_BASE CL_EU_BASE
#define DMA_BASE CL_DMA_BASE

#define CTRL_POWER REG(CL_CTRL_BASE + CL_CTRL_POWER)
#define CTRL_NB_CORES REG(CL_CTRL_BASE + CL_CTRL_NB_CORES)
#define CTRL_FREQ_HZ REG(CL_CTRL_BASE + CL_CTRL_FREQ_HZ)
#define CTRL_BOOT_ADDR REG(CL_CTRL_BASE + CL_CTRL_BOOT_ADDR)
#define CTRL_FETCH_EN REG(CL_CTRL_BASE + CL_CTRL_FETCH_EN)
#define CTRL_RUNNING REG(CL_CTRL_BASE + CL_CTRL_RUNNING)
#define CTRL_FC_EVENT REG(CL_CTRL_BASE + CL_CTRL_FC_EVENT)
#define CTRL_HALT REG(CL_CTRL_BASE + CL_CTRL_HALT)
#define CTRL_MAILBOX REG(CL_CTRL_BASE + CL_CTRL_MAILBOX)

#define EU_EVT_MASK REG(CL_EU_BASE + CL_EU_EVT_MASK)
#define EU_EVT_BUFFER REG(CL_EU_BASE + CL_EU_EVT_BUFFER)
#define EU_EVT_WAIT REG(CL_EU_BASE + CL_EU_EVT_WAIT)
#define EU_EVT_WAIT_CLR REG(CL_EU_BASE + CL_EU_EVT_WAIT_CLR)
#define EU_EVT_CLEAR REG(CL_EU_BASE + CL_EU_EVT_CLEAR)
#define EU_CORE_ID REG(CL_EU_BASE + CL_EU_CORE_ID)
#define EU_SW_EVT_TRIG(e) REG(CL_EU_BASE + CL_EU_SW_EVT_TRIG(e))
#define EU_BARRIER_SETUP REG(CL_EU_BASE + CL_EU_BARRIER_SETUP)
#define EU_BARRIER_WAIT REG(CL_EU_BASE + CL_EU_BARRIER_WAIT)
#define EU_MUTEX_LOCK REG(CL_EU_BASE + CL_EU_MUTEX_LOCK)
#define EU_MUTEX_UNLOCK REG(CL_EU_BASE + CL_EU_MUTEX_UNLOCK)
#define EU_TEAM_CONFIG REG(CL_EU_BASE + CL_EU_TEAM_CONFIG)
#define EU_DISPATCH_PUSH REG(CL_EU_BASE + CL_EU_DISPATCH_PUSH)
#define EU_DISPATCH_POP REG(CL_EU_BASE + CL_EU_DISPATCH_POP)

#define DMA_EXT REG(CL_DMA_BASE + CL_DMA_EXT)
#define DMA_LOC REG(CL_DMA_BASE + CL_DMA_LOC)
#define DMA_SIZE REG(CL_DMA_BASE + CL_DMA_SIZE)
#define DMA_STRIDE REG(CL_DMA_BASE + CL_DMA_STRIDE)
#define DMA_LENGTH REG(CL_DMA_BASE + CL_DMA_LENGTH)
#define DMA_CMD REG(CL_DMA_BASE + CL_DMA_CMD)
#define DMA_ID REG(CL_DMA_BASE + CL_DMA_ID)
#define DMA_STATUS REG(CL_DMA_BASE + CL_DMA_STATUS)

#define DMA_EXT2LOC 0u
#define DMA_LOC2EXT CL_DMA_CMD_LOC2EXT
#define DMA_2D CL_DMA_CMD_2D
#define EVT_DMA CL_EVT_DMA

static inline uint32_t hartid(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, mhartid" : "=r"(v));
    return v;
}

/* Absolute cluster cycle (mtime counts every cycle of the core's clock,
 * gated or not). */
static inline uint32_t now_cycles(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

static inline uint32_t mcycle(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, mcycle" : "=r"(v));
    return v;
}
#endif
