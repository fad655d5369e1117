/*
 * The thesis's GVSoC program (§4.3, Algorithm 4, Appendix D): the drone
 * takes off, flies through the 10 gates NUM_OF_CIRCUIT_LOOPS times (or, built
 * with -DCORNERS_TEST=N, to the corners of the map; with -DHOVER_TEST, holds
 * the start point until the battery is low; with -DSHORT_TEST, one nearby
 * target; with -DCONTINUOUS, the STM32's RUN_PID flies each leg without
 * the camera loop), lands and prints the
 * simulated time. Every operation uses the register protocol of Listing 4.6:
 * write the opcode to the control register, poll the status register until
 * it shows the same code, then clear both.
 */
#include <stdio.h>

#include "cosim_regs.h"

#ifndef NUM_OF_CIRCUIT_LOOPS
#define NUM_OF_CIRCUIT_LOOPS 1
#endif

/* Time the GAP8 spends in its (not simulated) neural network per image,
 * from GreenWaves' measurement the thesis uses (§4.2.4): 10 ms. */
#ifndef INFERENCE_MS
#define INFERENCE_MS 10
#endif

#define camera_control REG8(CAMERA_CTRL_REG_OFFSET)
#define camera_status REG8(CAMERA_STAT_REG_OFFSET)
#define stm32_control REG8(STM32_CTRL_REG_OFFSET)
#define stm32_status REG8(STM32_STAT_REG_OFFSET)
#define stm32_x REGF64(STM32_TARGET_POS_X_OFFSET)
#define stm32_y REGF64(STM32_TARGET_POS_Y_OFFSET)
#define stm32_z REGF64(STM32_TARGET_POS_Z_OFFSET)

static int target_reached = 0;
static int low_battery = 0;
static int target_point = 1;

/* Listing 4.6. */
static void perform(uint8_t op)
{
    stm32_control = op;
    while (stm32_status != op)
        ;
    stm32_status = 0;
    stm32_control = 0;
}

__attribute__((unused)) static void get_image(void)
{
    camera_control = GET_IMAGE;
    while (camera_status != GET_IMAGE)
        ;
    camera_status = 0;
    camera_control = 0;
}

/* ITER_ADVANCE: a value v > 10 advances both simulations by v - 10 ms. */
__attribute__((unused)) static void advance_simul(uint8_t ms)
{
    stm32_control = (uint8_t)(ITER_ADVANCE + ms);
    while (stm32_status != ITER_ADVANCE)
        ;
    stm32_status = 0;
    stm32_control = 0;
}

__attribute__((unused)) static void run_single_pid_iter(void)
{
    stm32_control = RUN_SINGLE_STEP_PID;
    for (;;) {
        uint8_t status = stm32_status;
        if (status == RUN_SINGLE_STEP_PID)
            return;
        if (status == BATTERY_LOW) {
            low_battery = 1;
            printf("\n[GVoC] Low battery !\n");
            return;
        }
        if (status == TARGET_REACHED) {
            target_reached = 1;
            return;
        }
    }
}

__attribute__((unused)) static void set_target(double x, double y, double z)
{
    if (!low_battery) {
        printf("\n[GVoC] New destination: point %d...", target_point);
        target_point += 1;
        stm32_x = x;
        stm32_y = y;
        stm32_z = z;
        perform(SET_TARGET);
#ifdef CONTINUOUS
        /* The STM32 flies to the target on its own (RUN_PID, the thesis's
         * PID_loop, §4.2.1 and §5.2): no image, no per-iteration polling. */
        stm32_control = RUN_PID;
        for (;;) {
            uint8_t status = stm32_status;
            if (status == RUN_PID)
                break;
            if (status == BATTERY_LOW) {
                low_battery = 1;
                break;
            }
        }
#else
        while (!target_reached && !low_battery) {
            get_image();
            advance_simul(INFERENCE_MS);
            run_single_pid_iter();
        }
#endif
        target_reached = 0;
        stm32_control = 0;
        stm32_status = 0;
        if (!low_battery)
            printf("reached!\n");
    } else {
        printf("\n[GVoC] Skipping gate %d: LOW BATTERY", target_point);
        target_point += 1;
        stm32_control = SKIP_TARGET;
        stm32_control = 0;
    }
}

int main(void)
{
    printf("[GVoC] Hello from the virtual GAP8! Starting the simulation\n");
    perform(INIT_PID);
    printf("[GVoC] PID initialised\n");
    perform(GET_STABLE);
    printf("[GVoC] Drone stable at 1 m\n");

#if defined(HOVER_TEST)
    /* Hover endurance: hold the start point at 1 m, one image + inference +
     * PID iteration every cycle, until the STM32 reports a low battery. */
    printf("[GVoC] Hovering until the battery is low\n");
    stm32_x = -2.6;
    stm32_y = 0;
    stm32_z = 1;
    perform(SET_TARGET);
    while (!low_battery) {
        get_image();
        advance_simul(INFERENCE_MS);
        run_single_pid_iter();
        if (target_reached) {
            /* Keep hovering on the same target. */
            target_reached = 0;
            stm32_status = 0;
        }
    }
    stm32_control = 0;
    stm32_status = 0;
#elif defined(SHORT_TEST)
    /* A short flight for tests: one target a metre away (SHORT_Y), then
     * land. */
#ifndef SHORT_Y
#define SHORT_Y 1.0
#endif
    set_target(-2.6, SHORT_Y, 1.0);
#elif defined(CORNERS_TEST)
#if CORNERS_TEST > 0
    printf("[GVoC] Reaching the first target corner\n");
    set_target(-1, 11, 1.15);
#endif
#if CORNERS_TEST > 1
    printf("[GVoC] Reaching the second target corner\n");
    set_target(17, 11, 1.15);
#endif
#if CORNERS_TEST > 2
    printf("[GVoC] Reaching the third target corner\n");
    set_target(17, -11, 1.15);
#endif
#if CORNERS_TEST > 3
    printf("[GVoC] Reaching the fourth target corner\n");
    set_target(-1, -11, 1.15);
    set_target(-2.6, 0, 1);
#endif
#else
    for (int i = 0; i < NUM_OF_CIRCUIT_LOOPS; i++) {
        set_target(-0.8, 1.5, 1.00);
        set_target(2, -0.4, 1.00);
        set_target(4.7, 1.7, 1.00);
        set_target(7.7, 3.1, 1.00);
        set_target(9.8, 2, 1.00);
        set_target(11.3, -3.5, 1.00);
        set_target(9.4, -6.4, 2.15);
        set_target(5.3, -6.5, 3.15);
        set_target(1.6, -5.8, 1.65);
        set_target(-0.3, -4.7, 1.35);
        set_target(-2.6, 0, 1);
    }
#endif

    printf("\n[GVoC] Making the drone descend ... ");
    perform(GO_DOWN);
    printf("ground reached!\n");
    printf("\n[GVoC] End of simulation! \n[GVoC] Bye from GVSoC!\n");
    /* As in the thesis, no reset of the registers: the simulation ends. */
    stm32_control = PRINT_SIMUL_TIME;
    while (stm32_status != PRINT_SIMUL_TIME)
        ;
    /* A low battery is an outcome of the run, not a failure of the program. */
    return 0;
}
