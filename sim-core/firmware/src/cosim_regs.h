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

/* STM32 extension (not in the thesis; DESIGN.md §9-§10):
 * the state estimate, the six ranges and the optical flow the STM32 read at
 * its last sensor update, and MotionCommander-like commands (cflib's
 * motion_commander: take-off, land, body-frame velocity set-point, speed
 * limit) plus a heading target for the race's position controller. Offsets
 * are from the window's base; f64 little-endian, SI units (m, m/s, rad,
 * rad/s; yaw counter-clockwise from the world's +x axis).
 *
 * Extension commands go to their own 32-bit register because every CTRL
 * value from 10 to 250 is ITER_ADVANCE + ms; write it as one 32-bit word
 * (the command starts when its last byte is written). EXT_STAT is 0 from
 * the command's write until it completes, then shows its code, or
 * EXT_ERROR. */
#define STM32_EXT_CTRL_OFFSET 102432 /* u32 W  extension command */
#define STM32_EXT_STAT_OFFSET 102436 /* u32 R  code of the last completed one */
/* State estimate (R), refreshed at every sensor read of the STM32 (each PID
 * iteration, INIT_PID, TAKEOFF/LAND steps). Position from GPS or from flow
 * dead reckoning, as the run setting stm32.position_source says. */
#define STM32_EST_X_OFFSET 102440
#define STM32_EST_Y_OFFSET 102448
#define STM32_EST_Z_OFFSET 102456
#define STM32_EST_YAW_OFFSET 102464
#define STM32_EST_VX_OFFSET 102472 /* world frame */
#define STM32_EST_VY_OFFSET 102480
#define STM32_EST_VZ_OFFSET 102488
/* Ranges (R, m) of the Multi-ranger (front/back/left/right) and the Flow
 * deck (down) plus up, body frame; a negative value means "nothing within
 * the sensor's max range" (or no such sensor in the world). */
#define STM32_RANGE_FRONT_OFFSET 102496
#define STM32_RANGE_BACK_OFFSET 102504
#define STM32_RANGE_LEFT_OFFSET 102512
#define STM32_RANGE_RIGHT_OFFSET 102520
#define STM32_RANGE_UP_OFFSET 102528
#define STM32_RANGE_DOWN_OFFSET 102536
/* Optical-flow velocity (R, m/s, body frame), 0 when the world sends none. */
#define STM32_FLOW_VX_OFFSET 102544
#define STM32_FLOW_VY_OFFSET 102552
/* Command arguments (RW), read when an extension command starts. */
#define STM32_CMD_VX_OFFSET 102560          /* m/s, body frame */
#define STM32_CMD_VY_OFFSET 102568          /* m/s, body frame */
#define STM32_CMD_HEIGHT_OFFSET 102576      /* m */
#define STM32_CMD_YAW_RATE_OFFSET 102584    /* rad/s, CCW */
#define STM32_CMD_YAW_OFFSET 102592         /* rad, heading target */
#define STM32_CMD_SPEED_LIMIT_OFFSET 102600 /* m/s */
/* Attitude (R, rad, InertialUnit roll and pitch at the same sensor read as
 * the estimate): added for the vision firmware, which levels the
 * camera's body-frame gate position before rotating it by the yaw
 * (docs/VISION.md, "What the flight integration needs" 3). */
#define STM32_EST_ROLL_OFFSET 102608
#define STM32_EST_PITCH_OFFSET 102616
/* World time (R, s) of the same sensor read: the time_s the world returned
 * with the state. The core's mtime does not follow the world's
 * clock in flight (the thesis's bookkeeping adds the core time between the
 * STM32's steps), so a flying firmware stamps what it derives from the
 * state, or does between two steps, with this (docs/SWARM_RESULTS.md §5). */
#define STM32_EST_TIME_OFFSET 102624
/* Seed 004's radar on a drone flown over CRTP (crtp/crtp_radar.c,
 * docs/LAB.md), u32 each, while EXT_CRTP runs: P2P_ENABLE (R) the
 * `radar.enable` parameter cflib wrote; P2P_SELF (W) this drone's radio id,
 * before EXT_CRTP (0: no radar); P2P_ID (W) the last drone heard (0: none
 * for 3 s); P2P_RSSI (W, int32) its RSSI in centi-dBm. */
#define STM32_P2P_ENABLE_OFFSET 102632
#define STM32_P2P_SELF_OFFSET 102636
#define STM32_P2P_ID_OFFSET 102640
#define STM32_P2P_RSSI_OFFSET 102644
#define STM32_EXT_END 102648

/* Bytes STM32_EXT_END to 0x1A000 are reserved for future STM32 registers:
 * any access faults (as do 102428-102431). */
#define STM32_RESERVED_END 0x1A000

/* Extension commands (STM32_EXT_CTRL) and EXT_STAT codes. */
#define EXT_SET_HEADING 1     /* race mode: hold CMD_YAW; the position controller
                               * rotates the world-frame error by the current
                               * yaw (at +90 deg exactly Appendix C's mapping) */
#define EXT_SET_VELOCITY 2    /* velocity mode: CMD_VX/VY (body), CMD_HEIGHT,
                               * CMD_YAW_RATE, clamped to the speed limit; the
                               * set-point holds until the next command, each
                               * RUN_SINGLE_STEP_PID / ITER_ADVANCE flies it */
#define EXT_SET_SPEED_LIMIT 3 /* from CMD_SPEED_LIMIT (default 0.2 m/s, cflib) */
#define EXT_TAKEOFF 4         /* climb to CMD_HEIGHT above the start, then hover */
#define EXT_LAND 5            /* descend, stop the motors, STOP the drone */
#define EXT_POSITION_MODE 6   /* back to the race's SET_TARGET position targets */
#define EXT_CRTP 7            /* serve the CRTP link (sim-core --crtp) until the
                               * client has gone, then STOP (docs/CFLIB.md) */
#define EXT_ERROR 0xFFFFFFFFu /* unknown command or bad argument (NaN, ...) */

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
#define RADIO_TX_DELAY_OFFSET 0x28   /* u32 RW  ns after the next TX_START (one-shot) */
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
