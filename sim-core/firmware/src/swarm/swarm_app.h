/*
 * The application side of seed 003's positioning on the UWB radio
 * (docs/SWARM_FIRMWARE.md §4), as a poll function so that both a carried
 * drone (swarm_node.c: wfi until the next event) and a flying one
 * (swarm_fly.c: between the STM32's PID steps) can run it:
 *
 *   app_start(uwb, eui, t0, settings)  receiver on, first transmission drawn
 *   app_next_wake()                    mtime of the next timer event
 *   app_poll()                         TX_DONE, every frame received, a
 *                                      transmission if due (§6.5), the 100 Hz
 *                                      estimates line, the per-second load line
 *   app_poll_ahead(c, w)               app_poll, and a transmission due within
 *                                      the next c cycles is started now with
 *                                      the delay that places it as far into
 *                                      the next w ns of world time
 *   app_end()                          the "swarm end" counters line
 *
 * Times are mtime cycles (core cycles at APP_CORE_HZ); t0 is the mtime of
 * INIT_DONE, the origin of the printed times.
 */
#ifndef SWARM_APP_H
#define SWARM_APP_H

#include <stdint.h>

#include "../radio/radio.h"
#include "swarm.h"

/* The core clock of sim-core's embedded Crazyflie platform (DESIGN.md §4):
 * mtime counts core cycles. */
#ifndef APP_CORE_HZ
#define APP_CORE_HZ 250000000ull
#endif

void app_start(const radio_t *uwb, uint64_t eui, uint64_t t0, const swarm_settings_t *set);
uint64_t app_next_wake(void);
void app_poll(void);
void app_poll_ahead(uint64_t ahead, uint64_t world_ns);
void app_end(void);
/* Sleeps in wfi until mtime reaches t. */
void app_sleep_until(uint64_t t);

#endif
