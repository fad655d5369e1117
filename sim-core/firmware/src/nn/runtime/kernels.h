/*
 * The generic runtime's cluster side (docs/NN_ONNX.md "On the deck"): one
 * cluster task per layer (or per part of an L3 layer's output channels),
 * run by core 0, which tiles the layer through L1 with the cluster DMA and
 * forks the team on each tile, DORY's scheme (Burrello et al. 2021, §III):
 * the host planned the tiles (model.h), the runtime follows the plan.
 */
#ifndef NN_RUNTIME_KERNELS_H
#define NN_RUNTIME_KERNELS_H

#include <stdint.h>

#include <pmsis.h>

#include "model.h"

/* What the FC sends for one layer (or one part of it). */
typedef struct {
    const nn_model_t *model;
    const uint8_t *l2;     /* the image (nn_l2) */
    const nn_layer_t *layer;
    /* CONV, DENSE: the weights of output channel oc_begin (in the image,
     * or in a stage buffer for an L3 layer); the task computes channels
     * [oc_begin, oc_end). */
    const int8_t *w;
    uint32_t oc_begin, oc_end;
    /* Filled by the task. */
    int32_t status;
    uint32_t cycles, dma_bytes;
} nn_job_t;

/* Status codes (nn_status). */
#define NN_E_MAGIC (-1)
#define NN_E_VERSION (-2)
#define NN_E_HEADER (-3)  /* tables outside the image, too many layers */
#define NN_E_VALUE (-4)   /* a value outside the image or of no size */
#define NN_E_LAYER (-5)   /* a layer's descriptor (nn_layer_done: which) */
#define NN_E_L1 (-6)      /* no L1 for the smallest tile */
#define NN_E_L3 (-7)      /* an L3 part larger than the stage buffer */

/* The L1 work area (kernels.c): allocated by the FC once the model's
 * budget is known (nn_l1_setup), kept while the cluster is open. */
int nn_l1_setup(struct pi_device *cluster, uint32_t budget);

/* The cluster task's entry (core 0): job is an nn_job_t. */
void nn_layer_task(void *job);

#endif
