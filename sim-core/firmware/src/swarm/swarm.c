/* One drone's side of seed 003's relative positioning: see swarm.h. */
#include "swarm_nodes.h"

#include <string.h>

/* The antenna delay the firmware subtracts from every TOF, DW1000 ticks:
 * the run key firmware.swarm_antenna_delay_ticks = N writes it by its
 * symbol (sim-core/src/kernel/firmware_params.rs). 0 for the world's
 * "ideal" radio profile, whose stamps carry no antenna delay; seed 003
 * §6.4.2's one constant, 515.7 ns = 32 952 ticks of 15.65 ps, for the
 * "dw1000" profile, whose chips each have their own delays (DESIGN.md §16). */
/* In .data: a zero-initialised global would sit in .bss, which the start
 * file clears after the kernel has written the parameter. */
__attribute__((section(".data"))) volatile int32_t swarm_antenna_delay_ticks = 0;

void swarm_default_settings(swarm_settings_t *s)
{
    memset(s, 0, sizeof *s);
    s->meas_std = 0.25f;   /* §7.3 */
    s->stable_std = 0.25f; /* §6.8.3 */
    /* §6.8.3's "maximum allowed" σ: the Crazyflie estimator bounds a
     * position to 100 m. */
    s->init_std = 100.0f;
    /* The arbitrary values that hold the frame: 1 cm, firm against the
     * 0.25 m of a distance, not so firm as to make P singular. */
    s->pseudo_std = 0.01f;
    /* The frame's arbitrary values stay once it is built. The seed's text
     * drops them (§6.8.4), but its Table 7.1 shows the references with Y
     * exactly 0 and a standard deviation of 0, and without them nothing
     * holds the frame: it drifts and turns with the ranging noise. */
    s->keep_frame = 1;
    /* Covariance correction: a position random walk of 0.1 m/√s lets a
     * filter follow a drone carried at walking pace (§7.3 section D)
     * while a measurement of σ 0.25 moves it by a few percent of its
     * innovation. Velocity only matters with the prediction step. */
    s->kf.process_noise_pos = 0.01f;
    s->kf.process_noise_vel = 0.01f;
    s->kf.max_position = 100.0f;
    s->kf.max_velocity = 10.0f;
    s->kf.prediction = 0; /* §6.8.2 */
    /* §6.4.1: the DW1000's crystal is ±25 ppm untrimmed (the simulated
     * clocks are not trimmed); limits 1 ± 2·25 ppm. */
    s->clock.clock_deviation_ppb = 25000;
    s->clock.accepted_noise_ppb = 30; /* §6.4.2: ±0.03e-6 */
    /* The "ideal" simulated DW1000 stamps the arrival itself (DESIGN.md
     * §8): no antenna delay; the thesis's hardware needed ≈ 515.7 ns
     * (§6.4.2), as the "dw1000" profile does. */
    s->antenna_delay = swarm_antenna_delay_ticks;
    s->neighbour_timeout_us = 1000000;
    /* A reference closer than this to the origin, the X axis or the XY
     * plane is passed over (see assign_references). */
    s->frame_min_sep = 0.2f;
    s->swarm_rate_hz = 400;
    s->min_rate_hz = 20;
    s->max_rate_hz = 100;
}

uint8_t swarm_id_from_eui(uint64_t eui)
{
    uint8_t id = 0;
    for (int i = 0; i < 8; i++)
        id ^= (uint8_t)(eui >> (8 * i));
    return id;
}

void swarm_init(swarm_t *s, const swarm_settings_t *set, uint64_t eui)
{
    memset(s, 0, sizeof *s);
    s->set = *set;
    s->eui = eui;
    swarm_prng_seed(&s->prng, eui);
    s->id = swarm_id_from_eui(eui);
    s->building = 1;
}
/* ---- nodes and the TOF table ------------------------------------------ */

uint16_t swarm_tof(const swarm_t *s, int a, int b)
{
    if (a == b || a < 0 || b < 0 || a >= SWARM_NODES || b >= SWARM_NODES)
        return 0;
    return s->tof[swarm_pair_index(a, b)];
}

static void set_tof(swarm_t *s, int a, int b, uint16_t t)
{
    if (a != b)
        s->tof[swarm_pair_index(a, b)] = t;
}

int swarm_find(const swarm_t *s, uint8_t id)
{
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++)
        if (s->nb[i].used && s->nb[i].id == id)
            return i;
    return -1;
}

unsigned swarm_neighbour_count(const swarm_t *s)
{
    unsigned n = 0;
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++)
        n += s->nb[i].used;
    return n;
}

const swarm_kf_t *swarm_filter(const swarm_t *s, int node)
{
    return node == SWARM_SELF ? &s->self_kf : &s->nb[node].kf;
}

int swarm_position(const swarm_t *s, int node, swarm_vec3_t *p)
{
    *p = swarm_kf_position(swarm_filter(s, node));
    return swarm_placed(s, node);
}

/* ---- transmission (§6.5, §6.7) ---------------------------------------- */

uint32_t swarm_next_tx_delay_us(swarm_t *s)
{
    uint32_t f = s->set.swarm_rate_hz / (swarm_neighbour_count(s) + 1);
    if (f > s->set.max_rate_hz)
        f = s->set.max_rate_hz;
    if (f < s->set.min_rate_hz)
        f = s->set.min_rate_hz;
    uint32_t avg = 1000000 / f;
    return avg / 2 + swarm_prng_below(&s->prng, avg);
}

size_t swarm_build_status(swarm_t *s, uint8_t *buf, size_t cap)
{
    swarm_status_t p;
    p.source_id = s->id;
    p.seq = s->next_seq;
    p.tx_valid = s->have_prev_tx && s->prev_tx_seq == (uint8_t)(p.seq - 1);
    p.tx = p.tx_valid ? (uint32_t)s->prev_tx : 0;
    /* Entries: the receptions reported pair with our previous
     * transmission (the one whose stamp is in the header); then take the
     * snapshot the next packet will report. With more neighbours than fit
     * (16 > 14), the packets take turns from a rotating start. */
    unsigned count = 0;
    for (int k = 0; k < SWARM_MAX_NEIGHBOURS; k++) {
        int i = (s->rotate + k) % SWARM_MAX_NEIGHBOURS;
        swarm_neighbour_t *n = &s->nb[i];
        if (!n->used || !n->have_report || count >= SWARM_MAX_ENTRIES)
            continue;
        p.entry[count++] = (swarm_entry_t){.id = n->id,
                                           .seq = n->report_seq,
                                           .rx = n->report_rx,
                                           .tof = swarm_tof(s, SWARM_SELF, i)};
    }
    p.count = (uint8_t)count;
    size_t len = swarm_status_write(&p, buf, cap);
    if (len == 0)
        return 0;
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++) {
        swarm_neighbour_t *n = &s->nb[i];
        n->have_report = n->used && n->have_last;
        n->report_seq = n->last_seq;
        n->report_rx = (uint32_t)n->last_rx;
    }
    s->rotate = (uint8_t)((s->rotate + SWARM_MAX_ENTRIES) % SWARM_MAX_NEIGHBOURS);
    s->have_built = 1;
    s->built_seq = p.seq;
    s->next_seq++;
    s->stats.tx_built++;
    return len;
}

void swarm_tx_done(swarm_t *s, uint64_t tx_stamp)
{
    if (!s->have_built)
        return;
    tx_stamp &= SWARM_STAMP_MASK;
    s->have_built = 0;
    s->have_prev_tx = 1;
    s->prev_tx_seq = s->built_seq;
    s->prev_tx = tx_stamp;
    s->txh[s->txh_next].stamp = tx_stamp;
    s->txh[s->txh_next].seq = s->built_seq;
    s->txh[s->txh_next].valid = 1;
    s->txh_next = (uint8_t)((s->txh_next + 1) % SWARM_TX_HISTORY);
    s->stats.tx_done++;
}

static int own_tx_stamp(const swarm_t *s, uint8_t seq, uint64_t *stamp)
{
    for (int i = 0; i < SWARM_TX_HISTORY; i++)
        if (s->txh[i].valid && s->txh[i].seq == seq) {
            *stamp = s->txh[i].stamp;
            return 1;
        }
    return 0;
}

/* ---- identifiers (§6.2) ------------------------------------------------ */

static void regenerate_id(swarm_t *s, const swarm_status_t *p)
{
    for (;;) {
        uint8_t c = (uint8_t)swarm_prng_next(&s->prng);
        int taken = c == p->source_id || swarm_find(s, c) >= 0;
        for (unsigned i = 0; i < p->count && !taken; i++)
            taken = p->entry[i].id == c;
        if (!taken) {
            s->id = c;
            return;
        }
    }
}

/* ---- neighbours -------------------------------------------------------- */
static void remove_neighbour(swarm_t *s, int i)
{
    for (int b = 0; b < SWARM_NODES; b++)
        set_tof(s, i, b, 0);
    int was_ref = swarm_role_of(s, i) >= 0;
    memset(&s->nb[i], 0, sizeof s->nb[i]);
    s->stats.removed++;
    if (was_ref)
        swarm_positions_reset(s);
}

void swarm_housekeeping(swarm_t *s, uint32_t now_us)
{
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++)
        if (s->nb[i].used && now_us - s->nb[i].last_heard_us > s->set.neighbour_timeout_us)
            remove_neighbour(s, i);
}

static int add_neighbour(swarm_t *s, uint8_t id)
{
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++) {
        swarm_neighbour_t *n = &s->nb[i];
        if (n->used)
            continue;
        memset(n, 0, sizeof *n);
        n->used = 1;
        n->id = id;
        n->order = s->next_order++;
        return i;
    }
    return -1;
}
/* ---- reception (§5.2.2, §5.3.1, §6.1-§6.6) ---------------------------- */

int swarm_on_rx(swarm_t *s, const uint8_t *buf, size_t len, uint64_t rx_stamp, int32_t rssi_cdbm,
                uint32_t now_us)
{
    swarm_status_t p;
    int r = swarm_status_read(&p, buf, len);
    if (r == SWARM_PARSE_SHORT) {
        s->stats.rx_short++;
        return SWARM_RX_SHORT;
    }
    if (r == SWARM_PARSE_NOT_STATUS) {
        s->stats.rx_not_status++;
        return SWARM_RX_NOT_STATUS;
    }
    if (r != SWARM_PARSE_OK) {
        s->stats.rx_bad_length++;
        return SWARM_RX_BAD_LENGTH;
    }
    if (p.source_id == s->id) {
        regenerate_id(s, &p);
        s->stats.rx_id_clash++;
        return SWARM_RX_ID_CLASH;
    }
    rx_stamp &= SWARM_STAMP_MASK;
    int x = swarm_find(s, p.source_id);
    if (x < 0) {
        x = add_neighbour(s, p.source_id);
        if (x < 0) {
            s->stats.rx_table_full++;
            return SWARM_RX_TABLE_FULL;
        }
    } else if ((uint8_t)(p.seq - s->nb[x].expected_seq) > 250) {
        /* §6.3: 1 to 5 below the expected number: a late reflection. */
        s->stats.rx_reflection++;
        return SWARM_RX_REFLECTION;
    }
    swarm_neighbour_t *n = &s->nb[x];
    n->expected_seq = (uint8_t)(p.seq + 1);
    n->last_heard_us = now_us;
    n->rssi_cdbm = rssi_cdbm;

    /* The header's tx completes the previous packet of X: its reception
     * stamp is ours, its transmission stamp is now known. */
    if (p.tx_valid && n->have_last && n->last_seq == (uint8_t)(p.seq - 1)) {
        if (n->have_pair) {
            uint64_t local = swarm_stamp_since(n->last_rx, n->pair_rx);
            uint64_t remote = swarm_unwrap32(swarm_packet_since(p.tx, n->pair_tx), local);
            int64_t cand;
            if (swarm_clock_candidate(local, remote, &cand) &&
                swarm_clock_update(&n->clock, cand, &s->set.clock))
                s->stats.clock_accepted++;
            else
                s->stats.clock_rejected++;
        }
        n->have_pair = 1;
        n->pair_tx = p.tx;
        n->pair_rx = n->last_rx;
        /* Eq. 5.11 with the entry X wrote about us. */
        for (unsigned i = 0; i < p.count && n->clock.have; i++) {
            if (p.entry[i].id != s->id)
                continue;
            uint64_t local_tx;
            int32_t tof;
            if (own_tx_stamp(s, p.entry[i].seq, &local_tx) &&
                swarm_exchange_tof(local_tx, p.entry[i].rx, p.tx, n->last_rx, n->clock.delta_q40,
                                   s->set.antenna_delay, &tof) == 0) {
                /* 0 is "unknown" in the table and the packets. */
                set_tof(s, SWARM_SELF, x, (uint16_t)(tof > 0 ? tof : 1));
                s->stats.tof_valid++;
            } else {
                s->stats.tof_invalid++;
            }
        }
    }
    /* §5.3.1: the TOFs X measured to the others, in our ticks. Only
     * between known nodes, so a removed neighbour does not come back. */
    for (unsigned i = 0; i < p.count; i++) {
        int y = swarm_find(s, p.entry[i].id);
        if (y < 0 || p.entry[i].tof == 0)
            continue;
        uint64_t t = n->clock.have ? swarm_clock_apply(p.entry[i].tof, n->clock.delta_q40)
                                   : p.entry[i].tof;
        set_tof(s, x, y, (uint16_t)(t > 0xffff ? 0xffff : t));
    }
    n->have_last = 1;
    n->last_seq = p.seq;
    n->last_rx = rx_stamp;
    s->stats.rx_ok++;

    swarm_positions_update(s, x, now_us);
    return SWARM_RX_OK;
}

/* ---- output ------------------------------------------------------------ */

/* A bounded writer: printf's machinery costs ~8000 cycles per node on this
 * core; these few lines a tenth of it. */
typedef struct {
    char *buf;
    size_t len, room;
} out_t;

static void put_char(out_t *o, char c)
{
    if (o->len < o->room)
        o->buf[o->len++] = c;
}

static void put_str(out_t *o, const char *str)
{
    while (*str)
        put_char(o, *str++);
}

static void put_uint(out_t *o, uint32_t u)
{
    char tmp[10];
    int n = 0;
    do {
        tmp[n++] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    while (n)
        put_char(o, tmp[--n]);
}

static void put_int(out_t *o, int32_t v)
{
    if (v < 0)
        put_char(o, '-');
    put_uint(o, v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v);
}

static int32_t mm(float m)
{
    float v = m * 1000.0f;
    return (int32_t)(v >= 0.0f ? v + 0.5f : v - 0.5f);
}

static void put_node(out_t *o, const swarm_t *s, int node)
{
    const swarm_kf_t *kf = swarm_filter(s, node);
    swarm_vec3_t p = swarm_kf_position(kf);
    put_char(o, ' ');
    put_int(o, node == SWARM_SELF ? s->id : s->nb[node].id);
    put_char(o, '=');
    put_int(o, mm(p.x));
    put_char(o, ',');
    put_int(o, mm(p.y));
    put_char(o, ',');
    put_int(o, mm(p.z));
    put_char(o, ',');
    put_int(o, kf->init ? mm(swarm_kf_position_std(kf)) : -1);
    put_char(o, ',');
    put_char(o, !kf->init ? '-' : swarm_kf_is_stable(kf, s->set.stable_std) ? 's' : 'u');
}

size_t swarm_format_estimates(const swarm_t *s, uint32_t now_ms, char *buf, size_t cap)
{
    if (cap < 2)
        return 0;
    /* Room for the newline and the terminating zero. */
    out_t o = {buf, 0, cap - 2};
    put_str(&o, "swarm t=");
    put_uint(&o, now_ms);
    put_str(&o, " id=");
    put_int(&o, s->id);
    put_str(&o, s->building ? " frame=building n=" : " frame=built n=");
    put_uint(&o, swarm_neighbour_count(s));
    put_node(&o, s, SWARM_SELF);
    for (int i = 0; i < SWARM_MAX_NEIGHBOURS; i++)
        if (s->nb[i].used)
            put_node(&o, s, i);
    buf[o.len++] = '\n';
    buf[o.len] = 0;
    return o.len;
}
