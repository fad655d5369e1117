/* The cluster's registers (docs/CLUSTER.md, DESIGN.md §12), for the
 * hardware tests; programs use pmsis.h instead. */
#ifndef CLUSTER_REGS_H
#define CLUSTER_REGS_H
#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))

#define L1_BASE 0x10000000u
#define CTRL_BASE 0x10200000u
#define EU_BASE 0x10200400u
#define DMA_BASE 0x10200800u

#define CTRL_POWER REG(CTRL_BASE + 0x00)
#define CTRL_NB_CORES REG(CTRL_BASE + 0x04)
#define CTRL_FREQ_HZ REG(CTRL_BASE + 0x08)
#define CTRL_BOOT_ADDR REG(CTRL_BASE + 0x0C)
#define CTRL_FETCH_EN REG(CTRL_BASE + 0x10)
#define CTRL_RUNNING REG(CTRL_BASE + 0x14)
#define CTRL_FC_EVENT REG(CTRL_BASE + 0x18)
#define CTRL_HALT REG(CTRL_BASE + 0x1C)
#define CTRL_MAILBOX REG(CTRL_BASE + 0x20)

#define EU_EVT_MASK REG(EU_BASE + 0x00)
#define EU_EVT_BUFFER REG(EU_BASE + 0x04)
#define EU_EVT_WAIT REG(EU_BASE + 0x08)
#define EU_EVT_WAIT_CLR REG(EU_BASE + 0x0C)
#define EU_EVT_CLEAR REG(EU_BASE + 0x10)
#define EU_CORE_ID REG(EU_BASE + 0x14)
#define EU_SW_EVT_TRIG(e) REG(EU_BASE + 0x40 + 4 * (e))
#define EU_BARRIER_SETUP REG(EU_BASE + 0x80)
#define EU_BARRIER_WAIT REG(EU_BASE + 0x84)
#define EU_MUTEX_LOCK REG(EU_BASE + 0x88)
#define EU_MUTEX_UNLOCK REG(EU_BASE + 0x8C)
#define EU_TEAM_CONFIG REG(EU_BASE + 0x90)
#define EU_DISPATCH_PUSH REG(EU_BASE + 0x94)
#define EU_DISPATCH_POP REG(EU_BASE + 0x98)

#define DMA_EXT REG(DMA_BASE + 0x00)
#define DMA_LOC REG(DMA_BASE + 0x04)
#define DMA_SIZE REG(DMA_BASE + 0x08)
#define DMA_STRIDE REG(DMA_BASE + 0x0C)
#define DMA_LENGTH REG(DMA_BASE + 0x10)
#define DMA_CMD REG(DMA_BASE + 0x14)
#define DMA_ID REG(DMA_BASE + 0x18)
#define DMA_STATUS REG(DMA_BASE + 0x1C)

#define DMA_EXT2LOC 0u
#define DMA_LOC2EXT 1u
#define DMA_2D 2u
#define EVT_DMA 8

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
