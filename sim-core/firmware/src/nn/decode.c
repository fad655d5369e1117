/* The head's decoding, as training/int8_ref.decode (docs/NN.md step 3). */
#include "decode.h"

#include "weights.h"

void nn_decode(const int16_t *head, nn_output_t *o)
{
    int best = 0;
    for (int i = 1; i < NN_GRID * NN_GRID; i++)
        if (head[i * NN_HEAD_CHANNELS] > head[best * NN_HEAD_CHANNELS])
            best = i; /* strictly greater: the first maximum wins */
    const int16_t *h = head + best * NN_HEAD_CHANNELS;
    int gx = best % NN_GRID, gy = best / NN_GRID;
    int32_t cu = 16 * (NN_CELL_PX * gx + NN_CELL_PX / 2);
    int32_t cv = 16 * (NN_CELL_PX * gy + NN_CELL_PX / 2);
    o->visible = h[0] > 0;
    o->score = h[0];
    o->cell_x = gx;
    o->cell_y = gy;
    o->u_q4 = cu + h[1];
    o->v_q4 = cv + h[2];
    o->distance_mm = h[3];
    for (int j = 0; j < 8; j++)
        o->corners_q4[j] = (j % 2 ? cv : cu) + h[4 + j];
}
