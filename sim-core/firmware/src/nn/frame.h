/* The network's input from a camera frame, on the FC (docs/NN.md step 1). */
#ifndef NN_FRAME_H
#define NN_FRAME_H

#include <stdint.h>

#include "net.h"

/* Bytes of the padded input nn_downsample writes. */
#define NN_INPUT_PADDED_BYTES ((NN_INPUT + 2) * (NN_INPUT + 2))

/* The NN_CAMERA^2 uint8 frame -> each NN_POOL^2 block's rounded mean
 * (sum + 8) >> 4, minus 128, as int8, into an (NN_INPUT + 2)^2 buffer with
 * a zero border (the first layer's padding). `frame` and `out` word-aligned. */
void nn_downsample(const uint8_t *frame, int8_t *out);

#endif
