/*
 * Hover for a fixed time, then land: the firmware of the swarm benchmark
 * (docs/SWARM.md, docs/COSIM.md "Several drones"). A variant of race.c's
 * continuous mode (-DCONTINUOUS): no camera, the STM32's RUN_PID flies on
 * its own (thesis §4.2.1, §5.2).
 *
 * GET_STABLE lifts the drone to 1 m above its start point and leaves that
 * point as the STM32's target; RUN_PID then holds it. Once the target has
 * been reached (Listing 4.3: target_cycles iterations inside the
 * tolerance), every RUN_PID returns after one iteration of one timestep, so
 * the loop below checks the time once per basicTimeStep. The time is the
 * core's own: mcycle/mcycleh at the platform's clock (the spinning on the
 * status register keeps the core awake, so mcycle follows platform time).
 * After HOVER_SECONDS of it the drone lands. The firmware never needs to
 * know where it starts, so one ELF serves every drone of a swarm.
 */
#include <stdint.h>
#include <stdio.h>

#include "cosim_regs.h"
#include "cycles.h"
#include "stm32.h"

#ifndef HOVER_SECONDS
#define HOVER_SECONDS 60
#endif

/* The core clock of sim-core's embedded Crazyflie platform file
 * (core.frequency, 250 MHz: DESIGN.md §4). A platform file with another
 * clock needs -DCORE_HZ=... to keep HOVER_SECONDS in seconds. */
#ifndef CORE_HZ
#define CORE_HZ 250000000ull
#endif

int main(void)
{
    printf("[hover] Hello from the virtual GAP8! Hovering for %d s\n", HOVER_SECONDS);
    stm32_perform(INIT_PID);
    stm32_perform(GET_STABLE);
    printf("[hover] Drone stable at 1 m\n");

    const uint64_t start = csr_mcycle64();
    const uint64_t span = (uint64_t)HOVER_SECONDS * CORE_HZ;
    int low_battery = 0;
    while (!low_battery && csr_mcycle64() - start < span) {
        stm32_control = RUN_PID;
        for (;;) {
            uint8_t status = stm32_status;
            if (status == RUN_PID)
                break;
            if (status == BATTERY_LOW) {
                low_battery = 1;
                printf("[hover] Low battery !\n");
                break;
            }
        }
        stm32_status = 0;
        stm32_control = 0;
    }
    printf("[hover] Held for %u ms of platform time\n",
           (unsigned)((csr_mcycle64() - start) / (CORE_HZ / 1000u)));

    printf("[hover] Making the drone descend ... ");
    stm32_perform(GO_DOWN);
    printf("ground reached!\n");
    stm32_control = PRINT_SIMUL_TIME;
    while (stm32_status != PRINT_SIMUL_TIME)
        ;
    return 0;
}
