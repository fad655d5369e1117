/*
 * Driver for the platform's two radios (DESIGN.md §8, docs/SWARM.md §4.3):
 * one shape for the DW1000 (uwb) and the nRF51 P2P radio, as the Bitcraze
 * deck drivers share one (init / send / receive by polling or interrupt /
 * timestamps). Header-only: every function is small and static inline.
 *
 *   radio_t uwb = RADIO_UWB;
 *   radio_init(&uwb);                 claims the world if nobody has
 *   radio_rx_on(&uwb);
 *   radio_send(&uwb, buf, len);       then radio_wait(&uwb, RADIO_TX_DONE, ...)
 *   radio_send_delayed(&uwb, buf, len, ns)  the frame leaves ns after the call
 *   radio_tx_stamp(&uwb);             40-bit DW1000 stamp of that frame
 *   radio_recv(&uwb, &frame);         1 if a frame was taken from RX_BUF
 *
 * Waiting uses wfi: the radio's IRQ_MASK raises mip.MEIP, the machine timer
 * bounds the wait; with mstatus.MIE clear no handler runs (wfi wakes on a
 * pending enabled interrupt either way), so the core sleeps until a frame
 * is delivered, at exactly that simulated time.
 */
#ifndef RADIO_RADIO_H
#define RADIO_RADIO_H

#include <stdint.h>
#include <string.h>

#include "../cosim_regs.h"

typedef struct {
    uint32_t base; /* window offset: UWB_BASE_OFFSET or P2P_BASE_OFFSET */
    uint8_t max_payload;
} radio_t;

#define RADIO_UWB ((radio_t){UWB_BASE_OFFSET, UWB_MAX_PAYLOAD})
#define RADIO_P2P ((radio_t){P2P_BASE_OFFSET, P2P_MAX_PAYLOAD})

/* A received frame. */
typedef struct {
    uint8_t len;
    uint8_t data[RADIO_BUF_SIZE];
    uint64_t stamp; /* 40-bit DW1000 stamp (uwb), 0 (p2p) */
    int32_t rssi_centi_dbm;
} radio_frame_t;

/* The DW1000's stamps are 40 bits wide: intervals are taken modulo 2^40. */
#define DW1000_STAMP_MASK ((1ull << 40) - 1)
static inline uint64_t dw1000_interval(uint64_t later, uint64_t earlier)
{
    return (later - earlier) & DW1000_STAMP_MASK;
}

#define RADIO_REG8(r, off) REG8((r)->base + (off))

static inline uint64_t radio_reg64(const radio_t *r, uint32_t off)
{
    uint32_t lo = REG32(r->base + off);
    uint32_t hi = REG32(r->base + off + 4);
    return ((uint64_t)hi << 32) | lo;
}

/* The machine timer (CLINT, counts core cycles). */
#define CLINT_MTIME_LO (*(volatile uint32_t *)0x0200bff8)
#define CLINT_MTIME_HI (*(volatile uint32_t *)0x0200bffc)
#define CLINT_MTIMECMP_LO (*(volatile uint32_t *)0x02004000)
#define CLINT_MTIMECMP_HI (*(volatile uint32_t *)0x02004004)

static inline uint64_t radio_now_cycles(void)
{
    uint32_t hi, lo;
    do {
        hi = CLINT_MTIME_HI;
        lo = CLINT_MTIME_LO;
    } while (hi != CLINT_MTIME_HI);
    return ((uint64_t)hi << 32) | lo;
}

static inline void radio_set_timer(uint64_t at)
{
    CLINT_MTIMECMP_HI = 0xffffffffu; /* no spurious interrupt meanwhile */
    CLINT_MTIMECMP_LO = (uint32_t)at;
    CLINT_MTIMECMP_HI = (uint32_t)(at >> 32);
}

static inline uint64_t radio_eui(const radio_t *r)
{
    return radio_reg64(r, RADIO_EUI_OFFSET);
}

static inline uint8_t radio_status(const radio_t *r)
{
    return RADIO_REG8(r, RADIO_STATUS_OFFSET);
}

static inline void radio_clear(const radio_t *r, uint8_t bits)
{
    RADIO_REG8(r, RADIO_STATUS_OFFSET) = bits;
}

/* Sleeps until one of `bits` is set in STATUS or the core's cycle counter
 * passes `deadline` (mtime). Returns the STATUS bits found (0: timeout). */
static inline uint8_t radio_wait(const radio_t *r, uint8_t bits, uint64_t deadline)
{
    RADIO_REG8(r, RADIO_IRQ_MASK_OFFSET) = bits;
    radio_set_timer(deadline);
    __asm__ volatile("csrs mie, %0" ::"r"((1u << 11) | (1u << 7)));
    uint8_t s;
    while ((s = radio_status(r) & bits) == 0 && radio_now_cycles() < deadline)
        __asm__ volatile("wfi");
    __asm__ volatile("csrc mie, %0" ::"r"((1u << 11) | (1u << 7)));
    RADIO_REG8(r, RADIO_IRQ_MASK_OFFSET) = 0;
    return s;
}

/* Switches the radio on (and claims the world if no device has: the first
 * INIT_DONE comes after the world's 2000 ms start-up alignment). Returns 0,
 * or -1 if INIT_DONE never came. */
static inline int radio_init(const radio_t *r)
{
    RADIO_REG8(r, RADIO_CTRL_OFFSET) = RADIO_INIT;
    /* Polled: the platform skips this loop up to INIT_DONE exactly. */
    while ((radio_status(r) & RADIO_INIT_DONE) == 0)
        ;
    radio_clear(r, RADIO_INIT_DONE);
    return 0;
}

static inline void radio_rx_on(const radio_t *r)
{
    RADIO_REG8(r, RADIO_CTRL_OFFSET) = RADIO_RX_ON;
}

static inline void radio_rx_off(const radio_t *r)
{
    RADIO_REG8(r, RADIO_CTRL_OFFSET) = RADIO_RX_OFF;
}

/* Starts a transmission of `len` bytes (1..max_payload). TX_DONE follows
 * when the frame has left; clear it before waiting for the next. */
static inline void radio_send(const radio_t *r, const void *data, uint8_t len)
{
    const uint8_t *p = data;
    for (uint8_t i = 0; i < len; i++)
        RADIO_REG8(r, RADIO_TX_BUF_OFFSET + i) = p[i];
    RADIO_REG8(r, RADIO_TX_LEN_OFFSET) = len;
    radio_clear(r, RADIO_TX_DONE);
    RADIO_REG8(r, RADIO_CTRL_OFFSET) = RADIO_TX_START;
}

/* Starts a transmission that leaves `delay_ns` after its TX_START (the
 * DW1000's delayed send, DX_TIME + SYS_CTRL.TXDLYS; docs/SWARM.md §4.3),
 * i.e. about delay_ns + the time to fill TX_BUF after this call; the radio
 * is busy from the TX_START to the frame's end; TX_DONE as radio_send. */
static inline void radio_send_delayed(const radio_t *r, const void *data, uint8_t len,
                                      uint32_t delay_ns)
{
    for (uint32_t i = 0; i < 4; i++)
        RADIO_REG8(r, RADIO_TX_DELAY_OFFSET + i) = (uint8_t)(delay_ns >> (8 * i));
    radio_send(r, data, len);
}

/* The stamp of the last finished transmission (uwb). */
static inline uint64_t radio_tx_stamp(const radio_t *r)
{
    return radio_reg64(r, RADIO_TX_STAMP_OFFSET);
}

/* Takes the frame in RX_BUF if there is one (and moves the next in). */
static inline int radio_recv(const radio_t *r, radio_frame_t *f)
{
    if ((radio_status(r) & RADIO_RX_DONE) == 0)
        return 0;
    f->len = RADIO_REG8(r, RADIO_RX_LEN_OFFSET);
    for (uint8_t i = 0; i < f->len; i++)
        f->data[i] = RADIO_REG8(r, RADIO_RX_BUF_OFFSET + i);
    f->stamp = radio_reg64(r, RADIO_RX_STAMP_OFFSET);
    f->rssi_centi_dbm = (int32_t)REG32(r->base + RADIO_RX_RSSI_OFFSET);
    radio_clear(r, RADIO_RX_DONE);
    return 1;
}

static inline uint32_t radio_rx_lost(const radio_t *r)
{
    return REG32(r->base + RADIO_RX_LOST_OFFSET);
}

#endif
