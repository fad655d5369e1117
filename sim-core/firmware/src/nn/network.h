/*
 * The whole network on the cluster (docs/NN_KERNELS.md "On the cluster"): the
 * layers of weights.h, their weights streamed L2 -> L1 by the cluster DMA
 * tile by tile, double-buffered, each tile's outputs shared by the team.
 */
#ifndef NN_NETWORK_H
#define NN_NETWORK_H

#include <stdint.h>

#include <pmsis.h>

#include "net.h"

/* One inference, filled by the FC, run by nn_network_run on core 0. */
typedef struct {
    /* The open cluster (its L1 heap). */
    struct pi_device *cluster;
    /* L2: the int8 input, (NN_INPUT + 2)^2 bytes, zero-padded by one
     * pixel (nn_downsample's layout). */
    const int8_t *input;
    /* L2: the head's int16 grid, NN_GRID^2 * NN_HEAD_CHANNELS values, HWC. */
    int16_t *head;
    /* Cluster cycles (the cluster clock, `time` CSR of core 0) from the
     * task's start to the head's arrival in L2, and of each layer (its
     * tiles' DMA waits and computations). */
    uint32_t cycles;
    uint32_t layer_cycles[NN_N_LAYERS];
    /* 0, or -1: the layers do not fit in L1 (message on the console). */
    int status;
} nn_job_t;

/* The cluster task's entry (core 0): runs the network on `job` (an
 * nn_job_t *), forking every tile's computation on the task's cores. */
void nn_network_run(void *job);

/* Forgets the L1 working set (on the FC, after pi_cluster_close: a powered
 * down cluster's L1 is lost and the next open starts a new L1 heap); the
 * next nn_network_run allocates it again, outside its measured cycles. */
void nn_network_release(void);

#endif
