/*
 * Two drones range each other with the DW1000 (seed 003's ranging, DESIGN.md
 * §8): double-sided two-way ranging, N rounds, the distance printed each
 * round. Both drones run this same program (sim-core --drone A / --drone B,
 * run key radio_id = 1, 2).
 *
 *   1. Discovery: each drone listens, then beacons its EUI in a slot of its
 *      own (20 ms x (EUI mod 16 + 1) after its radio is up), so the two
 *      beacons never collide. The lower EUI initiates.
 *   2. A round: the initiator sends POLL, the responder RESPONSE, the
 *      initiator FINAL, then REPORT carrying its three stamps (poll sent,
 *      response received, final sent: it knows the last only once FINAL has
 *      left). The responder computes the time of flight with the asymmetric
 *      formula, ToF = (Ra*Rb - Da*Db) / (Ra + Rb + Da + Db), where Ra, Da are
 *      the initiator's round and reply times and Rb, Db the responder's
 *      (Decawave APS011; Neirynck et al. 2016), prints it, and sends the
 *      distance back in RESULT, which the initiator prints too.
 *
 * Intervals are taken on the 40-bit stamps modulo 2^40 (the DW1000's clock
 * wraps every 17.2 s). The numerator is computed exactly in 64-bit integers
 * as x*Rb + Db*y with x = Ra - Db and y = Rb - Da (both a few thousand ticks:
 * twice the flight time plus the clocks' drift over a reply), which equals
 * Ra*Rb - Da*Db without its 2^60-sized products; only the final division and
 * the conversion to metres are in (soft) floating point.
 *
 * Exit status: 0 after N rounds; 2 if the peer never answered (timeout); 3
 * if both drones have the same EUI (no initiator).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "../radio/radio.h"

#ifndef ROUNDS
#define ROUNDS 5
#endif
/* The core clock of the default platform (250 MHz): mtime counts cycles. */
#define CORE_HZ 250000000ull
#define MS (CORE_HZ / 1000)
#define BEACON_SLOT (20 * MS)
#define TIMEOUT (2000 * MS)

enum { BEACON = 0xB0, POLL = 1, RESPONSE = 2, FINAL = 3, REPORT = 4, RESULT = 5 };

/* Metres per DW1000 tick: c / (128 * 499.2 MHz). */
#define SPEED_OF_LIGHT 299792458.0
#define TICKS_PER_SECOND 63897600000.0

static radio_t uwb;
static radio_frame_t frame;

static void put40(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 5; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint64_t get40(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 0; i < 5; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static void fail(const char *what, int code)
{
    printf("[radio_ping] %s\n", what);
    fflush(stdout);
    _Exit(code);
}

/* Sends a frame and waits until it has left; returns its TX stamp. */
static uint64_t send_and_wait(const uint8_t *data, uint8_t len)
{
    radio_send(&uwb, data, len);
    if (!radio_wait(&uwb, RADIO_TX_DONE, radio_now_cycles() + TIMEOUT))
        fail("no TX_DONE", 2);
    radio_clear(&uwb, RADIO_TX_DONE);
    return radio_tx_stamp(&uwb);
}

/* Waits for a frame of `type` (and `seq`, unless negative) until `deadline`;
 * other frames are dropped. Returns 1 with the frame in `frame`. */
static int wait_for(uint8_t type, int seq, uint64_t deadline)
{
    for (;;) {
        while (radio_recv(&uwb, &frame)) {
            if (frame.len >= 2 && frame.data[0] == type && (seq < 0 || frame.data[1] == seq))
                return 1;
        }
        if (!radio_wait(&uwb, RADIO_RX_DONE, deadline))
            return 0;
    }
}

static void expect(uint8_t type, int seq)
{
    if (!wait_for(type, seq, radio_now_cycles() + TIMEOUT))
        fail("timeout: the peer did not answer", 2);
}

static uint64_t discover(uint64_t me)
{
    uint8_t beacon[10] = {BEACON, 0};
    for (int i = 0; i < 8; i++)
        beacon[2 + i] = (uint8_t)(me >> (8 * i));
    uint64_t peer = 0;
    int known = 0;
    uint64_t slot = radio_now_cycles() + BEACON_SLOT * ((me % 16) + 1);
    if (wait_for(BEACON, -1, slot))
        known = 1;
    send_and_wait(beacon, sizeof beacon);
    if (!known && !wait_for(BEACON, -1, radio_now_cycles() + TIMEOUT))
        fail("timeout: no beacon from a peer", 2);
    for (int i = 0; i < 8; i++)
        peer |= (uint64_t)frame.data[2 + i] << (8 * i);
    return peer;
}

static void print_distance(int round, int32_t mm)
{
    printf("[radio_ping] round %d: distance %ld.%03ld m\n", round, (long)(mm / 1000),
           (long)(mm % 1000));
}

static void initiator(void)
{
    uint8_t msg[17];
    for (int k = 0; k < ROUNDS; k++) {
        msg[0] = POLL;
        msg[1] = (uint8_t)k;
        uint64_t poll_tx = send_and_wait(msg, 2);
        expect(RESPONSE, k);
        uint64_t resp_rx = frame.stamp;
        msg[0] = FINAL;
        uint64_t final_tx = send_and_wait(msg, 2);
        msg[0] = REPORT;
        put40(msg + 2, poll_tx);
        put40(msg + 7, resp_rx);
        put40(msg + 12, final_tx);
        send_and_wait(msg, 17);
        expect(RESULT, k);
        int32_t mm = (int32_t)((uint32_t)frame.data[2] | (uint32_t)frame.data[3] << 8 |
                               (uint32_t)frame.data[4] << 16 | (uint32_t)frame.data[5] << 24);
        print_distance(k, mm);
    }
}

static void responder(void)
{
    uint8_t msg[6];
    for (int k = 0; k < ROUNDS; k++) {
        expect(POLL, k);
        uint64_t poll_rx = frame.stamp;
        msg[0] = RESPONSE;
        msg[1] = (uint8_t)k;
        uint64_t resp_tx = send_and_wait(msg, 2);
        expect(FINAL, k);
        uint64_t final_rx = frame.stamp;
        expect(REPORT, k);
        uint64_t poll_tx = get40(frame.data + 2);
        uint64_t resp_rx = get40(frame.data + 7);
        uint64_t final_tx = get40(frame.data + 12);

        int64_t ra = (int64_t)dw1000_interval(resp_rx, poll_tx);
        int64_t da = (int64_t)dw1000_interval(final_tx, resp_rx);
        int64_t rb = (int64_t)dw1000_interval(final_rx, resp_tx);
        int64_t db = (int64_t)dw1000_interval(resp_tx, poll_rx);
        int64_t x = ra - db, y = rb - da;
        int64_t num = x * rb + db * y; /* = ra*rb - da*db, exactly */
        int64_t den = ra + rb + da + db;
        double tof = (double)num / (double)den; /* ticks */
        double metres = tof * SPEED_OF_LIGHT / TICKS_PER_SECOND;
        int32_t mm = (int32_t)(metres * 1000.0 + (metres >= 0 ? 0.5 : -0.5));
        print_distance(k, mm);

        msg[0] = RESULT;
        for (int i = 0; i < 4; i++)
            msg[2 + i] = (uint8_t)((uint32_t)mm >> (8 * i));
        send_and_wait(msg, 6);
    }
}

int main(void)
{
    uwb = RADIO_UWB;
    radio_init(&uwb);
    radio_rx_on(&uwb);
    uint64_t me = radio_eui(&uwb);
    uint64_t peer = discover(me);
    if (peer == me)
        fail("both drones have the same EUI (set radio_id)", 3);
    int initiating = me < peer;
    printf("[radio_ping] EUI %lu, peer %lu: %s\n", (unsigned long)me, (unsigned long)peer,
           initiating ? "initiator" : "responder");
    if (initiating)
        initiator();
    else
        responder();
    printf("[radio_ping] %d rounds done, %lu frames lost\n", ROUNDS,
           (unsigned long)radio_rx_lost(&uwb));
    return 0;
}
