/*
 * Seed 004's radar on a drone flown over CRTP (§4.3.1, §4.3.2.A;
 * docs/LAB.md): the firmware of crtp_host.c plus the seed's modified
 * firmware's P2P side, which on a real Crazyflie runs on the nRF51 beside
 * the CRTP link. While the STM32 serves cflib (EXT_CRTP) this core
 *
 * - broadcasts a beacon (its radio id) every radar_period_ms (100 ms: the
 *   Radar reads every 100 ms, §4.3.2.A) while cflib has set the
 *   `radar.enable` parameter ("if this flag was set by the host, a packet
 *   is broadcasted", §4.3.1), in a phase by its id so that drones do not
 *   all send at once, each period drawn within ±1/4 of it: free-running
 *   radios do not keep a fixed order, and with one the register's "last
 *   sender", read by the log at the beacons' own period, named the same
 *   neighbour at every read and never a nearer one beaconing just before
 *   it (a guide 3 collision);
 * - hears every beacon and keeps the last sender's id and RSSI in the
 *   STM32's P2P_ID and P2P_RSSI (the `radar.id` and `radar.rssi` log
 *   variables): "these variables will be overridden every time a new drone
 *   is detected", cleared after radar_timeout_ms (3 s, §4.3.1) without a
 *   beacon.
 *
 * Between packets it sleeps (radio_wait), so the core's energy is the
 * radio's and an idle core's.
 */
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../radio/radio.h"
#include "../stm32.h"

volatile int32_t radar_period_ms = 100;   /* §4.3.2.A */
volatile int32_t radar_timeout_ms = 3000; /* §4.3.1: 3 s without a P2P message */
volatile int32_t radar_core_hz = 250000000;

/* xorshift32 (Marsaglia 2003), seeded by the drone's id: the beacons'
 * periods, the same in every run of a scenario. */
static uint32_t rng_state;

static uint32_t rng_next(void)
{
    uint32_t x = rng_state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return rng_state = x;
}

enum { PKT_BEACON = 0xA5 };

#define P2P_ENABLE REG32(STM32_P2P_ENABLE_OFFSET)
#define P2P_SELF REG32(STM32_P2P_SELF_OFFSET)
#define P2P_ID REG32(STM32_P2P_ID_OFFSET)
#define P2P_RSSI REG32(STM32_P2P_RSSI_OFFSET)

static uint64_t ms_cycles(uint32_t ms)
{
    return (uint64_t)ms * (uint64_t)(radar_core_hz / 1000);
}

int main(void)
{
    radio_t p2p = RADIO_P2P;
    stm32_perform(INIT_PID);
    radio_init(&p2p);
    radio_rx_on(&p2p);
    uint32_t id = (uint32_t)radio_eui(&p2p);
    P2P_SELF = id;
    printf("[crtp] serving the CRTP link, radar id %lu\n", (unsigned long)id);
    stm32_ext_ctrl = EXT_CRTP;

    uint64_t period = ms_cycles((uint32_t)radar_period_ms);
    /* Phases 0, 1/2, 1/4, 3/4 of the period by id (radar.c's phase_ms). */
    uint32_t k = id > 0 ? id - 1 : 0;
    uint64_t phase = ((k % 2) * period / 2 + ((k / 2) % 2) * period / 4) % period;
    uint64_t next_tx = radio_now_cycles() + phase;
    rng_state = 0x9E3779B9u ^ id;
    if (rng_state == 0)
        rng_state = 1;
    uint64_t last_heard = 0;
    uint32_t heard = 0, sent = 0, received = 0;
    uint16_t seq = 0;
    uint32_t s;
    while ((s = stm32_ext_stat) == 0) {
        uint64_t now = radio_now_cycles();
        if (P2P_ENABLE && now >= next_tx) {
            if (REG8(p2p.base + RADIO_STATE_OFFSET) != RADIO_STATE_TX) {
                uint8_t pkt[4] = {PKT_BEACON, (uint8_t)id, (uint8_t)seq, (uint8_t)(seq >> 8)};
                radio_send(&p2p, pkt, sizeof pkt);
                seq++;
                sent++;
            }
            /* The next period: period ± period/4, uniform. */
            while (next_tx <= now)
                next_tx += period - period / 4 + (uint64_t)rng_next() % (period / 2 + 1);
        } else if (!P2P_ENABLE) {
            next_tx = now + phase;
        }
        radio_frame_t f;
        while (radio_recv(&p2p, &f)) {
            received++;
            if (f.len >= 2 && f.data[0] == PKT_BEACON && f.data[1] != 0) {
                heard = f.data[1];
                last_heard = radio_now_cycles();
                P2P_RSSI = (uint32_t)f.rssi_centi_dbm;
                P2P_ID = heard;
            }
        }
        if (heard && radio_now_cycles() - last_heard > ms_cycles((uint32_t)radar_timeout_ms)) {
            heard = 0;
            P2P_ID = 0;
            P2P_RSSI = 0;
        }
        /* Sleep until a frame, the next beacon or 10 ms (the STM32's
         * EXT_STAT and the parameter are looked at again then). */
        uint64_t wake = radio_now_cycles() + ms_cycles(10);
        if (P2P_ENABLE && next_tx < wake)
            wake = next_tx;
        radio_wait(&p2p, RADIO_RX_DONE, wake);
    }
    printf("[crtp] link closed, drone stopped; radar sent=%lu received=%lu lost=%lu\n",
           (unsigned long)sent, (unsigned long)received, (unsigned long)radio_rx_lost(&p2p));
    return s == EXT_CRTP ? 0 : 1;
}
