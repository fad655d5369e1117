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

/* Bytes 102428 (STM32 + 26) to 0x1A000 are reserved for future STM32
 * registers: any access faults. */
#define STM32_RESERVED_END 0x1A000

/* Radios (DESIGN.md §8, docs/SWARM.md §4.3): the same register file at two
 * fixed offsets; add a radio's base to each RADIO_*_OFFSET. */
#define UWB_BASE_OFFSET 0x1A000 /* DW1000 of the Loco Positioning deck */
#define P2P_BASE_OFFSET 0x1A200 /* the nRF51's peer-to-peer radio */

#define RADIO_CTRL_OFFSET 0x00       /* u8  W   command */
#define RADIO_STATUS_OFFSET 0x01     /* u8  R/W1C */
#define RADIO_IRQ_MASK_OFFSET 0x02   /* u8  RW  STATUS bits that interrupt */
#define RADIO_STATE_OFFSET 0x03      /* u8  R */
#define RADIO_TX_LEN_OFFSET 0x04     /* u8  RW */
#define RADIO_RX_LEN_OFFSET 0x05     /* u8  R */
#define RADIO_RX_PENDING_OFFSET 0x06 /* u8  R   frames behind RX_BUF */
#define RADIO_TX_STAMP_OFFSET 0x08   /* u64 R   40-bit DW1000 stamp (uwb) */
#define RADIO_RX_STAMP_OFFSET 0x10   /* u64 R   40-bit DW1000 stamp (uwb) */
#define RADIO_RX_RSSI_OFFSET 0x18    /* i32 R   1/100 dBm */
#define RADIO_RX_LOST_OFFSET 0x1C    /* u32 R */
#define RADIO_EUI_OFFSET 0x20        /* u64 R   run key radio_id */
#define RADIO_TX_BUF_OFFSET 0x40     /* 128 B RW */
#define RADIO_RX_BUF_OFFSET 0xC0     /* 128 B R */
#define RADIO_BUF_SIZE 128

/* Radio commands (CTRL). */
#define RADIO_INIT 1 /* claim the world if nobody has; radio to IDLE */
#define RADIO_TX_START 2
#define RADIO_RX_ON 3
#define RADIO_RX_OFF 4 /* to IDLE */
#define RADIO_SLEEP 5

/* Radio STATUS bits (write 1 to clear; clearing RX_DONE moves the next frame
 * of the 8-frame receive FIFO into RX_BUF). */
#define RADIO_INIT_DONE 0x01
#define RADIO_TX_DONE 0x02
#define RADIO_RX_DONE 0x04
#define RADIO_RX_OVERRUN 0x08

/* Radio STATE values. */
#define RADIO_STATE_SLEEP 0
#define RADIO_STATE_IDLE 1
#define RADIO_STATE_RX 2
#define RADIO_STATE_TX 3

/* Payload limits. */
#define UWB_MAX_PAYLOAD 127
#define P2P_MAX_PAYLOAD 60

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
#define REG32(off) (*(volatile uint32_t *)(AXI_BASE + (off)))

#endif
