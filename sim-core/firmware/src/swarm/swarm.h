/*
 * One drone's side of seed 003's relative positioning (chapters 5-6): the
 * context of Appendix D (neighbour storage, TOF storage, identifier,
 * sequence numbers, transmission timing) and the processing of STATUS
 * packets, all statically allocated (§6.9.3): the caller owns a swarm_t.
 *
 * The boundary to the radio is thin (docs/SWARM_FIRMWARE.md §4):
 *   swarm_init(eui)                  once, with the radio's EUI register
 *   swarm_next_tx_delay_us()         when to transmit next (§6.5)
 *   swarm_build_status(buf)          the frame to transmit (TX_BUF/TX_LEN)
 *   swarm_tx_done(tx_stamp)          after TX_DONE, with TX_STAMP
 *   swarm_on_rx(buf, rx_stamp, rssi) for every received frame (RX_DONE)
 *   swarm_housekeeping(now)          e.g. at every 100 Hz output tick
 *   swarm_format_estimates(buf)      the 100 Hz output line
 * Times are a free-running microsecond counter of the caller (platform
 * time); stamps are the DW1000's 40-bit values.
 */
#ifndef SWARM_SWARM_H
#define SWARM_SWARM_H

#include <stddef.h>
#include <stdint.h>

#include "coords.h"
#include "kalman.h"
#include "prng.h"
#include "ranging.h"
#include "status_packet.h"

/* §6.9: the seed configures 16 tracked neighbours. */
#ifndef SWARM_MAX_NEIGHBOURS
#define SWARM_MAX_NEIGHBOURS 16
#endif
#if SWARM_MAX_NEIGHBOURS > 255
#error "identifiers are 8 bits (§6.2): at most 255 neighbours"
#endif
/* Nodes are the neighbour slots 0..N-1 and this drone, node N. */
#define SWARM_NODES (SWARM_MAX_NEIGHBOURS + 1)
#define SWARM_SELF SWARM_MAX_NEIGHBOURS
/* Eq. 6.13, with this drone counted among the nodes. */
#define SWARM_TOF_PAIRS (SWARM_NODES * (SWARM_NODES - 1) / 2)
/* Own transmit stamps kept to compute round times: 16 transmissions at the
 * highest rate (100 Hz, down to 5 ms apart in the window of §6.5) cover
 * 80 ms, more than the longest round of a swarm at 20 Hz. */
#define SWARM_TX_HISTORY 16

typedef struct {
    float meas_std;   /* σ of a distance (m), §7.3: 0.25 */
    float stable_std; /* a filter is used below this σ (m), §6.8.3: 0.25 */
    float init_std;   /* σ of a filter's start (m), §6.8.3 "maximum" */
    float pseudo_std; /* σ of the coordinate system's arbitrary values (m) */
    float frame_min_sep; /* a reference must be this far from the origin, the
                            X axis, the XY plane it completes (m) */
    swarm_kf_settings_t kf;
    swarm_clock_settings_t clock;
    int32_t antenna_delay;         /* ticks subtracted from each TOF, §6.4.2 */
    uint32_t neighbour_timeout_us; /* §6.9.3: 1 s without a packet */
    uint16_t swarm_rate_hz;        /* §6.5: 400 packets/s for the swarm */
    uint16_t min_rate_hz;          /* 20 */
    uint16_t max_rate_hz;          /* 100 */
    uint8_t planar;                /* 1: 2D (z = 0), as the thesis's table tests;
                                      SWARM_LINE: 1D (y = z = 0), §7.3's pair */
    uint8_t keep_frame;            /* keep the frame's arbitrary values after
                                      it is built (the seed drops them) */
} swarm_settings_t;

/* `planar` for the 1D experiment of §7.3 (two drones on a line). */
#define SWARM_LINE 2

void swarm_default_settings(swarm_settings_t *s);

typedef struct {
    uint8_t used;
    uint8_t id;
    uint8_t expected_seq; /* §6.3 */
    uint8_t have_last;    /* last accepted packet: */
    uint8_t last_seq;
    uint8_t have_report; /* what our next packet reports to it: */
    uint8_t report_seq;
    uint8_t have_pair; /* newest packet whose remote tx is known */
    uint32_t report_rx;
    uint32_t pair_tx;
    uint64_t last_rx;
    uint64_t pair_rx;
    swarm_clock_t clock;
    uint16_t order; /* detection order (§5.3.2) */
    uint32_t last_heard_us;
    int32_t rssi_cdbm;
    swarm_kf_t kf;
} swarm_neighbour_t;

typedef struct {
    uint32_t rx_ok, rx_short, rx_not_status, rx_bad_length, rx_reflection, rx_id_clash,
        rx_table_full;
    uint32_t tof_valid, tof_invalid, clock_accepted, clock_rejected;
    uint32_t tx_built, tx_done, removed;
} swarm_stats_t;

typedef struct {
    swarm_settings_t set;
    uint64_t eui;
    swarm_prng_t prng;
    uint8_t id;
    uint8_t next_seq;
    uint8_t have_built; /* a packet was built, with seq built_seq */
    uint8_t built_seq;
    uint8_t have_prev_tx; /* the stamp of our packet prev_tx_seq */
    uint8_t prev_tx_seq;
    uint8_t rotate; /* first neighbour slot of the next packet */
    uint8_t txh_next;
    uint16_t next_order;
    uint64_t prev_tx;
    struct {
        uint64_t stamp;
        uint8_t seq, valid;
    } txh[SWARM_TX_HISTORY];
    swarm_neighbour_t nb[SWARM_MAX_NEIGHBOURS];
    uint16_t tof[SWARM_TOF_PAIRS]; /* local ticks, 0: unknown (§5.3.1) */
    swarm_kf_t self_kf;
    int8_t ref[4]; /* the nodes defining the frame, in detection order */
    uint8_t nref;
    uint8_t building; /* §5.3.2: the frame is not complete yet */
    swarm_stats_t stats;
} swarm_t;

void swarm_init(swarm_t *s, const swarm_settings_t *set, uint64_t eui);

/* The identifier of §6.2 derived from the EUI (its bytes xor-folded: EUIs
 * 1, 2, 3 give identifiers 1, 2, 3). */
uint8_t swarm_id_from_eui(uint64_t eui);

/* Delay to the next transmission (§6.5): uniform in [T/2, 3T/2) with
 * T = 1/f, f = swarm_rate / (neighbours + 1) clamped to [min, max]. */
uint32_t swarm_next_tx_delay_us(swarm_t *s);

/* Build the next STATUS packet into buf (≥ SWARM_MAX_FRAME bytes for the
 * largest); returns its length (0 if cap is too small). */
size_t swarm_build_status(swarm_t *s, uint8_t *buf, size_t cap);

/* The packet last built has left: its 40-bit TX_STAMP. */
void swarm_tx_done(swarm_t *s, uint64_t tx_stamp);

enum {
    SWARM_RX_OK = 0,
    SWARM_RX_SHORT = -1,
    SWARM_RX_NOT_STATUS = -2,
    SWARM_RX_BAD_LENGTH = -3,
    SWARM_RX_REFLECTION = -4, /* duplicate sequence number (§6.3) */
    SWARM_RX_ID_CLASH = -5,   /* sender has our identifier: we took a new one */
    SWARM_RX_TABLE_FULL = -6, /* a new neighbour and no free slot */
};

/* One received frame with its 40-bit RX_STAMP and RSSI (1/100 dBm). */
int swarm_on_rx(swarm_t *s, const uint8_t *buf, size_t len, uint64_t rx_stamp, int32_t rssi_cdbm,
                uint32_t now_us);

/* Forget neighbours silent for longer than the timeout, with their TOFs
 * (§6.9.3 removeOutdatedData). A reference of the frame leaving restarts
 * the frame. */
void swarm_housekeeping(swarm_t *s, uint32_t now_us);

/* The node index of a neighbour identifier, or -1. */
int swarm_find(const swarm_t *s, uint8_t id);
unsigned swarm_neighbour_count(const swarm_t *s);
/* TOF between two nodes (local ticks; 0 unknown). */
uint16_t swarm_tof(const swarm_t *s, int a, int b);
/* The filter of a node (SWARM_SELF for this drone). */
const swarm_kf_t *swarm_filter(const swarm_t *s, int node);
/* Estimated position, 1 if the filter is stable (§6.8.3). */
int swarm_position(const swarm_t *s, int node, swarm_vec3_t *p);

/* The 100 Hz output line (docs/SWARM_FIRMWARE.md §5), '\n'-terminated;
 * returns its length (truncated to cap - 1 if needed). */
size_t swarm_format_estimates(const swarm_t *s, uint32_t now_ms, char *buf, size_t cap);

#endif
