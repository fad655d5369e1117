/* Several drones exchanging STATUS packets: see swarm_scenario.h. */
#include "swarm_scenario.h"

#include <math.h>
#include <string.h>

#include "selftest_util.h"
#include "swarm.h"

/* The heap is never used (no malloc, §6.9): the harness's input goes there. */
extern char __heap_start[], __heap_end[];

static swarm_t ctx[SC_MAX_DRONES];

typedef struct {
    const char *name;
    int n;
    int planar;
    uint64_t eui[SC_MAX_DRONES];
    float pos[SC_MAX_DRONES][3]; /* m */
    uint32_t true_tof[SC_MAX_DRONES][SC_MAX_DRONES]; /* milliticks */
    uint32_t tof_bound, pos_tol_mm, dist_tol_mm;
} sc_truth_t;

typedef struct {
    uint32_t sender, t_us;
    uint64_t tx;
    uint64_t rx[SC_MAX_DRONES];
    uint32_t lost;
} sc_event_t;

static st_cost_t cost_build = {.name = "swarm_build_status"}, cost_rx = {.name = "swarm_on_rx"},
                 cost_format = {.name = "swarm_format_estimates"},
                 cost_house = {.name = "swarm_housekeeping"};
static uint32_t next_tick_us, ticks;

static void begin(const sc_truth_t *t)
{
    swarm_settings_t set;
    swarm_default_settings(&set);
    set.planar = (uint8_t)t->planar;
    for (int i = 0; i < t->n; i++)
        swarm_init(&ctx[i], &set, t->eui[i]);
    next_tick_us = 0;
    ticks = 0;
    cost_build.count = cost_rx.count = cost_format.count = cost_house.count = 0;
    cost_build.total = cost_rx.total = cost_format.total = cost_house.total = 0;
    cost_build.max = cost_rx.max = cost_format.max = cost_house.max = 0;
}

/* The 100 Hz output of every drone up to time t (§7.1 records at 100 Hz). */
static void ticks_until(const sc_truth_t *t, uint32_t t_us)
{
    static char line[512];
    if (ticks == 0 && next_tick_us < t_us)
        next_tick_us = t_us; /* the output starts with the first packet */
    while (next_tick_us <= t_us) {
        for (int i = 0; i < t->n; i++) {
            uint64_t c0 = st_cycles();
            swarm_housekeeping(&ctx[i], next_tick_us);
            uint64_t c1 = st_cycles();
            swarm_format_estimates(&ctx[i], next_tick_us / 1000, line, sizeof line);
            uint64_t c2 = st_cycles();
            st_cost_add(&cost_house, c1 - c0);
            st_cost_add(&cost_format, c2 - c1);
            if (i == 0 && ticks % 50 == 0)
                printf("%s: %s", t->name, line);
        }
        ticks++;
        next_tick_us += 10000;
    }
}

static void event(const sc_truth_t *t, const sc_event_t *e)
{
    uint8_t buf[SWARM_MAX_FRAME];
    ticks_until(t, e->t_us);
    swarm_t *s = &ctx[e->sender];
    uint64_t c0 = st_cycles();
    size_t len = swarm_build_status(s, buf, sizeof buf);
    st_cost_add(&cost_build, st_cycles() - c0);
    swarm_tx_done(s, e->tx);
    for (int q = 0; q < t->n; q++) {
        if (q == (int)e->sender || (e->lost >> q & 1))
            continue;
        uint64_t c1 = st_cycles();
        int r = swarm_on_rx(&ctx[q], buf, len, e->rx[q], -7000, e->t_us);
        st_cost_add(&cost_rx, st_cycles() - c1);
        CHECK(r == SWARM_RX_OK, "%s: drone %d rejected a packet of %lu: %d", t->name, q,
              (unsigned long)e->sender, r);
    }
}

static int drone_of_id(const sc_truth_t *t, uint8_t id)
{
    for (int k = 0; k < t->n; k++)
        if (ctx[k].id == id)
            return k;
    return -1;
}

/* The drone index of a node of drone i's context. */
static int drone_of_node(const sc_truth_t *t, int i, int node)
{
    return node == SWARM_SELF ? i : drone_of_id(t, ctx[i].nb[node].id);
}

static void sub(float *o, const float *a, const float *b)
{
    for (int k = 0; k < 3; k++)
        o[k] = a[k] - b[k];
}
static float dot(const float *a, const float *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void unit(float *a)
{
    float n = sqrtf(dot(a, a));
    for (int k = 0; k < 3; k++)
        a[k] /= n;
}

static int rnd_mm(float m)
{
    return (int)lroundf(m * 1000.0f);
}

/* Checks of drone i: TOFs (§5.2.2, §5.3.1), frame and positions. */
static void check_drone(const sc_truth_t *t, int i)
{
    swarm_t *s = &ctx[i];
    int64_t bound = t->tof_bound;
    printf("%s: drone %d id %u neighbours %u frame %s refs", t->name, i, s->id,
           swarm_neighbour_count(s), s->building ? "building" : "built");
    for (int r = 0; r < s->nref; r++)
        printf(" %d", drone_of_node(t, i, s->ref[r]));
    printf("\n");
    CHECK((int)swarm_neighbour_count(s) == t->n - 1, "%s: drone %d sees %u neighbours", t->name,
          i, swarm_neighbour_count(s));
    int slot[SC_MAX_DRONES];
    for (int j = 0; j < t->n; j++)
        slot[j] = j == i ? SWARM_SELF : swarm_find(s, ctx[j].id);
    for (int j = 0; j < t->n; j++) {
        if (j == i)
            continue;
        CHECK(slot[j] >= 0, "%s: drone %d lacks %d", t->name, i, j);
        if (slot[j] < 0)
            return;
        int64_t got = (int64_t)swarm_tof(s, SWARM_SELF, slot[j]) * 1000;
        int64_t want = t->true_tof[i][j];
        printf("%s: tof %d %d %ld want %ld\n", t->name, i, j, (long)(got / 1000), (long)want);
        CHECK(got != 0 && got - want <= bound && want - got <= bound,
              "%s: tof %d-%d: %ld milliticks, want %ld ± %ld", t->name, i, j, (long)got,
              (long)want, (long)bound);
        for (int k = j + 1; k < t->n; k++) {
            if (k == i)
                continue;
            int64_t g = (int64_t)swarm_tof(s, slot[j], slot[k]) * 1000;
            int64_t w = t->true_tof[j][k];
            CHECK(g != 0 && g - w <= bound + 100 && w - g <= bound + 100,
                  "%s: drone %d's tof %d-%d: %ld milliticks, want %ld", t->name, i, j, k, (long)g,
                  (long)w);
        }
    }
    int need = t->planar ? 3 : 4;
    CHECK(!s->building, "%s: drone %d's frame is not built", t->name, i);
    /* The seed's frame (§5.3.2) from the true positions of the references,
     * by Gram-Schmidt; with fewer references, this drone completes it. */
    int fr[4], nfr = 0;
    for (int r = 0; r < s->nref; r++)
        fr[nfr++] = drone_of_node(t, i, s->ref[r]);
    if (nfr < need)
        fr[nfr++] = i;
    float ex[3], ey[3], ez[3], v[3];
    const float *o = t->pos[fr[0]];
    sub(ex, t->pos[fr[1]], o);
    unit(ex);
    sub(v, t->pos[fr[2]], o);
    float d = dot(v, ex);
    for (int k = 0; k < 3; k++)
        ey[k] = v[k] - d * ex[k];
    unit(ey);
    ez[0] = ex[1] * ey[2] - ex[2] * ey[1];
    ez[1] = ex[2] * ey[0] - ex[0] * ey[2];
    ez[2] = ex[0] * ey[1] - ex[1] * ey[0];
    if (!t->planar && nfr > 3) {
        sub(v, t->pos[fr[3]], o);
        if (dot(v, ez) < 0.0f)
            for (int k = 0; k < 3; k++)
                ez[k] = -ez[k];
    }
    float est[SC_MAX_DRONES][3];
    for (int j = 0; j < t->n; j++) {
        swarm_vec3_t p;
        int stable = swarm_position(s, slot[j], &p);
        est[j][0] = p.x;
        est[j][1] = p.y;
        est[j][2] = p.z;
        sub(v, t->pos[j], o);
        float want[3] = {dot(v, ex), dot(v, ey), dot(v, ez)};
        sub(v, est[j], want);
        float err = sqrtf(dot(v, v));
        printf("%s: pos %d %d %d,%d,%d want %d,%d,%d %s\n", t->name, i, j, rnd_mm(p.x),
               rnd_mm(p.y), rnd_mm(p.z), rnd_mm(want[0]), rnd_mm(want[1]), rnd_mm(want[2]),
               stable ? "stable" : "unstable");
        CHECK(stable, "%s: drone %d's estimate of %d is not stable", t->name, i, j);
        CHECK(err * 1000.0f <= (float)t->pos_tol_mm,
              "%s: drone %d's estimate of %d is %d mm off the seed's frame", t->name, i, j,
              rnd_mm(err));
    }
    for (int j = 0; j < t->n; j++)
        for (int k = j + 1; k < t->n; k++) {
            float a[3], b[3];
            sub(a, est[j], est[k]);
            sub(b, t->pos[j], t->pos[k]);
            float e = sqrtf(dot(a, a)) - sqrtf(dot(b, b));
            CHECK(fabsf(e) * 1000.0f <= (float)t->dist_tol_mm,
                  "%s: drone %d's distance %d-%d is %d mm off", t->name, i, j, k, rnd_mm(e));
        }
}

static void finish(const sc_truth_t *t)
{
    for (int i = 0; i < t->n; i++)
        check_drone(t, i);
    printf("%s: ", t->name);
    st_cost_print(&cost_build);
    printf("%s: ", t->name);
    st_cost_print(&cost_rx);
    printf("%s: ", t->name);
    st_cost_print(&cost_house);
    printf("%s: ", t->name);
    st_cost_print(&cost_format);
    const swarm_stats_t *st = &ctx[0].stats;
    printf("%s: drone 0 stats rx %lu tof valid %lu invalid %lu clock accepted %lu rejected %lu\n",
           t->name, (unsigned long)st->rx_ok, (unsigned long)st->tof_valid,
           (unsigned long)st->tof_invalid, (unsigned long)st->clock_accepted,
           (unsigned long)st->clock_rejected);
}

/* ---- the harness's scenario ------------------------------------------- */

int sc_run_input(void)
{
    const sc_input_t *in = (const sc_input_t *)__heap_start;
    if (in->magic != SC_INPUT_MAGIC)
        return 0;
    static sc_truth_t t;
    static sc_event_t e;
    size_t room = (size_t)(__heap_end - __heap_start);
    CHECK(in->version == SC_INPUT_VERSION, "input version %lu", (unsigned long)in->version);
    CHECK(in->n_drones >= 2 && in->n_drones <= SC_INPUT_DRONES, "input drones %lu",
          (unsigned long)in->n_drones);
    CHECK(sizeof *in + (size_t)in->n_events * sizeof(sc_input_event_t) <= room,
          "input events %lu do not fit", (unsigned long)in->n_events);
    if (st_failures)
        return 1;
    t.name = "input";
    t.n = (int)in->n_drones;
    t.planar = (int)in->planar;
    t.tof_bound = in->tof_bound_milliticks;
    t.pos_tol_mm = in->pos_tol_mm;
    t.dist_tol_mm = in->dist_tol_mm;
    for (int i = 0; i < t.n; i++) {
        t.eui[i] = in->eui[i];
        for (int k = 0; k < 3; k++)
            t.pos[i][k] = (float)in->pos_mm[i][k] * 1e-3f;
        for (int j = 0; j < t.n; j++)
            t.true_tof[i][j] = in->true_tof_milliticks[i][j];
    }
    begin(&t);
    const sc_input_event_t *ev = (const sc_input_event_t *)(in + 1);
    for (uint32_t k = 0; k < in->n_events; k++) {
        e.sender = ev[k].sender;
        if (e.sender >= (uint32_t)t.n) {
            CHECK(0, "input event %lu: sender %lu", (unsigned long)k, (unsigned long)e.sender);
            return 1;
        }
        e.t_us = ev[k].t_us;
        e.tx = ev[k].tx_stamp;
        e.lost = ev[k].lost_mask;
        for (int q = 0; q < t.n; q++)
            e.rx[q] = ev[k].rx_stamp[q];
        event(&t, &e);
    }
    finish(&t);
    return 1;
}

/* ---- built-in scenarios -------------------------------------------------- */

/* Time is counted in 1/1024 of a tick; a drone's stamp of true time T is
 * floor(T·(1 + ppb·1e-9) / 1024 + phase) mod 2^40 (DESIGN.md §8's model). */
#define SUB 1024
static int32_t ppb[SC_MAX_DRONES];
static uint64_t phase[SC_MAX_DRONES];

static uint64_t stamp(int d, int64_t t_sub)
{
    int64_t local =
        t_sub + (t_sub / 1000000000) * ppb[d] + (t_sub % 1000000000) * ppb[d] / 1000000000;
    return ((uint64_t)(local / SUB) + phase[d]) & SWARM_STAMP_MASK;
}

/* Flight time over mm millimetres, in 1/1024 ticks. */
static int64_t flight_sub(int32_t mm)
{
    return (int64_t)mm * 63897600000LL * SUB / 299792458000LL;
}

static void generate(sc_truth_t *t, uint32_t duration_ms, uint32_t loss_permille, uint64_t seed)
{
    swarm_prng_t r;
    swarm_prng_seed(&r, seed);
    int32_t dist[SC_MAX_DRONES][SC_MAX_DRONES];
    for (int i = 0; i < t->n; i++) {
        t->eui[i] = (uint64_t)(i + 1);
        /* ±20 ppm clocks (the brief's worst case), phases anywhere; drone
         * 0's counter wraps 1 s into the run (§6.4.1). */
        ppb[i] = (int32_t)swarm_prng_below(&r, 40001) - 20000;
        phase[i] = ((uint64_t)swarm_prng_next(&r) << 8 ^ swarm_prng_next(&r)) & SWARM_STAMP_MASK;
    }
    phase[0] = (SWARM_STAMP_MASK + 1) - SWARM_TICKS_PER_SECOND;
    for (int i = 0; i < t->n; i++)
        for (int j = 0; j < t->n; j++) {
            float v[3];
            sub(v, t->pos[i], t->pos[j]);
            dist[i][j] = rnd_mm(sqrtf(dot(v, v)));
            int64_t f = flight_sub(dist[i][j]) * 1000 / SUB;
            t->true_tof[i][j] = (uint32_t)(f + f * ppb[i] / 1000000000);
        }
    begin(t);
    /* Each drone transmits when its own scheduler says (§6.5). */
    uint64_t next_ns[SC_MAX_DRONES];
    for (int i = 0; i < t->n; i++)
        next_ns[i] = (uint64_t)swarm_next_tx_delay_us(&ctx[i]) * 1000;
    static sc_event_t e;
    for (;;) {
        int d = 0;
        for (int i = 1; i < t->n; i++)
            if (next_ns[i] < next_ns[d])
                d = i;
        if (next_ns[d] >= (uint64_t)duration_ms * 1000000)
            break;
        /* True time in 1/1024 ticks: ns · 63.8976 · 1024. */
        int64_t t_sub = (int64_t)next_ns[d] * 654311424 / 10000;
        e.sender = (uint32_t)d;
        e.t_us = (uint32_t)(next_ns[d] / 1000);
        e.tx = stamp(d, t_sub);
        e.lost = 0;
        for (int q = 0; q < t->n; q++) {
            e.rx[q] = stamp(q, t_sub + flight_sub(dist[d][q]));
            if (q != d && swarm_prng_below(&r, 1000) < loss_permille)
                e.lost |= 1u << q;
        }
        event(t, &e);
        next_ns[d] += (uint64_t)swarm_next_tx_delay_us(&ctx[d]) * 1000;
    }
    finish(t);
}

void sc_run_builtin(void)
{
    static sc_truth_t t;
    /* Five drones in 3D: four to build the frame, one placed in it. */
    static const float tetra[5][3] = {{1.0f, 1.0f, 0.5f},
                                      {3.0f, 1.2f, 0.6f},
                                      {2.0f, 3.0f, 0.4f},
                                      {2.2f, 2.0f, 2.5f},
                                      {0.5f, 2.5f, 1.5f}};
    memset(&t, 0, sizeof t);
    t.name = "tetra5";
    t.n = 5;
    memcpy(t.pos, tetra, sizeof tetra);
    t.tof_bound = 2000;
    t.pos_tol_mm = 30;
    t.dist_tol_mm = 30;
    generate(&t, 3000, 100, 5);

    /* The thesis's table (§7.1, location 1): B at (0, 0), C at (1, 0), A
     * at (1, 0.5), in 2D. */
    static const float table[3][3] = {{1.0f, 0.5f, 0.0f}, {0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}};
    memset(&t, 0, sizeof t);
    t.name = "table3";
    t.n = 3;
    t.planar = 1;
    memcpy(t.pos, table, sizeof table);
    t.tof_bound = 2000;
    t.pos_tol_mm = 30;
    t.dist_tol_mm = 30;
    generate(&t, 3000, 100, 3);

    /* 17 drones: every context tracks the seed's 16 neighbours (§6.9). */
    swarm_prng_t r;
    swarm_prng_seed(&r, 17);
    memset(&t, 0, sizeof t);
    t.name = "swarm17";
    t.n = 17;
    for (int i = 0; i < t.n; i++)
        for (int k = 0; k < 3; k++)
            t.pos[i][k] = (float)swarm_prng_below(&r, 5000) * 1e-3f;
    t.tof_bound = 2000;
    t.pos_tol_mm = 50;
    t.dist_tol_mm = 50;
    generate(&t, 3000, 100, 17);
}
