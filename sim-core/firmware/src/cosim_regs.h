/*
 * Register map of the virtual platform's peripheral window, as the thesis's
 * GVSoC program defines it (Appendix D, Tables 4.1-4.3) and DESIGN.md §4:
 * the MESSY sensors laid out one after another from the window's base.
 */
#ifndef COSIM_REGS_H
#define COSIM_REGS_H

#include <stdint.h>

#define AXI_BASE 0x20000000u

/* Camera (Table 4.1): control, status, 320x320 grey image. */
#define CAMERA_CTRL_REG_OFFSET 0
#define CAMERA_STAT_REG_OFFSET 1
#define CAMERA_IMAGE_OFFSET 2
#define CAMERA_WIDTH 320
#define CAMERA_HEIGHT 320

/* STM32 (Table 4.2): control, status, target X/Y/Z as little-endian doubles. */
#define STM32_CTRL_REG_OFFSET 102402
#define STM32_STAT_REG_OFFSET 102403
#define STM32_TARGET_POS_X_OFFSET 102404
#define STM32_TARGET_POS_Y_OFFSET 102412
#define STM32_TARGET_POS_Z_OFFSET 102420

/* Camera commands. */
#define GET_IMAGE 1

/* STM32 commands (Table 4.3). */
#define INIT_PID 1
#define GET_STABLE 2
#define SET_TARGET 3
#define RUN_SINGLE_STEP_PID 4
#define RUN_PID 5
#define TARGET_REACHED 6
#define GO_DOWN 7
#define PRINT_SIMUL_TIME 8
#define BATTERY_LOW 9
#define ITER_ADVANCE 10
/* Extension of Table 4.3 (not in the thesis): the firmware tells the STM32
 * that it skipped a target because of a low battery, so the platform can
 * count skipped targets in summary.json. Takes no simulated time. Written
 * as a value above 250 so it can never be mistaken for ITER_ADVANCE + ms
 * (ITER_ADVANCE + up to 240 ms). */
#define SKIP_TARGET 251

#define REG8(off) (*(volatile uint8_t *)(AXI_BASE + (off)))
#define REGF64(off) (*(volatile double *)(AXI_BASE + (off)))

#endif
