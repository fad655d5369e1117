/*
 * 320x320 -> 80x80 block means on the FC, as training/netdef.downsample:
 * x = (sum of the 4x4 block + 8) >> 4, then x - 128. One block row is one
 * word: cv.sdotup.b against 0x01010101 adds its four unsigned bytes in one
 * instruction (CV32E40P manual, "SIMD dot product"; the FC has the XCV
 * extensions too, docs/CLUSTER.md "Instructions").
 */
#include "frame.h"

#include <string.h>

#include "../xcv.h"

#if NN_POOL != 4 || NN_CAMERA != NN_INPUT * NN_POOL
#error "nn_downsample sums one 4-byte word per block row: NN_POOL must be 4"
#endif

void nn_downsample(const uint8_t *frame, int8_t *out)
{
    const int row = NN_INPUT + 2;
    memset(out, 0, row);
    memset(out + (NN_INPUT + 1) * row, 0, row);
    for (int by = 0; by < NN_INPUT; by++) {
        const uint32_t *r0 = (const uint32_t *)(frame + by * NN_POOL * NN_CAMERA);
        const uint32_t *r1 = r0 + NN_CAMERA / 4, *r2 = r1 + NN_CAMERA / 4, *r3 = r2 + NN_CAMERA / 4;
        int8_t *o = out + (by + 1) * row;
        o[0] = 0;
        o[NN_INPUT + 1] = 0;
        for (int bx = 0; bx < NN_INPUT; bx++) {
            uint32_t s = 8; /* rounding half up */
            s = xcv_sdotup_b(s, r0[bx], 0x01010101u);
            s = xcv_sdotup_b(s, r1[bx], 0x01010101u);
            s = xcv_sdotup_b(s, r2[bx], 0x01010101u);
            s = xcv_sdotup_b(s, r3[bx], 0x01010101u);
            o[bx + 1] = (int8_t)((int32_t)(s >> 4) - 128);
        }
    }
}
