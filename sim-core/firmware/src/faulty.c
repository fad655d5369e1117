/*
 * Firmware that misuses the peripherals, for the platform's bad-input tests.
 * Built twice:
 *   -DBAD_COMMAND  writes a code no device knows into the STM32's control
 *                  register (after a correct INIT_PID);
 *   -DBAD_READ     reads past the end of the peripheral window.
 * The platform must stop with a clear message naming the problem.
 */
#include <stdio.h>

#include "cosim_regs.h"

int main(void)
{
    REG8(STM32_CTRL_REG_OFFSET) = INIT_PID;
    while (REG8(STM32_STAT_REG_OFFSET) != INIT_PID)
        ;
    REG8(STM32_STAT_REG_OFFSET) = 0;
    REG8(STM32_CTRL_REG_OFFSET) = 0;
#if defined(BAD_COMMAND)
    printf("[GVoC] writing command 252 to the STM32\n");
    REG8(STM32_CTRL_REG_OFFSET) = 252;
#elif defined(BAD_READ)
    printf("[GVoC] reading past the peripheral window\n");
    volatile uint32_t v = *(volatile uint32_t *)(AXI_BASE + 102428);
    printf("read %lu\n", (unsigned long)v);
#endif
    return 0;
}
