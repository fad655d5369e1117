/*
 * Seed 003's relative positioning as an application: the loop of
 * docs/SWARM_FIRMWARE.md §4 on the DW1000-like radio (radio.h), around the
 * library of swarm.h. Every drone of a swarm runs this same program; what
 * tells them apart is the radio's EUI (run key radio_id: cosim gives 1, 2,
 * 3, ... in [[platform]] order).
 *
 *   1. INIT the radio (claims the world; the platform's clock ticker moves a
 *      carried drone's clock, docs/SWARM.md §4.1), then stay off until this
 *      drone's switch-on time: (EUI - 1) x SWITCH_ON_STEP_MS after INIT_DONE,
 *      so the drones come up in EUI order as the seed's A, B, C (§7.1 step 2).
 *   2. Receiver on; transmit a STATUS packet at randomized times (§6.5):
 *      next_tx += swarm_next_tx_delay_us(), never while a frame is on the air.
 *   3. TX_DONE -> swarm_tx_done(TX_STAMP); RX_DONE -> swarm_on_rx() for every
 *      frame of the receive FIFO, in order.
 *   4. Every 10 ms: swarm_housekeeping() and the estimates line of
 *      swarm_format_estimates() (§7.1 records 100 samples per second),
 *      written with one semihosting write to the console (console.log).
 *   5. Every second: a "swarm load" line (packets sent/received in that
 *      second, neighbours, the core cycles spent in the library and in the
 *      output) for §7.2.1 and §7.4; at the end a "swarm end" line with the
 *      library's counters. After RUN_SECONDS the program ends (the platform
 *      sends STOP for it).
 *
 * Between events the core sleeps in wfi (radio interrupt or machine timer),
 * so the cycles it spends are the work done, as a CPU load figure wants.
 * mtime (core cycles at CORE_HZ, running during wfi) is the clock; mcycle
 * (stopped during wfi) measures the work.
 *
 * The platform offers no run keys to a firmware besides radio_id, so the
 * settings are compile-time (Makefile variants):
 *   SWITCH_ON_STEP_MS  switch-on stagger per EUI (default 200 ms)
 *   MEAS_STD_MM        σ of a distance for the filters, §7.3 (250)
 *   RUN_SECONDS        run length after INIT_DONE (52 s)
 *   PLANAR             1: 2D, z = 0 for everyone (the seed's table, §7.1)
 *   KEEP_FRAME         1: keep the frame's arbitrary values (SWARM_FIRMWARE §3)
 *   OUTPUT_HZ          estimates lines per second (100)
 */
#include <stdint.h>

#include "../radio/radio.h"
#include "swarm_app.h"

#ifndef SWITCH_ON_STEP_MS
#define SWITCH_ON_STEP_MS 200
#endif
#ifndef MEAS_STD_MM
#define MEAS_STD_MM 250
#endif
#ifndef RUN_SECONDS
#define RUN_SECONDS 52
#endif
#ifndef PLANAR
#define PLANAR 1
#endif
#ifndef KEEP_FRAME
#define KEEP_FRAME 1
#endif

int main(void)
{
    radio_t uwb = RADIO_UWB;
    radio_init(&uwb);
    const uint64_t eui = radio_eui(&uwb);
    const uint64_t t0 = radio_now_cycles();
    const uint64_t on_at =
        t0 + (eui > 0 ? eui - 1 : 0) * (uint64_t)SWITCH_ON_STEP_MS * (APP_CORE_HZ / 1000);
    const uint64_t end_at = t0 + (uint64_t)RUN_SECONDS * APP_CORE_HZ;
    if (on_at < end_at)
        app_sleep_until(on_at);

    swarm_settings_t set;
    swarm_default_settings(&set);
    set.meas_std = (float)MEAS_STD_MM / 1000.0f;
    set.planar = PLANAR;
    set.keep_frame = KEEP_FRAME;
    app_start(&uwb, eui, t0, &set);
    while (radio_now_cycles() < end_at) {
        uint64_t wake = app_next_wake();
        if (wake > end_at)
            wake = end_at;
        radio_wait(&uwb, RADIO_TX_DONE | RADIO_RX_DONE, wake);
        app_poll();
    }
    app_end();
    return 0;
}
