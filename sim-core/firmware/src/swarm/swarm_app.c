/* The radio side of seed 003's positioning (docs/SWARM_FIRMWARE.md §4),
 * shared by swarm_node.c (carried drones, sleeping in wfi between events)
 * and swarm_fly.c (flying drones, polled between the STM32's PID steps):
 * see swarm_app.h. */
#include "swarm_app.h"

#include <stdio.h>

#include "../cycles.h"

#ifndef OUTPUT_HZ
#define OUTPUT_HZ 100
#endif
#define CYCLES_PER_US (APP_CORE_HZ / 1000000ull)

static swarm_t ctx;
static radio_t uwb;
static radio_frame_t frame;
static uint8_t txbuf[RADIO_BUF_SIZE];
static char line[1024];

/* Work counters (mcycle): the library (ranging + estimation) and the
 * output (formatting + the console write). */
static uint64_t cyc_swarm, cyc_output;
static uint64_t t0, tick, next_tx, next_out, next_load;
static int on_air;
static uint32_t sec_tx, sec_rx, sec_bad;
static uint64_t sec_swarm, sec_output, sec_busy;

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
void app_sleep_until(uint64_t t)
{
    radio_set_timer(t);
    __asm__ volatile("csrs mie, %0" ::"r"(1u << 7));
    while (radio_now_cycles() < t)
        __asm__ volatile("wfi");
    __asm__ volatile("csrc mie, %0" ::"r"(1u << 7));
}


void app_start(const radio_t *r, uint64_t eui, uint64_t start, const swarm_settings_t *set)
{
    uwb = *r;
    t0 = start;
    swarm_init(&ctx, set, eui);
    radio_rx_on(&uwb);
    tick = APP_CORE_HZ / OUTPUT_HZ;
    uint64_t now = radio_now_cycles();
    next_tx = now + (uint64_t)swarm_next_tx_delay_us(&ctx) * CYCLES_PER_US;
    next_out = t0 + ((now - t0) / tick + 1) * tick;
    next_load = t0 + ((now - t0) / APP_CORE_HZ + 1) * APP_CORE_HZ;
    sec_busy = mcycle();
}

#ifdef APP_POLL_AHEAD
/* app_poll_ahead's look-ahead (mtime cycles) and the world time it covers. */
static uint64_t ahead, ahead_world_ns;
#endif

uint64_t app_next_wake(void)
{
    return next_out < next_tx || on_air ? next_out : next_tx;
}

void app_poll(void)
{
    uint64_t now = radio_now_cycles();
    const uint32_t now_us = (uint32_t)((now - t0) / CYCLES_PER_US);
    uint8_t st = radio_status(&uwb);
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
#ifdef APP_POLL_AHEAD
    if (!on_air && now + ahead >= next_tx) {
#else
    if (!on_air && now >= next_tx) {
#endif
        uint64_t c = mcycle();
        size_t len = swarm_build_status(&ctx, txbuf, sizeof txbuf);
        uint32_t delay = swarm_next_tx_delay_us(&ctx);
        cyc_swarm += mcycle() - c;
        if (len > 0) {
#ifdef APP_POLL_AHEAD
            /* The DW1000's delayed send (docs/SWARM.md §4.3): the packet
             * goes at the same fraction of the coming ahead_world_ns of
             * world time as next_tx is of the look-ahead. */
            const uint64_t at = radio_now_cycles();
            if (next_tx > at)
                radio_send_delayed(&uwb, txbuf, (uint8_t)len,
                                   (uint32_t)((next_tx - at) * ahead_world_ns / ahead));
            else
#endif
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
        const uint32_t now_ms = (uint32_t)((now - t0) / (APP_CORE_HZ / 1000));
        report_frame(now_ms);
        size_t n = swarm_format_estimates(&ctx, now_ms, line, sizeof line);
#ifdef APP_WORLD_TIME
        /* Only in the flying firmware's build (Makefile: -DAPP_WORLD_TIME):
         * the world time of the STM32's last sensor read (EST_TIME, µs),
         * appended as " world_us=…" before the newline. In flight mtime
         * does not follow the world's clock (the thesis's bookkeeping adds
         * the core time between the STM32's steps), so the report takes the
         * estimate's instant from this; polled between two steps, the
         * estimate holds what the radio saw up to the end of the last step,
         * at most one step (4 ms) after this time (docs/SWARM_RESULTS.md §5). */
        if (n > 0 && line[n - 1] == '\n') {
            const double world_s = REGF64(STM32_EST_TIME_OFFSET);
            n--;
            n += (size_t)snprintf(line + n, sizeof line - n, " world_us=%llu\n",
                                  (unsigned long long)(world_s * 1e6 + 0.5));
        }
#endif
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
                         (unsigned long)((now - t0) / (APP_CORE_HZ / 1000)), (unsigned)ctx.id,
                         swarm_neighbour_count(&ctx), (unsigned long)sec_tx,
                         (unsigned long)sec_rx, (unsigned long)sec_bad,
                         (unsigned long long)(cyc_swarm - sec_swarm),
                         (unsigned long long)(cyc_output - sec_output),
                         (unsigned long long)(busy - sec_busy), (unsigned long long)APP_CORE_HZ);
        put(line, (size_t)n);
        sec_tx = sec_rx = sec_bad = 0;
        sec_swarm = cyc_swarm;
        sec_output = cyc_output;
        sec_busy = mcycle();
        next_load += APP_CORE_HZ;
    }
}

#ifdef APP_POLL_AHEAD
/* Only in the flying firmware's build (Makefile: -DAPP_POLL_AHEAD), so the
 * carried drones' code stays as it was, cycle for cycle. */
void app_poll_ahead(uint64_t cycles, uint64_t world_ns)
{
    ahead = cycles;
    ahead_world_ns = world_ns;
    app_poll();
}
#endif

void app_end(void)
{
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
}
