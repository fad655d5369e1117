/*
 * Seed 004's drone-to-drone radar (§4.3.2.A, §5.3 Tables 7-8; docs/SWARM.md
 * "Radar"): every drone broadcasts a P2P packet (its id and a sequence
 * number) every 100 ms; a packet received with an RSSI above -48 dBm from
 * the watched drone is a detection ("dangerous proximity", §5.3: "Proximity
 * is considered dangerous if the RSSI value returned is bigger than -48
 * dBm"). The detecting drone then makes both land (§5.3: "When one of the
 * drones detects it is in dangerous proximity with another drone, they both
 * land"): in the seed each drone is flown by its ground station through
 * cflib and the P2P packet only carries the sender's id, so how the other
 * drone is told is not the radio's business there; here the detecting drone
 * broadcasts a LAND packet (three times, one per PID iteration, so one lost
 * frame does not leave the other flying) and lands with EXT_LAND; a drone
 * that receives a LAND packet lands too.
 *
 * Roles by run parameters (firmware.radar_* run keys): every drone takes
 * off to radar_height_mm and flies the body-frame velocity set-point
 * (radar_vx_mm_s, radar_vy_mm_s): zero for the hovering drone A and the
 * cluster, 0.2 m/s towards A for B (§5.3). The STM32's PID runs every
 * 32 ms iteration between packets (as explore_app.c's loop).
 *
 * Console (one line each, parsed by `cosim`'s radar report):
 *   RADAR start id= height_mm= vx_mm_s= vy_mm_s= watch=
 *   RADAR detect t_ms= id= from= seq= rssi_cdbm= x_mm= y_mm= z_mm=
 *   RADAR land_cmd t_ms= id= from=         a LAND packet made it land
 *   RADAR timeout t_ms= id=                radar_max_ms passed: it lands
 *   RADAR end t_ms= id= sent= received= lost=
 * t_ms is platform time (mtime / core clock); the world-time distance of a
 * detection is in the world's radio.csv (the received frame, its
 * distance_m).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "../radio/radio.h"
#include "../stm32.h"

/* Run parameters (the platform may patch them before the core starts;
 * initialised, so they live in .data). */
volatile int32_t radar_height_mm = 500;     /* §5.3: flown at 0.5 m */
__attribute__((section(".data"))) volatile int32_t radar_vx_mm_s = 0; /* body frame */
__attribute__((section(".data"))) volatile int32_t radar_vy_mm_s = 0;
volatile int32_t radar_threshold_cdbm = -4800; /* §5.3: -48 dBm */
volatile int32_t radar_period_ms = 100;        /* §4.3.2.A: read every 100 ms */
/* Only packets from this id count as a detection (the seed's experiment
 * watches A <-> B; the cluster's other two only add traffic): 0 = any,
 * -1 = none (a cluster drone that only broadcasts). */
__attribute__((section(".data"))) volatile int32_t radar_watch_id = 0;
/* Lands anyway after this long in the air (the run always ends). */
volatile int32_t radar_max_ms = 40000;
/* This drone's send phase in the period, ms (-1: by its id, phase_ms()). */
volatile int32_t radar_phase_ms = -1;
volatile int32_t radar_core_hz = 250000000;
/* Beacons leave at a pseudo-random time in [0, radar_tx_spread_us) into
 * the PID iteration that follows the send (the radio's TX_DELAY), instead
 * of at its start (0: off, as before). On the Crazyflie the P2P packets
 * leave when the application task calls the radio, at no common time; here
 * a flying drone's frames would otherwise all leave on the 32 ms grid of
 * the iterations, shared by all drones (iteration() below), so that two
 * drones sending in one iteration always collide. The nRF51 has no delayed
 * send: the delay only puts the frame at the time the real firmware's call
 * could have sent it. At most ITER_MS: the frame leaves within the
 * iteration. */
__attribute__((section(".data"))) volatile int32_t radar_tx_spread_us = 0;

enum { PKT_BEACON = 0xA5, PKT_LAND = 0x1D };
#define LAND_REPEATS 3

/* One 32 ms PID iteration (as motion_test.c / explore_app.c). */
#define ITER_MS 32
#define PID_MS 7

static radio_t p2p;
static uint32_t id, sent, received;
static uint32_t rng_state;

/* xorshift32 (Marsaglia 2003): the beacons' send delays, seeded by the
 * drone's id, so every run of a scenario is the same. */
static uint32_t rng_next(void)
{
    uint32_t x = rng_state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return rng_state = x;
}

/* One PID iteration. A frame started between iterations leaves at the
 * world time the drone's clock has reached (docs/SWARM.md §4.2): the STM32
 * sends its ITER_ADVANCE to the world together with the PID step, so every
 * transmission of a flying drone leaves on the 32 ms grid of its
 * iterations, common to all drones (they start together). */
static void iteration(void)
{
    stm32_iteration(ITER_MS - PID_MS);
}


static uint32_t now_ms(void)
{
    return (uint32_t)(radio_now_cycles() / (uint64_t)(radar_core_hz / 1000));
}

static int32_t mm(double m) { return (int32_t)lround(m * 1000.0); }

/* The send phase in the period: radar_phase_ms, or by default 0, 50, 25,
 * 75 ms for ids 1, 2, 3, 4 (of a 100 ms period). Frames leave on the
 * drones' common 32 ms iteration grid (iteration() above), so two drones
 * whose send times fall into one iteration transmit together and, half
 * duplex, do not hear each other; 50 ms apart, A and B never share one (a
 * 32 ms grid cannot put two times 50 ms apart into one bin). Four drones
 * cannot share 100 ms on that grid without collisions: the cluster
 * scenario spreads its beacons within the iteration (radar_tx_spread_us). */
static uint32_t phase_ms(uint32_t period)
{
    if (radar_phase_ms >= 0)
        return (uint32_t)radar_phase_ms % period;
    uint32_t k = id > 0 ? id - 1 : 0;
    return ((k % 2) * period / 2 + ((k / 2) % 2) * period / 4) % period;
}

/* Sends a packet unless the previous one is still on the air; 1 if sent. */
static int send(uint8_t kind, uint16_t seq)
{
    if (REG8(p2p.base + RADIO_STATE_OFFSET) == RADIO_STATE_TX)
        return 0;
    uint8_t pkt[4] = {kind, (uint8_t)id, (uint8_t)seq, (uint8_t)(seq >> 8)};
    int32_t spread_us = radar_tx_spread_us;
    if (kind == PKT_BEACON && spread_us > 0) {
        if (spread_us > ITER_MS * 1000)
            spread_us = ITER_MS * 1000;
        radio_send_delayed(&p2p, pkt, sizeof pkt, (rng_next() % (uint32_t)spread_us) * 1000u);
    } else {
        radio_send(&p2p, pkt, sizeof pkt);
    }
    sent++;
    return 1;
}

/* Broadcasts LAND, lands (EXT_LAND stops the motors and STOPs the drone),
 * prints the totals. */
static int land(void)
{
    for (int n = 0, tries = 0; n < LAND_REPEATS && tries < 10; tries++) {
        n += send(PKT_LAND, (uint16_t)n);
        iteration();
    }
    uint32_t t = now_ms();
    uint32_t s = stm32_ext(EXT_LAND);
    printf("RADAR end t_ms=%lu id=%lu sent=%lu received=%lu lost=%lu\n", (unsigned long)t,
           (unsigned long)id, (unsigned long)sent, (unsigned long)received,
           (unsigned long)radio_rx_lost(&p2p));
    return s == EXT_LAND ? 0 : 3;
}

int main(void)
{
    p2p = RADIO_P2P;
    stm32_perform(INIT_PID);
    radio_init(&p2p);
    radio_rx_on(&p2p);
    id = (uint32_t)radio_eui(&p2p);
    rng_state = 0x9E3779B9u ^ (id * 2654435761u);
    if (rng_state == 0)
        rng_state = 1;
    printf("RADAR start id=%lu height_mm=%ld vx_mm_s=%ld vy_mm_s=%ld watch=%ld\n",
           (unsigned long)id, (long)radar_height_mm, (long)radar_vx_mm_s, (long)radar_vy_mm_s,
           (long)radar_watch_id);
    if (radar_tx_spread_us > 0)
        printf("RADAR tx_spread_us=%ld\n", (long)radar_tx_spread_us);

    REGF64(STM32_CMD_HEIGHT_OFFSET) = radar_height_mm / 1000.0;
    if (stm32_ext(EXT_TAKEOFF) != EXT_TAKEOFF) {
        printf("RADAR error take-off refused\n");
        return 1;
    }
    double vx = radar_vx_mm_s / 1000.0, vy = radar_vy_mm_s / 1000.0;
    /* Velocity mode's speed limit must allow the set-point. */
    double speed = sqrt(vx * vx + vy * vy);
    if (speed > 0.2) {
        REGF64(STM32_CMD_SPEED_LIMIT_OFFSET) = speed;
        stm32_ext(EXT_SET_SPEED_LIMIT);
    }
    REGF64(STM32_CMD_VX_OFFSET) = vx;
    REGF64(STM32_CMD_VY_OFFSET) = vy;
    REGF64(STM32_CMD_YAW_RATE_OFFSET) = 0.0;
    if (stm32_ext(EXT_SET_VELOCITY) != EXT_SET_VELOCITY) {
        printf("RADAR error velocity set-point refused\n");
        return 2;
    }
    /* Drain what arrived during the take-off: only live packets count. */
    radio_frame_t f;
    while (radio_recv(&p2p, &f))
        ;

    uint32_t start = now_ms(), period = (uint32_t)radar_period_ms;
    uint32_t next_tx = start + phase_ms(period);
    uint16_t seq = 0;
    for (;;) {
        if ((int32_t)(now_ms() - next_tx) >= 0 && send(PKT_BEACON, seq)) {
            seq++;
            next_tx += period;
        }
        iteration();
        while (radio_recv(&p2p, &f)) {
            received++;
            if (f.len < 4)
                continue;
            uint32_t from = f.data[1];
            if (f.data[0] == PKT_LAND) {
                printf("RADAR land_cmd t_ms=%lu id=%lu from=%lu\n", (unsigned long)now_ms(),
                       (unsigned long)id, (unsigned long)from);
                return land();
            }
            int watched = radar_watch_id == 0 || (int32_t)from == radar_watch_id;
            if (f.data[0] == PKT_BEACON && watched && f.rssi_centi_dbm > radar_threshold_cdbm) {
                printf("RADAR detect t_ms=%lu id=%lu from=%lu seq=%u rssi_cdbm=%ld x_mm=%ld "
                       "y_mm=%ld z_mm=%ld\n",
                       (unsigned long)now_ms(), (unsigned long)id, (unsigned long)from,
                       (unsigned)(f.data[2] | f.data[3] << 8), (long)f.rssi_centi_dbm,
                       (long)mm(REGF64(STM32_EST_X_OFFSET)), (long)mm(REGF64(STM32_EST_Y_OFFSET)),
                       (long)mm(REGF64(STM32_EST_Z_OFFSET)));
                return land();
            }
        }
        if (now_ms() - start > (uint32_t)radar_max_ms) {
            printf("RADAR timeout t_ms=%lu id=%lu\n", (unsigned long)now_ms(), (unsigned long)id);
            return land();
        }
    }
}
