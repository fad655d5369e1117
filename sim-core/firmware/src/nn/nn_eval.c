/*
 * `cosim nn eval`'s program (docs/NN.md "cosim nn eval"): the FC takes
 * camera frames from the host, averages them to the network's input,
 * offloads the network to the cluster and decodes the head, frame after
 * frame, with the cluster kept open.
 *
 * The host (scenarios/src/nn_eval.rs) drives it through these symbols:
 * at each `ebreak` (a stop of the run with the ISS's ebreak_stops) the
 * results of the previous frame are in nn_head / nn_out / nn_stats; the
 * host writes the next frame into nn_image and nn_command = NN_CMD_INFER
 * (or NN_CMD_QUIT) and resumes after the ebreak. nn_shape tells it the
 * geometry, so nothing of weights.h is copied into the host's code.
 */
#include <pmsis.h>
#include <stdio.h>
#include "../host_stop.h"

#include "decode.h"
#include "frame.h"
#include "network.h"
#include "net.h"

#define NN_CMD_INFER 1u
#define NN_CMD_QUIT 2u

uint8_t nn_image[NN_CAMERA * NN_CAMERA] __attribute__((aligned(4)));
volatile uint32_t nn_command;
int16_t nn_head[NN_GRID * NN_GRID * NN_HEAD_CHANNELS] __attribute__((aligned(4)));
nn_output_t nn_out;
/* status (0 ok), FC cycles of the downsampling, cluster cycles of the
 * network, then each layer's cluster cycles. */
uint32_t nn_stats[3 + NN_N_LAYERS];
/* camera side, grid, head channels, layers, MACs, then each layer's MACs. */
uint32_t nn_shape[5 + NN_N_LAYERS];
static int8_t input[NN_INPUT_PADDED_BYTES] __attribute__((aligned(4)));

static inline uint32_t fc_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}


static struct pi_device cluster;

static void infer(void)
{
    static nn_job_t job;
    uint32_t t0 = fc_now();
    nn_downsample(nn_image, input);
    uint32_t t1 = fc_now();
    job = (nn_job_t){.cluster = &cluster, .input = input, .head = nn_head};
    struct pi_cluster_task task;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, nn_network_run, &job));
    nn_stats[0] = (uint32_t)job.status;
    nn_stats[1] = t1 - t0;
    nn_stats[2] = job.cycles;
    for (int i = 0; i < NN_N_LAYERS; i++)
        nn_stats[3 + i] = job.layer_cycles[i];
    nn_decode(nn_head, &nn_out);
}

int main(void)
{
    struct pi_cluster_conf conf;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster) != 0) {
        printf("nn_eval: cannot open the cluster\n");
        return 1;
    }
    const uint32_t shape[5] = {NN_CAMERA, NN_GRID, NN_HEAD_CHANNELS, NN_N_LAYERS, NN_MACS};
    for (int i = 0; i < 5; i++)
        nn_shape[i] = shape[i];
    for (int i = 0; i < NN_N_LAYERS; i++)
        nn_shape[5 + i] = nn_layers[i].macs;
    for (;;) {
        nn_command = 0;
        host_stop();
        if (nn_command != NN_CMD_INFER)
            break;
        infer();
        if (nn_stats[0] != 0)
            break;
    }
    pi_cluster_close(&cluster);
    return nn_stats[0] != 0;
}
