/* The head's decoding (docs/NN.md step 3, training/int8_ref.decode). */
#ifndef NN_DECODE_H
#define NN_DECODE_H

#include <stdint.h>

typedef struct {
    int32_t visible;         /* a gate reported (decode.c's rule) */
    int32_t score;           /* its objectness, 1/64 logit */
    int32_t cell_x, cell_y;  /* the best cell */
    int32_t u_q4, v_q4;      /* the gate's centre, 1/16 camera pixel */
    int32_t distance_mm;
    int32_t corners_q4[8];   /* u0 v0 .. u3 v3, 1/16 camera pixel */
} nn_output_t;

/* head: the int16 grid NN_GRID x NN_GRID x NN_HEAD_CHANNELS, HWC. The best
 * cell is the first maximum of channel 0 in raster order (visible when > 0);
 * with weights.h's NN_DECODE_THRESHOLD the nearest (channel 3) of the cells
 * above the threshold, visible when there is one. */
void nn_decode(const int16_t *head, nn_output_t *out);

#endif
