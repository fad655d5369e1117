/*
 * Self-tests of the STM32 extension (cosim_regs.h, "STM32 extension";
 * sim-core/src/peripherals/stm32/motion.rs), flown against the real world:
 *
 * -DMOTION_VELOCITY: a refused command (EXT_ERROR), take-off to 1 m, a
 *   body-frame velocity set-point of 0.2 m/s forward for VELOCITY_ITERS
 *   iterations of 32 ms, hover, land (the drone STOPs at the end of EXT_LAND).
 * -DMOTION_HEADING: the race's position controller with a heading target:
 *   turn from +y to +x (yaw 0) and fly to a target 1 m ahead, then GO_DOWN.
 *
 * Positions are printed in mm and angles in mrad (integers: no float printf).
 */
#include <stdio.h>

#include "../cosim_regs.h"
#include "../stm32.h"

#ifndef VELOCITY_ITERS
#define VELOCITY_ITERS 156 /* 156 x 32 ms = 4.992 s */
#endif

/* One 32 ms iteration: ITER_ADVANCE + 25 ms, then the PID's 7 ms (at a
 * 32 ms basicTimeStep the world steps once). Returns the status. */
static uint8_t iteration(void) { return stm32_iteration(25); }

static int mm(double v) { return (int)(v * 1000.0 + (v < 0 ? -0.5 : 0.5)); }

static void print_estimate(const char *what)
{
    printf("[motion] %s: est %d %d %d mm yaw %d mrad, ranges F %d B %d L %d R %d mm\n", what,
           mm(REGF64(STM32_EST_X_OFFSET)), mm(REGF64(STM32_EST_Y_OFFSET)),
           mm(REGF64(STM32_EST_Z_OFFSET)), mm(REGF64(STM32_EST_YAW_OFFSET)),
           mm(REGF64(STM32_RANGE_FRONT_OFFSET)), mm(REGF64(STM32_RANGE_BACK_OFFSET)),
           mm(REGF64(STM32_RANGE_LEFT_OFFSET)), mm(REGF64(STM32_RANGE_RIGHT_OFFSET)));
}

int main(void)
{
    stm32_perform(INIT_PID);
    print_estimate("start");
#if defined(MOTION_VELOCITY)
    if (stm32_ext(99) == EXT_ERROR)
        printf("[motion] bad command -> EXT_ERROR\n");
    REGF64(STM32_CMD_HEIGHT_OFFSET) = 1.0;
    if (stm32_ext(EXT_TAKEOFF) != EXT_TAKEOFF)
        return 1;
    print_estimate("took off");
    REGF64(STM32_CMD_VX_OFFSET) = 0.2;
    REGF64(STM32_CMD_VY_OFFSET) = 0.0;
    REGF64(STM32_CMD_YAW_RATE_OFFSET) = 0.0;
    if (stm32_ext(EXT_SET_VELOCITY) != EXT_SET_VELOCITY)
        return 2;
    print_estimate("velocity start");
    for (int i = 0; i < VELOCITY_ITERS; i++)
        if (iteration() != RUN_SINGLE_STEP_PID)
            return 3;
    print_estimate("velocity end");
    REGF64(STM32_CMD_VX_OFFSET) = 0.0;
    if (stm32_ext(EXT_SET_VELOCITY) != EXT_SET_VELOCITY)
        return 4;
    for (int i = 0; i < 60; i++)
        if (iteration() != RUN_SINGLE_STEP_PID)
            return 5;
    print_estimate("hover");
    if (stm32_ext(EXT_LAND) != EXT_LAND)
        return 6;
    print_estimate("landed");
#elif defined(MOTION_HEADING)
    stm32_perform(GET_STABLE);
    REGF64(STM32_CMD_YAW_OFFSET) = 0.0;
    if (stm32_ext(EXT_SET_HEADING) != EXT_SET_HEADING)
        return 1;
    REGF64(STM32_TARGET_POS_X_OFFSET) = -1.6;
    REGF64(STM32_TARGET_POS_Y_OFFSET) = 0.0;
    REGF64(STM32_TARGET_POS_Z_OFFSET) = 1.0;
    stm32_perform(SET_TARGET);
    int n = 0;
    while (iteration() != TARGET_REACHED)
        n++;
    printf("[motion] target reached after %d iterations\n", n);
    print_estimate("at target");
    stm32_perform(GO_DOWN);
#endif
    printf("[motion] done\n");
    return 0;
}
