/*
 * Hover endurance with the AI deck working (docs/AIDECK_POWER.md,
 * scenarios/hover-endurance-aideck.toml): race.c's HOVER_TEST (hold the
 * start point at 1 m, one image, ITER_ADVANCE and PID step per cycle,
 * until BATTERY_LOW or the battery's end) with the gate network run on
 * the cluster on every nn_look_every-th frame, as nn_race.c runs it: the
 * frame copied into L2 and averaged to the network's input, the cluster
 * powered up for the inference and down after it. The drone does not act
 * on the result: the flight is the plain hover, what the network costs is
 * the difference. The inferences' count goes to the console at the end.
 */
#include <pmsis.h>
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "decode.h"
#include "frame.h"
#include "network.h"
#include "net.h"

#define camera_control REG8(CAMERA_CTRL_REG_OFFSET)
#define camera_status REG8(CAMERA_STAT_REG_OFFSET)
#define stm32_control REG8(STM32_CTRL_REG_OFFSET)
#define stm32_status REG8(STM32_STAT_REG_OFFSET)
#define stm32_x REGF64(STM32_TARGET_POS_X_OFFSET)
#define stm32_y REGF64(STM32_TARGET_POS_Y_OFFSET)
#define stm32_z REGF64(STM32_TARGET_POS_Z_OFFSET)

/* The network on every nn_look_every-th frame (nn_race.c's default
 * cadence; `--set firmware.nn_look_every=N`, 0: never). */
int32_t nn_look_every = 5;
/* The hover's ITER_ADVANCE: race.c's INFERENCE_MS. */
#define ITER_MS 10

static uint8_t frame[NN_CAMERA * NN_CAMERA] __attribute__((aligned(4)));
static int8_t input[NN_INPUT_PADDED_BYTES] __attribute__((aligned(4)));
static int16_t head[NN_GRID * NN_GRID * NN_HEAD_CHANNELS] __attribute__((aligned(4)));
static struct pi_device cluster;
static uint32_t inferences, failures;

/* Listing 4.6: write the opcode, poll until the status shows it, clear. */
static void perform(uint8_t op)
{
    stm32_control = op;
    while (stm32_status != op)
        ;
    stm32_status = 0;
    stm32_control = 0;
}

static void get_image(void)
{
    camera_control = GET_IMAGE;
    while (camera_status != GET_IMAGE)
        ;
    camera_status = 0;
    camera_control = 0;
}

/* ITER_ADVANCE: a value v > 10 advances both simulations by v - 10 ms. */
static void advance_simul(uint8_t ms)
{
    stm32_control = (uint8_t)(ITER_ADVANCE + ms);
    while (stm32_status != ITER_ADVANCE)
        ;
    stm32_status = 0;
    stm32_control = 0;
}

/* One PID step; 1 once the STM32 reports a low battery. */
static int run_single_pid_iter(void)
{
    stm32_control = RUN_SINGLE_STEP_PID;
    for (;;) {
        uint8_t status = stm32_status;
        if (status == RUN_SINGLE_STEP_PID)
            return 0;
        if (status == BATTERY_LOW)
            return 1;
        if (status == TARGET_REACHED) {
            /* Keep hovering on the same target. */
            stm32_control = 0;
            stm32_status = 0;
            return 0;
        }
    }
}

/* The frame the camera holds into L2, a word at a time (nn_race.c). */
static void copy_frame(void)
{
    const volatile uint8_t *src = &REG8(CAMERA_IMAGE_OFFSET);
    uint32_t *dst = (uint32_t *)frame;
    for (int i = 0; i < NN_CAMERA * NN_CAMERA / 4; i++)
        dst[i] = *(const volatile uint32_t *)(src + 4 * i);
}

static void infer(void)
{
    static nn_job_t job;
    copy_frame();
    nn_downsample(frame, input);
    struct pi_cluster_conf conf;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster) != 0) {
        failures++;
        return;
    }
    job = (nn_job_t){.cluster = &cluster, .input = input, .head = head};
    struct pi_cluster_task task;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, nn_network_run, &job));
    pi_cluster_close(&cluster);
    nn_network_release();
    nn_output_t o;
    nn_decode(head, &o);
    inferences++;
    if (job.status != 0)
        failures++;
}

int main(void)
{
    printf("[nn] hover with the network on the cluster every %ld frames\n", (long)nn_look_every);
    perform(INIT_PID);
    perform(GET_STABLE);
    stm32_x = -2.6;
    stm32_y = 0;
    stm32_z = 1;
    perform(SET_TARGET);
    uint32_t frames = 0;
    int low = 0;
    while (!low) {
        get_image();
        if (nn_look_every > 0 && ++frames % (uint32_t)nn_look_every == 0)
            infer();
        advance_simul(ITER_MS);
        low = run_single_pid_iter();
    }
    stm32_control = 0;
    stm32_status = 0;
    printf("[nn] battery low after %lu frames, %lu inferences, %lu failed\n",
           (unsigned long)frames, (unsigned long)inferences, (unsigned long)failures);
    perform(GO_DOWN);
    /* As race.c: no reset of the registers, the simulation ends. */
    stm32_control = PRINT_SIMUL_TIME;
    while (stm32_status != PRINT_SIMUL_TIME)
        ;
    return failures != 0;
}
