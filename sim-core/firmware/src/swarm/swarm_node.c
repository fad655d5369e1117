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
#include <stdio.h>

#include "../cycles.h"
#include "../radio/radio.h"
#include "swarm.h"

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
#ifndef OUTPUT_HZ
#define OUTPUT_HZ 100
#endif
/* The core clock of sim-core's embedded Crazyflie platform (DESIGN.md §4):
 * mtime counts core cycles. */
#ifndef CORE_HZ
#define CORE_HZ 250000000ull
#endif
#define CYCLES_PER_US (CORE_HZ / 1000000ull)

static swarm_t ctx;
static radio_t uwb;
static radio_frame_t frame;
static uint8_t txbuf[RADIO_BUF_SIZE];
static char line[1024];

/* Work counters (mcycle): the library (ranging + estimation) and the
 * output (formatting + the console write). */
static uint64_t cyc_swarm, cyc_output;

static uint64_t mcycle(void)
{
    return csr_mcycle64();
}

/* One semihosting SYS_WRITE0 per line (RISC-V semihosting: the ebreak
 * between the two marker instructions; a0 = operation, a1 = the string).
 * picolibc's stdout would make one call per character. `s` is zero-
 * terminated; `n` is its length (unused: WRITE0 stops at the zero). */
static void put(const char *s, size_t n)
{
    (void)n;
    register uint32_t a0 __asm__("a0") = 0x04;
    register const char *a1 __asm__("a1") = s;
    __asm__ volatile(".option push\n\t.option norvc\n\t"
                     "slli x0, x0, 0x1f\n\tebreak\n\tsrai x0, x0, 7\n\t.option pop"
                     : "+r"(a0)
                     : "r"(a1)
                     : "memory");
}

/* The identifier of a node (neighbour slot or SWARM_SELF). */
static unsigned node_id(int node)
{
    return node == SWARM_SELF ? ctx.id : ctx.nb[node].id;
}

/* "swarm frame t=.. id=.. refs=a,b,c" whenever the frame's references
 * change (§5.3.2: origin, +X, XY plane with +Y, +Z): the report computes
 * the true positions in the same frame from them. */
static void report_frame(uint32_t now_ms)
{
    static int8_t last[4] = {-1, -1, -1, -1};
    static uint8_t last_n = 0, last_building = 1;
    int same = last_n == ctx.nref && last_building == ctx.building;
    for (int i = 0; i < ctx.nref && same; i++)
        same = last[i] == ctx.ref[i];
    if (same)
        return;
    int n = snprintf(line, sizeof line, "swarm frame t=%lu id=%u %s refs=", (unsigned long)now_ms,
                     (unsigned)ctx.id, ctx.building ? "building" : "built");
    for (int i = 0; i < ctx.nref; i++)
        n += snprintf(line + n, sizeof line - (size_t)n, i ? ",%u" : "%u", node_id(ctx.ref[i]));
    n += snprintf(line + n, sizeof line - (size_t)n, "\n");
    put(line, (size_t)n);
    for (int i = 0; i < 4; i++)
        last[i] = i < ctx.nref ? ctx.ref[i] : -1;
    last_n = ctx.nref;
    last_building = ctx.building;
}

/* Sleeps until `t` (mtime cycles) with the machine timer. */
static void sleep_until(uint64_t t)
{
    radio_set_timer(t);
    __asm__ volatile("csrs mie, %0" ::"r"(1u << 7));
    while (radio_now_cycles() < t)
        __asm__ volatile("wfi");
    __asm__ volatile("csrc mie, %0" ::"r"(1u << 7));
}

int main(void)
{
    uwb = RADIO_UWB;
    radio_init(&uwb);
    const uint64_t eui = radio_eui(&uwb);
    const uint64_t t0 = radio_now_cycles();
    const uint64_t on_at =
        t0 + (eui > 0 ? eui - 1 : 0) * (uint64_t)SWITCH_ON_STEP_MS * (CORE_HZ / 1000);
    const uint64_t end_at = t0 + (uint64_t)RUN_SECONDS * CORE_HZ;
    if (on_at < end_at)
        sleep_until(on_at);

    swarm_settings_t set;
    swarm_default_settings(&set);
    set.meas_std = (float)MEAS_STD_MM / 1000.0f;
    set.planar = PLANAR;
    set.keep_frame = KEEP_FRAME;
    swarm_init(&ctx, &set, eui);
    radio_rx_on(&uwb);

    const uint64_t tick = CORE_HZ / OUTPUT_HZ;
    uint64_t now = radio_now_cycles();
    uint64_t next_tx = now + (uint64_t)swarm_next_tx_delay_us(&ctx) * CYCLES_PER_US;
    uint64_t next_out = t0 + ((now - t0) / tick + 1) * tick;
    uint64_t next_load = t0 + ((now - t0) / CORE_HZ + 1) * CORE_HZ;
    int on_air = 0;
    uint32_t sec_tx = 0, sec_rx = 0, sec_bad = 0;
    uint64_t sec_swarm = 0, sec_output = 0, sec_busy = mcycle();

    while ((now = radio_now_cycles()) < end_at) {
        uint64_t wake = next_out < next_tx || on_air ? next_out : next_tx;
        if (wake > end_at)
            wake = end_at;
        uint8_t st = radio_wait(&uwb, RADIO_TX_DONE | RADIO_RX_DONE, wake);
        now = radio_now_cycles();
        const uint32_t now_us = (uint32_t)((now - t0) / CYCLES_PER_US);

        if (st & RADIO_TX_DONE) {
            radio_clear(&uwb, RADIO_TX_DONE);
            uint64_t c = mcycle();
            swarm_tx_done(&ctx, radio_tx_stamp(&uwb));
            cyc_swarm += mcycle() - c;
            on_air = 0;
        }
        while (radio_recv(&uwb, &frame)) {
            uint64_t c = mcycle();
            int r = swarm_on_rx(&ctx, frame.data, frame.len, frame.stamp, frame.rssi_centi_dbm,
                                now_us);
            cyc_swarm += mcycle() - c;
            if (r == SWARM_RX_OK)
                sec_rx++;
            else
                sec_bad++;
        }
        if (!on_air && now >= next_tx) {
            uint64_t c = mcycle();
            size_t len = swarm_build_status(&ctx, txbuf, sizeof txbuf);
            uint32_t delay = swarm_next_tx_delay_us(&ctx);
            cyc_swarm += mcycle() - c;
            if (len > 0) {
                radio_send(&uwb, txbuf, (uint8_t)len);
                on_air = 1;
                sec_tx++;
            }
            next_tx += (uint64_t)delay * CYCLES_PER_US;
            if (next_tx < now)
                next_tx = now + (uint64_t)delay * CYCLES_PER_US;
        }
        if (now >= next_out) {
            uint64_t c = mcycle();
            swarm_housekeeping(&ctx, now_us);
            uint64_t c2 = mcycle();
            cyc_swarm += c2 - c;
            const uint32_t now_ms = (uint32_t)((now - t0) / (CORE_HZ / 1000));
            report_frame(now_ms);
            size_t n = swarm_format_estimates(&ctx, now_ms, line, sizeof line);
            put(line, n);
            cyc_output += mcycle() - c2;
            next_out += tick;
        }
        if (now >= next_load) {
            uint64_t busy = mcycle();
            int n = snprintf(line, sizeof line,
                             "swarm load t=%lu id=%u n=%u tx=%lu rx=%lu bad=%lu "
                             "swarm_cycles=%llu output_cycles=%llu busy_cycles=%llu "
                             "second_cycles=%llu\n",
                             (unsigned long)((now - t0) / (CORE_HZ / 1000)), (unsigned)ctx.id,
                             swarm_neighbour_count(&ctx), (unsigned long)sec_tx,
                             (unsigned long)sec_rx, (unsigned long)sec_bad,
                             (unsigned long long)(cyc_swarm - sec_swarm),
                             (unsigned long long)(cyc_output - sec_output),
                             (unsigned long long)(busy - sec_busy), (unsigned long long)CORE_HZ);
            put(line, (size_t)n);
            sec_tx = sec_rx = sec_bad = 0;
            sec_swarm = cyc_swarm;
            sec_output = cyc_output;
            sec_busy = mcycle();
            next_load += CORE_HZ;
        }
    }
    const swarm_stats_t *s = &ctx.stats;
    int n = snprintf(line, sizeof line,
                     "swarm end id=%u tx_built=%lu tx_done=%lu rx_ok=%lu rx_not_status=%lu "
                     "rx_reflection=%lu rx_id_clash=%lu tof_valid=%lu tof_invalid=%lu "
                     "clock_accepted=%lu clock_rejected=%lu removed=%lu rx_lost=%lu "
                     "swarm_cycles=%llu output_cycles=%llu\n",
                     (unsigned)ctx.id, (unsigned long)s->tx_built, (unsigned long)s->tx_done,
                     (unsigned long)s->rx_ok, (unsigned long)s->rx_not_status,
                     (unsigned long)s->rx_reflection, (unsigned long)s->rx_id_clash,
                     (unsigned long)s->tof_valid, (unsigned long)s->tof_invalid,
                     (unsigned long)s->clock_accepted, (unsigned long)s->clock_rejected,
                     (unsigned long)s->removed, (unsigned long)radio_rx_lost(&uwb),
                     (unsigned long long)cyc_swarm, (unsigned long long)cyc_output);
    put(line, (size_t)n);
    return 0;
}
