/*
 * The firmware of a drone flown over CRTP (cflib, cfclient; docs/CFLIB.md):
 * on a real Crazyflie the STM32 serves the radio link and the AI deck's
 * GAP8 runs its own application. Here the core hands the link to the STM32
 * model (EXT_CRTP, sim-core/src/peripherals/stm32/crtp/) after INIT_PID and
 * sleeps until the client has gone; the STM32 then STOPs the drone.
 */
#include <stdio.h>

#include "../cosim_regs.h"
#include "../stm32.h"

int main(void)
{
    stm32_perform(INIT_PID);
    printf("[crtp] serving the CRTP link\n");
    uint32_t s = stm32_ext(EXT_CRTP);
    if (s != EXT_CRTP) {
        printf("[crtp] EXT_CRTP refused (is sim-core run with --crtp?)\n");
        return 1;
    }
    printf("[crtp] link closed, drone stopped\n");
    return 0;
}
