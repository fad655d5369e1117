/*
 * Self-test of the swarm firmware (seed 003 chapters 5-7) on the ISS:
 * exit status = number of failed checks. sim-core's
 * tests/swarm_firmware.rs runs it, with and without a scenario of its own.
 *
 * Prints "cycles NAME: mean M max X n N" lines (mcycle) for the cost
 * table of docs/SWARM_FIRMWARE.md, and "sizeof" lines for the RAM.
 */
#include <math.h>
#include <string.h>

#include "selftest_util.h"
#include "swarm.h"
#include "swarm_scenario.h"

int st_checks, st_failures;

/* The context of one drone with the seed's 16 neighbours, as an
 * application would allocate it: the test reads its size from the ELF. */
swarm_t swarm_ctx;

/* ---- §6.4: timestamps and their wrap ------------------------------------ */

static void wrap_tables(void)
{
    /* Table 6.1: rx = 2^40 - 800, reply 1300: tx = 2^40 + 500, stored 500. */
    uint64_t rx = (UINT64_C(1) << 40) - 800, tx = ((UINT64_C(1) << 40) + 500) & SWARM_STAMP_MASK;
    CHECK(tx == 500, "Table 6.1 tx after the wrap: %lu", (unsigned long)tx);
    int64_t naive = (int64_t)tx - (int64_t)rx;
    CHECK(naive == 1300 - (INT64_C(1) << 40), "Table 6.1 signed reply");
    CHECK(swarm_stamp_since(tx, rx) == 1300, "Table 6.1 with unsigned 40-bit arithmetic");
    /* Table 6.2: the same on 8 bits: 246 + 20 = 266 → 10; 10 - 246 = -236
     * = 100010100b on 9 bits; truncated to 8 bits: 20. */
    CHECK(((266u) & 0xff) == 10, "Table 6.2 tx after the wrap");
    CHECK((uint32_t)(10 - 246) % 512 == 0x114, "Table 6.2 9-bit pattern");
    CHECK(swarm_since_bits(10, 246, 8) == 20, "Table 6.2 reply on 8 bits");
    /* The 32-bit packet stamps of §6.4.2. */
    CHECK(swarm_packet_since((uint32_t)tx, (uint32_t)rx) == 1300, "32-bit reply across the wrap");
    /* Unwrapping a 32-bit interval with a 40-bit one close to it. */
    uint64_t big = (UINT64_C(3) << 32) + 12345;
    CHECK(swarm_unwrap32((uint32_t)big, big + 77) == big, "unwrap32 above 2^32");
    CHECK(swarm_unwrap32((uint32_t)big, big - 77) == big, "unwrap32 below");
    CHECK(swarm_unwrap32(5, 3) == 5, "unwrap32 small");
    CHECK(swarm_unwrap32(0xfffffff0u, 5) == 0xfffffff0u, "unwrap32 never negative");
}

/* ---- eq. 5.11 with clock errors ----------------------------------------- */

/* Stamp of true time t (1/1024 ticks) by a clock of ppb error and phase. */
static uint64_t clk(int64_t t, int32_t e_ppb, uint64_t ph)
{
    int64_t local = t + (t / 1000000000) * e_ppb + (t % 1000000000) * e_ppb / 1000000000;
    return ((uint64_t)(local / 1024) + ph) & SWARM_STAMP_MASK;
}

static void eq511(void)
{
    static const int32_t ppbs[] = {-20000, -7000, 0, 13000, 20000};
    /* From 10 cm (two Crazyflies side by side) to 9.9 m (§7.4's 10 m). */
    static const int32_t mms[] = {100, 300, 2500, 6000, 9900};
    static const int32_t reply_us[] = {300, 5000, 20000, 50000, 90000};
    swarm_prng_t r;
    swarm_prng_seed(&r, 511);
    int64_t worst = 0, best_uncorrected = INT64_MAX;
    int cases = 0;
    for (unsigned a = 0; a < 5; a++)
        for (unsigned b = 0; b < 5; b++)
            for (unsigned m = 0; m < 5; m++)
                for (unsigned k = 0; k < 5; k++) {
                    int32_t em = ppbs[a], ex = ppbs[b];
                    /* Phases anywhere; every fifth case wraps mid-exchange. */
                    uint64_t pm = ((uint64_t)swarm_prng_next(&r) << 8) & SWARM_STAMP_MASK;
                    uint64_t px = ((uint64_t)swarm_prng_next(&r) << 8) & SWARM_STAMP_MASK;
                    if (k == m)
                        pm = SWARM_STAMP_MASK - 1000000;
                    int64_t f = (int64_t)mms[m] * 63897600000LL * 1024 / 299792458000LL;
                    int64_t us = 63897600LL * 1024 / 1000; /* 1/1024 ticks per µs */
                    /* X sends (a); M sends 1-4 ms later; X replies after
                     * reply_us; the clock ratio uses X's two packets. */
                    int64_t t_xa = 1000 * us + (int64_t)swarm_prng_below(&r, 1000) * us;
                    int64_t t_m = t_xa + (1000 + (int64_t)swarm_prng_below(&r, 3000)) * us;
                    int64_t t_xb = t_m + f + reply_us[k] * us + (int64_t)swarm_prng_below(&r, 1024);
                    uint64_t rx_a = clk(t_xa + f, em, pm), rx_b = clk(t_xb + f, em, pm);
                    uint64_t tx_a = clk(t_xa, ex, px), tx_b = clk(t_xb, ex, px);
                    uint64_t local = swarm_stamp_since(rx_b, rx_a);
                    uint64_t remote = swarm_unwrap32((uint32_t)tx_b - (uint32_t)tx_a, local);
                    int64_t delta;
                    CHECK(swarm_clock_candidate(local, remote, &delta), "clock candidate");
                    int32_t tof = -1, tof0 = -1;
                    int rc = swarm_exchange_tof(clk(t_m, em, pm), (uint32_t)clk(t_m + f, ex, px),
                                                (uint32_t)tx_b, rx_b, delta, 0, &tof);
                    /* True TOF in M's ticks, ×1000. */
                    int64_t want = f * 1000 / 1024;
                    want += want * em / 1000000000;
                    int64_t err = (int64_t)tof * 1000 - want;
                    if (err < 0)
                        err = -err;
                    CHECK(rc == 0 && err <= 2000,
                          "eq. 5.11: %ld mm, %ld/%ld ppb, reply %ld us: rc %d tof %ld "
                          "want %ld/1000",
                          (long)mms[m], (long)em, (long)ex, (long)reply_us[k], rc, (long)tof,
                          (long)want);
                    if (err > worst)
                        worst = err;
                    /* Without the clock correction (eq. 5.6) the same
                     * exchange is off by reply·Δppm/2. */
                    if (em != ex && reply_us[k] >= 20000) {
                        /* Rejected as out of 0-10 m, or wrong. */
                        rc = swarm_exchange_tof(clk(t_m, em, pm), (uint32_t)clk(t_m + f, ex, px),
                                                (uint32_t)tx_b, rx_b, 0, 0, &tof0);
                        int64_t e0 = (int64_t)tof0 * 1000 - want;
                        if (e0 < 0)
                            e0 = -e0;
                        if (rc == 0 && e0 < best_uncorrected)
                            best_uncorrected = e0;
                    }
                    cases++;
                }
    /* A tick is 4.692 mm of distance. */
    printf("eq. 5.11: %d exchanges, worst error %ld.%03ld ticks (%ld.%ld mm)\n", cases,
           (long)(worst / 1000), (long)(worst % 1000), (long)(worst * 4692 / 1000000),
           (long)(worst * 4692 / 100000 % 10));
    if (best_uncorrected == INT64_MAX)
        printf("eq. 5.11 without the clock correction: every such exchange is rejected\n");
    else
        printf("eq. 5.11 without the clock correction: best accepted error %ld ticks\n",
               (long)(best_uncorrected / 1000));
    CHECK(best_uncorrected > 20000, "the clock correction should matter");
}

/* ---- §6.4.2: the clock correction's filter -------------------------------- */

static void clock_filter(void)
{
    swarm_clock_settings_t cs = {25000, 30};
    swarm_clock_t c = {0};
    int64_t ppm = ((int64_t)1 << 40) / 1000000;
    CHECK(!swarm_clock_update(&c, 51 * ppm, &cs) && !c.have, "beyond 1 + 2·25 ppm is refused");
    CHECK(swarm_clock_update(&c, 40 * ppm, &cs) && c.have, "the first value is taken");
    CHECK(swarm_clock_update(&c, 40 * ppm + ppm / 100, &cs), "0.01 ppm away is accepted");
    CHECK(c.delta_q40 == 40 * ppm + ppm / 200, "and averaged in");
    CHECK(!swarm_clock_update(&c, 41 * ppm, &cs), "1 ppm away is an outlier");
    CHECK(c.delta_q40 == 40 * ppm + ppm / 200, "that does not move the value");
    /* A lasting change replaces the value once the bucket is empty. */
    int taken = 0;
    for (int i = 0; i < 6 && !taken; i++)
        taken = swarm_clock_update(&c, 30 * ppm, &cs) && c.delta_q40 == 30 * ppm;
    CHECK(taken, "a lasting change is followed");
    int64_t d;
    int64_t want = ((int64_t)20 << 40) / 1000000;
    CHECK(swarm_clock_candidate(1000020, 1000000, &d) && d - want <= 1 && want - d <= 1,
          "candidate 20 ppm: %ld, want %ld", (long)d, (long)want);
    CHECK(swarm_clock_candidate(999980, 1000000, &d) && d + want <= 1 && -want - d <= 1,
          "candidate -20 ppm: %ld", (long)d);
    CHECK(!swarm_clock_candidate(1002000, 1000000, &d), "a 0.2 %% ratio is not a clock");
}

/* ---- §6.7: the STATUS packet -------------------------------------------- */

static void packets(void)
{
    swarm_prng_t r;
    swarm_prng_seed(&r, 67);
    static swarm_status_t p, q;
    uint8_t buf[SWARM_MAX_FRAME + 8];
    CHECK(SWARM_MAX_ENTRIES == 14, "14 entries fit 127 bytes");
    CHECK(swarm_status_size(14) == 120, "a full packet is 120 bytes");
    for (unsigned count = 0; count <= SWARM_MAX_ENTRIES; count++) {
        memset(&p, 0, sizeof p);
        p.source_id = (uint8_t)swarm_prng_next(&r);
        p.seq = (uint8_t)swarm_prng_next(&r);
        p.tx_valid = count & 1;
        p.tx = swarm_prng_next(&r);
        p.count = (uint8_t)count;
        for (unsigned i = 0; i < count; i++)
            p.entry[i] = (swarm_entry_t){(uint8_t)swarm_prng_next(&r),
                                         (uint8_t)swarm_prng_next(&r), swarm_prng_next(&r),
                                         (uint16_t)swarm_prng_next(&r)};
        size_t len = swarm_status_write(&p, buf, sizeof buf);
        CHECK(len == 8 + 8 * count, "length of %u entries: %u", count, (unsigned)len);
        CHECK(buf[1] == SWARM_PACKET_TYPE_STATUS, "type byte");
        memset(&q, 0xee, sizeof q);
        CHECK(swarm_status_read(&q, buf, len) == SWARM_PARSE_OK, "parse %u entries", count);
        int same = q.source_id == p.source_id && q.seq == p.seq && q.tx_valid == p.tx_valid &&
                   q.tx == p.tx && q.count == p.count;
        for (unsigned i = 0; i < count; i++)
            same &= q.entry[i].id == p.entry[i].id && q.entry[i].seq == p.entry[i].seq &&
                    q.entry[i].rx == p.entry[i].rx && q.entry[i].tof == p.entry[i].tof;
        CHECK(same, "round trip of %u entries", count);
        if (count == 3) {
            /* Byte layout: little endian, header then entries. */
            CHECK(buf[0] == p.source_id && buf[2] == p.seq && buf[3] == (uint8_t)p.tx &&
                      buf[6] == (uint8_t)(p.tx >> 24) && buf[7] == (3 | SWARM_TX_VALID) &&
                      buf[8] == p.entry[0].id && buf[10] == (uint8_t)p.entry[0].rx &&
                      buf[14] == (uint8_t)p.entry[0].tof,
                  "byte layout");
            CHECK(swarm_status_read(&q, buf, len - 1) == SWARM_PARSE_BAD_LENGTH, "truncated");
            CHECK(swarm_status_read(&q, buf, len + 1) == SWARM_PARSE_BAD_LENGTH, "trailing byte");
            CHECK(swarm_status_read(&q, buf, 7) == SWARM_PARSE_SHORT, "shorter than a header");
            buf[1] ^= 1;
            CHECK(swarm_status_read(&q, buf, len) == SWARM_PARSE_NOT_STATUS, "other type (§6.1)");
        }
    }
    p.count = SWARM_MAX_ENTRIES + 1;
    CHECK(swarm_status_write(&p, buf, sizeof buf) == 0, "15 entries do not fit");
    p.count = 2;
    CHECK(swarm_status_write(&p, buf, 23) == 0, "nor 2 in 23 bytes");
}

/* ---- §6.2, §6.3, §6.5: identifiers, sequence numbers, timing -------------- */

static void identity_and_timing(void)
{
    CHECK(swarm_id_from_eui(1) == 1 && swarm_id_from_eui(3) == 3, "EUI 1, 3 → id 1, 3");
    CHECK(swarm_id_from_eui(0x0102030405060708ull) == (1 ^ 2 ^ 3 ^ 4 ^ 5 ^ 6 ^ 7 ^ 8), "xor fold");
    swarm_settings_t set;
    swarm_default_settings(&set);
    swarm_init(&swarm_ctx, &set, 7);
    static swarm_t other;
    swarm_init(&other, &set, 7);
    /* §6.5 with no neighbour: 100 Hz cap, uniform in [5, 15) ms. */
    uint32_t lo = UINT32_MAX, hi = 0;
    uint64_t sum = 0;
    int same = 1;
    for (int i = 0; i < 2000; i++) {
        uint32_t d = swarm_next_tx_delay_us(&swarm_ctx);
        same &= d == swarm_next_tx_delay_us(&other);
        lo = d < lo ? d : lo;
        hi = d > hi ? d : hi;
        sum += d;
    }
    printf("tx delay (alone): min %lu max %lu mean %lu us\n", (unsigned long)lo,
           (unsigned long)hi, (unsigned long)(sum / 2000));
    CHECK(lo >= 5000 && hi < 15000 && lo < 5100 && hi > 14900, "window [5, 15) ms");
    CHECK(sum / 2000 > 9800 && sum / 2000 < 10200, "mean 10 ms");
    CHECK(same, "same EUI, same draws (deterministic)");
    swarm_init(&other, &set, 8);
    CHECK(swarm_next_tx_delay_us(&swarm_ctx) != swarm_next_tx_delay_us(&other),
          "another EUI, other draws");

    /* Sequence numbers (§6.3) and an identifier clash (§6.2). */
    swarm_init(&swarm_ctx, &set, 1);
    swarm_init(&other, &set, 2);
    uint8_t buf[SWARM_MAX_FRAME];
    size_t len = swarm_build_status(&other, buf, sizeof buf);
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 1000, 0, 0) == SWARM_RX_OK, "first packet");
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 1100, 0, 0) == SWARM_RX_REFLECTION, "its reflection");
    for (int i = 0; i < 5; i++)
        len = swarm_build_status(&other, buf, sizeof buf);
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 2000, 0, 0) == SWARM_RX_OK, "a gap of lost packets");
    buf[2] -= 3;
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 2100, 0, 0) == SWARM_RX_REFLECTION, "3 behind");
    buf[2] -= 3;
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 2100, 0, 0) == SWARM_RX_OK,
          "7 behind: taken as a restart");
    buf[0] = swarm_ctx.id;
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 2200, 0, 0) == SWARM_RX_ID_CLASH, "our own id");
    CHECK(swarm_ctx.id != 1 && swarm_ctx.id != 2, "a new id, not the sender's: %u",
          swarm_ctx.id);
    CHECK(swarm_on_rx(&swarm_ctx, buf, 5, 2300, 0, 0) == SWARM_RX_SHORT, "short frame");

    /* The table holds 16 neighbours; a 17th is refused (§6.9.3). */
    swarm_init(&swarm_ctx, &set, 1);
    len = swarm_build_status(&other, buf, sizeof buf);
    int accepted = 0;
    for (int id = 100; id < 117; id++) {
        buf[0] = (uint8_t)id;
        int r = swarm_on_rx(&swarm_ctx, buf, len, 1000 + (uint64_t)id, 0, (uint32_t)id * 1000);
        accepted += r == SWARM_RX_OK;
        if (id == 116)
            CHECK(r == SWARM_RX_TABLE_FULL, "17th neighbour: %d", r);
    }
    CHECK(accepted == 16 && swarm_neighbour_count(&swarm_ctx) == 16, "16 neighbours");
    /* removeOutdatedData (§6.9.3): silent for more than 1 s, forgotten. */
    swarm_housekeeping(&swarm_ctx, 1000000 + 100000);
    CHECK(swarm_neighbour_count(&swarm_ctx) == 16, "all heard within 1 s");
    swarm_housekeeping(&swarm_ctx, 1000000 + 107500);
    CHECK(swarm_neighbour_count(&swarm_ctx) == 8, "the 8 silent for 1 s are gone: %u",
          swarm_neighbour_count(&swarm_ctx));
    buf[0] = 116;
    CHECK(swarm_on_rx(&swarm_ctx, buf, len, 5000, 0, 1200000) == SWARM_RX_OK,
          "room again for a 17th");
    swarm_housekeeping(&swarm_ctx, 5000000);
    CHECK(swarm_neighbour_count(&swarm_ctx) == 0, "all gone");
    int tofs = 0;
    for (unsigned i = 0; i < SWARM_TOF_PAIRS; i++)
        tofs += swarm_ctx.tof[i] != 0;
    CHECK(tofs == 0 && swarm_ctx.nref == 0, "their TOFs and the frame with them");
}

extern void coords_and_kalman_tests(void);

int main(void)
{
    printf("sizeof swarm_t %u (neighbours %u), swarm_neighbour_t %u, swarm_kf_t %u, tof table %u\n",
           (unsigned)sizeof(swarm_t), (unsigned)SWARM_MAX_NEIGHBOURS,
           (unsigned)sizeof(swarm_neighbour_t), (unsigned)sizeof(swarm_kf_t),
           (unsigned)sizeof(((swarm_t *)0)->tof));
    wrap_tables();
    eq511();
    clock_filter();
    packets();
    identity_and_timing();
    coords_and_kalman_tests();
    if (!sc_run_input())
        sc_run_builtin();
    printf("swarm_selftest: %d checks, %d failures: %s\n", st_checks, st_failures,
           st_failures ? "FAIL" : "PASS");
    return st_failures > 255 ? 255 : st_failures;
}
