/*
 * Swarm ranging of seed 003 (§5.2.2, §6.4, §6.6): DW1000 timestamp
 * arithmetic, the clock correction between two drones and the many-to-many
 * SDS-TWR time of flight of eq. 5.11.
 *
 * Everything here is integer ("fixed point where it matters"): a stamp has
 * 40 bits and a tick is 15.65 ps, so a single-precision float cannot even
 * hold a stamp, and the product reply x clock ratio must be exact to well
 * under a tick on ~1e9-tick intervals (a relative 1e-10): the clock
 * correction is kept as (ratio - 1) in units of 2^-40 and applied with
 * 64-bit integer products.
 */
#ifndef SWARM_RANGING_H
#define SWARM_RANGING_H

#include <stdint.h>

/* DW1000 system time: 40 bits of ticks of 1/(128 x 499.2 MHz) (§6.4). */
#define SWARM_STAMP_BITS 40
#define SWARM_STAMP_MASK ((UINT64_C(1) << SWARM_STAMP_BITS) - 1)
#define SWARM_TICKS_PER_SECOND UINT64_C(63897600000)
/* One tick in metres at the speed of light: 299 792 458 / 63.8976e9. */
#define SWARM_METRES_PER_TICK 0.004691763978616f
/* A TOF is valid when it is a distance between 0 and 10 m (§7.4):
 * 10 m / 4.6918 mm = 2131.4 ticks. */
#define SWARM_TOF_MAX_VALID 2131

/* Clock ratios are (ratio - 1) scaled by 2^SWARM_CLOCK_Q. */
#define SWARM_CLOCK_Q 40
/* Longest interval the ranging accepts between two stamps of one clock:
 * 2^35 ticks = 0.54 s. It keeps every product below 2^63 and is far above
 * the 50 ms longest transmission period of §6.5. */
#define SWARM_MAX_SPAN (UINT64_C(1) << 35)

/* later - earlier on the 40-bit counter: correct across one wrap
 * (§6.4.2: unsigned arithmetic truncated to the counter's width). */
static inline uint64_t swarm_stamp_since(uint64_t later, uint64_t earlier)
{
    return (later - earlier) & SWARM_STAMP_MASK;
}

/* The same on the 32-bit timestamps that travel in the packets (§6.4.2,
 * Table 6.2's truncation to the width of the type). */
static inline uint32_t swarm_packet_since(uint32_t later, uint32_t earlier)
{
    return later - earlier;
}

/* The same on any width up to 64 bits (Table 6.2 uses 8). */
static inline uint64_t swarm_since_bits(uint64_t later, uint64_t earlier, unsigned bits)
{
    uint64_t mask = bits >= 64 ? ~UINT64_C(0) : (UINT64_C(1) << bits) - 1;
    return (later - earlier) & mask;
}

/* A 32-bit packet interval is only known modulo 2^32 (0.0672 s, eq. 6.2).
 * When the same interval is also known roughly from a 40-bit local one
 * (`near`, within a clock ratio of it), the whole value is the one
 * congruent to `diff32` closest to `near`. This lifts the 0.0672 s limit
 * of §6.4.2 for every interval that has a local counterpart. */
uint64_t swarm_unwrap32(uint32_t diff32, uint64_t near);

/* The clock correction of one neighbour (§6.4.2). */
typedef struct {
    int64_t delta_q40; /* e = f_local / f_remote = 1 + delta_q40 / 2^40 */
    uint8_t have;      /* a value has been accepted */
    uint8_t bucket;    /* leaky bucket: accepted values in a row, max 4 */
} swarm_clock_t;

/* Filter settings of §6.4.2, in parts per billion. */
typedef struct {
    uint32_t clock_deviation_ppb; /* typical crystal error; limits 1 ± 2·dev */
    uint32_t accepted_noise_ppb;  /* accepted change from the last value (30) */
} swarm_clock_settings_t;

/* The candidate e - 1 = (local - remote) / remote for one interval seen by
 * both clocks, in 2^-40 units. Returns 0 (and leaves *out) when a span is
 * zero or longer than SWARM_MAX_SPAN. */
int swarm_clock_candidate(uint64_t local_span, uint64_t remote_span, int64_t *out);

/* Feed one candidate through the two filters of §6.4.2 (absolute limits,
 * then at most `accepted_noise` from the current value, averaged in).
 * The seed does not say how the first value is chosen nor how a wrong one
 * is left: the first candidate inside the limits is taken, and a leaky
 * bucket (4 accepted in a row at most; a rejection empties one; a
 * rejection with an empty bucket restarts from the candidate) lets a
 * genuine change of the ratio replace the old value.
 * Returns 1 when the candidate was used. */
int swarm_clock_update(swarm_clock_t *c, int64_t candidate, const swarm_clock_settings_t *s);

/* x · (1 + delta/2^40), rounded to the nearest tick: a remote interval in
 * local ticks (eq. 5.8). x < SWARM_MAX_SPAN. */
uint64_t swarm_clock_apply(uint64_t x, int64_t delta_q40);

/* Eq. 5.11: [tof]_M = ([t_round]_M - [t_reply]_X · e_MX) / 2 in local
 * ticks, rounded to the nearest tick (negative when the reply is longer
 * than the round). round and reply must be below SWARM_MAX_SPAN. */
int64_t swarm_tof_ticks(uint64_t round, uint64_t reply, int64_t delta_q40);

/* The TOF of a STATUS exchange from its four stamps, as received:
 *   local_tx  [t_tx M]_M   40-bit, when M sent the packet X answered
 *   remote_rx [t_rx M]_X   32-bit, when X received it
 *   remote_tx [t_tx X]_X   32-bit, when X sent its answer
 *   local_rx  [t_rx X]_M   40-bit, when M received that answer
 * The round is local (40 bits); the reply is unwrapped with it. Returns 0
 * and the TOF minus the antenna delay in *tof when it is valid (0–10 m,
 * §7.4), -1 when a span is out of range, -2 when the TOF is not valid. */
int swarm_exchange_tof(uint64_t local_tx, uint32_t remote_rx, uint32_t remote_tx, uint64_t local_rx,
                       int64_t delta_q40, int32_t antenna_delay, int32_t *tof);

#endif
