/* The head's decoding, as training/int8_ref.decode (docs/NN.md step 3):
 * the best cell's objectness > 0, or, when weights.h defines
 * NN_DECODE_THRESHOLD (a network trained on every visible gate), the
 * nearest of the cells above the threshold. */
#include "decode.h"

#include "net.h"

void nn_decode(const int16_t *head, nn_output_t *o)
{
    int best = 0;
    for (int i = 1; i < NN_GRID * NN_GRID; i++)
        if (head[i * NN_HEAD_CHANNELS] > head[best * NN_HEAD_CHANNELS])
            best = i; /* strictly greater: the first maximum wins */
#ifdef NN_DECODE_THRESHOLD
    /* The network's own rule (weights.h): the nearest of the cells that
     * see a gate, since objectness is trained on every visible gate's cell
     * and the label is the nearest one. Without a candidate, the best cell
     * is reported, not visible. */
    int nearest = -1;
    for (int i = 0; i < NN_GRID * NN_GRID; i++) {
        const int16_t *c = head + i * NN_HEAD_CHANNELS;
        if (c[0] > NN_DECODE_THRESHOLD && c[3] <= NN_DECODE_MAX_DISTANCE_MM &&
            (nearest < 0 || c[3] < head[nearest * NN_HEAD_CHANNELS + 3]))
            nearest = i; /* strictly smaller: the first minimum wins */
    }
    if (nearest >= 0)
        best = nearest;
    o->visible = nearest >= 0;
#endif
    const int16_t *h = head + best * NN_HEAD_CHANNELS;
    int gx = best % NN_GRID, gy = best / NN_GRID;
    int32_t cu = 16 * (NN_CELL_PX * gx + NN_CELL_PX / 2);
    int32_t cv = 16 * (NN_CELL_PX * gy + NN_CELL_PX / 2);
#ifndef NN_DECODE_THRESHOLD
    o->visible = h[0] > 0;
#endif
    o->score = h[0];
    o->cell_x = gx;
    o->cell_y = gy;
    o->u_q4 = cu + h[1];
    o->v_q4 = cv + h[2];
    o->distance_mm = h[3];
    for (int j = 0; j < 8; j++)
        o->corners_q4[j] = (j % 2 ? cv : cu) + h[4 + j];
}
