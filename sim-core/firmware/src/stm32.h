/*
 * The GAP8 side of the STM32's command handshakes, shared by the programs
 * that fly through the STM32 (register map in cosim_regs.h, Table 4.2 and
 * "STM32 extension"). race.c keeps its own copy of stm32_perform, so the
 * thesis's program stays as the thesis lists it.
 */
#ifndef STM32_H
#define STM32_H

#include <stdint.h>

#include "cosim_regs.h"

#define stm32_control REG8(STM32_CTRL_REG_OFFSET)
#define stm32_status REG8(STM32_STAT_REG_OFFSET)
/* SET_TARGET's position (m, Table 4.2). */
#define stm32_x REGF64(STM32_TARGET_POS_X_OFFSET)
#define stm32_y REGF64(STM32_TARGET_POS_Y_OFFSET)
#define stm32_z REGF64(STM32_TARGET_POS_Z_OFFSET)
#define stm32_ext_ctrl REG32(STM32_EXT_CTRL_OFFSET)
#define stm32_ext_stat REG32(STM32_EXT_STAT_OFFSET)

/*
 * Listing 4.6: write the opcode to CTRL, spin until STAT shows it (the
 * STM32 sets STAT to the opcode when the operation completes), then clear
 * STAT and CTRL for the next command.
 */
static inline void stm32_perform(uint8_t op)
{
    stm32_control = op;
    while (stm32_status != op)
        ;
    stm32_status = 0;
    stm32_control = 0;
}

/*
 * One iteration of the single-step mode: ITER_ADVANCE + advance_ms (the
 * simulations advance that long), then RUN_SINGLE_STEP_PID (the STM32's
 * PID and one world step). Returns the PID step's status
 * (RUN_SINGLE_STEP_PID, TARGET_REACHED or BATTERY_LOW).
 */
static inline uint8_t stm32_iteration(uint8_t advance_ms)
{
    uint8_t s;
    stm32_control = (uint8_t)(ITER_ADVANCE + advance_ms);
    while (stm32_status != ITER_ADVANCE)
        ;
    stm32_status = 0;
    stm32_control = RUN_SINGLE_STEP_PID;
    while ((s = stm32_status) == 0)
        ;
    stm32_status = 0;
    stm32_control = 0;
    return s;
}

/*
 * An extension command (sim-core/src/peripherals/stm32/motion.rs): write
 * the code to EXT_CTRL as one 32-bit word (the command starts when its
 * last byte is written); EXT_STAT is 0 from then until the command
 * completes, then shows its code, or EXT_ERROR. Returns that status.
 */
static inline uint32_t stm32_ext(uint32_t cmd)
{
    uint32_t s;
    stm32_ext_ctrl = cmd;
    while ((s = stm32_ext_stat) == 0)
        ;
    return s;
}

#endif
