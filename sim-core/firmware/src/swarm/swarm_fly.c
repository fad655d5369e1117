/*
 * Four drones fly a square with seed 003's positioning running
 * (scenarios/swarm-flight.toml). Each takes off to 1 m (GET_STABLE), then
 * flies to the next corner of a 2 m square, clockwise, LAPS times, one PID
 * step at a time (RUN_SINGLE_STEP_PID, the thesis's single-step mode,
 * §4.2.1): between two steps the radio side of swarm_app.c runs (TX_DONE,
 * frames received, a STATUS packet if due, the 100 Hz estimates). All
 * four move together, so they stay 2 m apart. Then GO_DOWN.
 *
 * The corners are world coordinates, compiled in (the firmware has no way
 * to learn its start, as race.c's targets): drone EUI e starts on corner
 * e - 1 of (0,0), (2,0), (2,2), (0,2) (scenarios/worlds/swarm-flight.toml).
 * In a flying firmware the world is advanced to the end of each STM32 step
 * when it starts (docs/SWARM.md §4.2), so a transmission started during or
 * between steps would leave on the steps' common grid and collide with the
 * other drones'. Instead, before each step, a STATUS packet whose §6.5 time
 * falls inside the coming step is started with the DW1000's delayed send
 * (TX_DELAY, docs/SWARM.md §4.3) that places it at that time
 * (app_poll_ahead, with the mtime length of the previous step as the
 * look-ahead): the step lasts STEP_MS of world time but more of the core's
 * (the thesis's bookkeeping adds the core time between steps, ~7 ms per
 * step here), so the packet goes at the same fraction of the world's step;
 * a delay as long as the core's step would end past the world's step,
 * TX_DONE would come a step later and the next packet would go late. The
 * estimates' times (t=) are the core's (mtime), which in the thesis's
 * bookkeeping runs ahead of the world by the core time between steps, so
 * this build (-DAPP_WORLD_TIME) also prints world_us=, the world time of the
 * STM32's last sensor read (EST_TIME): the estimate is made between two
 * steps, from what the radio saw up to the end of the last one, at most one
 * step (STEP_MS of world time) after that read.
 */
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../radio/radio.h"
#include "../stm32.h"
#include "swarm_app.h"

#ifndef LAPS
#define LAPS 1
#endif
/* World time of one RUN_SINGLE_STEP_PID: the scenario's basicTimeStep
 * (scenarios/swarm-flight.toml timestep_ms). */
#ifndef STEP_MS
#define STEP_MS 4
#endif
#define SIDE 2.0
#define HEIGHT 1.0

static const double corner[4][2] = {{0, 0}, {SIDE, 0}, {SIDE, SIDE}, {0, SIDE}};

/* Legs flown: LAPS laps, or the run key firmware.swarm_fly_legs = N
 * (sim-core/src/kernel/firmware_params.rs writes it by its symbol; the
 * end-to-end test flies one leg). */
volatile int32_t swarm_fly_legs = 4 * LAPS;

/* One PID step; returns its status (RUN_SINGLE_STEP_PID, TARGET_REACHED
 * or BATTERY_LOW). */
static uint8_t pid_step(void)
{
    stm32_control = RUN_SINGLE_STEP_PID;
    uint8_t s;
    while ((s = stm32_status) != RUN_SINGLE_STEP_PID && s != TARGET_REACHED && s != BATTERY_LOW)
        ;
    stm32_status = 0;
    stm32_control = 0;
    return s;
}

int main(void)
{
    stm32_perform(INIT_PID);
    stm32_perform(GET_STABLE);
    radio_t uwb = RADIO_UWB;
    radio_init(&uwb); /* after INIT_PID: only switches the radio on */
    const uint64_t eui = radio_eui(&uwb);
    const uint64_t t0 = radio_now_cycles();
    swarm_settings_t set;
    swarm_default_settings(&set);
    set.planar = 1; /* all four at 1 m: the frame's plane */
    app_start(&uwb, eui, t0, &set);
    printf("[fly] EUI %u stable at 1 m, positioning on\n", (unsigned)eui);

    uint64_t step = 0; /* mtime length of the last PID step */
    const int first = (int)((eui > 0 ? eui - 1 : 0) % 4);
    int low = 0;
    for (int leg = 1; leg <= swarm_fly_legs && !low; leg++) {
        const int k = (first + leg) % 4;
        stm32_x = corner[k][0];
        stm32_y = corner[k][1];
        stm32_z = HEIGHT;
        stm32_perform(SET_TARGET);
        for (;;) {
            /* A transmission due within the coming step leaves at its time. */
            app_poll_ahead(step, (uint64_t)STEP_MS * 1000000u);
            const uint64_t before = radio_now_cycles();
            uint8_t s = pid_step();
            step = radio_now_cycles() - before;
            if (s == BATTERY_LOW)
                low = 1;
            if (s != RUN_SINGLE_STEP_PID)
                break;
        }
    }
    app_end();
    stm32_perform(GO_DOWN);
    return 0;
}
