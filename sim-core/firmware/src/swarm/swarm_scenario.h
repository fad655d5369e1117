/*
 * Several drones' swarm contexts in one program, exchanging real STATUS
 * packets through the full API (build, tx done, rx) with stamps either
 * generated here or supplied by the test harness (sim-core's
 * tests/swarm_firmware.rs writes them, computed with the world's
 * protocol::radio::dw1000_stamp, into the unused heap before the run).
 */
#ifndef SWARM_SCENARIO_H
#define SWARM_SCENARIO_H

#include <stdint.h>

/* Drones of a scenario run here (17: every context sees 16 neighbours). */
#define SC_MAX_DRONES 17
/* Drones of a scenario supplied by the harness. */
#define SC_INPUT_DRONES 8
#define SC_INPUT_MAGIC 0x4e495753u /* "SWIN" */
#define SC_INPUT_VERSION 1

/* The harness's input, little endian, at __heap_start. */
typedef struct {
    uint32_t magic, version;
    uint32_t n_drones, n_events;
    uint32_t planar;
    uint32_t tof_bound_milliticks; /* allowed |TOF - true| */
    uint32_t pos_tol_mm;           /* allowed position error in the seed's frame */
    uint32_t dist_tol_mm;          /* allowed error of estimated distances */
    uint64_t eui[SC_INPUT_DRONES];
    int32_t pos_mm[SC_INPUT_DRONES][3];
    /* true TOF [measurer][other] in the measurer's ticks, x1000 */
    uint32_t true_tof_milliticks[SC_INPUT_DRONES][SC_INPUT_DRONES];
} sc_input_t;

typedef struct {
    uint32_t sender;
    uint32_t t_us; /* world time of the transmission, µs */
    uint64_t tx_stamp;
    uint64_t rx_stamp[SC_INPUT_DRONES];
    uint32_t lost_mask; /* bit q: drone q did not receive it */
    uint32_t pad;
} sc_input_event_t;

/* The harness (tests/swarm_firmware.rs) writes these layouts byte for byte. */
_Static_assert(sizeof(sc_input_t) == 448, "sc_input_t layout");
_Static_assert(sizeof(sc_input_event_t) == 88, "sc_input_event_t layout");

/* Run the harness's scenario if one was supplied (returns 1), else 0. */
int sc_run_input(void);
/* Run the built-in scenarios (stamps generated here with the firmware's
 * own transmission scheduling) and measure costs. */
void sc_run_builtin(void);

#endif
