/*
 * The model as data (docs/NN_ONNX.md "On the deck"): what `cosim nn run`
 * writes into the generic runtime's L2 image (`nn_l2`) and into the AI
 * deck's HyperRAM (L3) before an inference. The host (scenarios/src/nn/
 * onnx/deploy.rs) plans everything: where each activation lives in L2,
 * which weights stay in L2 and which stream from L3, and each layer's L1
 * tile (DORY's approach: tiling decided ahead of time, kept as data). The
 * firmware follows the plan; it computes nothing about memory itself.
 *
 * All fields little-endian 32-bit words; structures 4-byte aligned.
 * Offsets are bytes from `nn_l2` (L2) or from the HyperRAM's address 0
 * (L3, layers flagged NN_F_W_L3).
 *
 * Arithmetic (the host's integer reference, scenarios/src/nn/onnx/
 * reference.rs, is the specification; the runtime equals it bit for bit):
 * - Activations are int8 in the "stored" domain: a uint8 ONNX tensor is
 *   stored as q - 128, its zero point and clamp shifted alike, so every
 *   (q - zp) is unchanged and one set of kernels serves both types.
 * - A record {mult, shift} applies as rq(acc) = (acc * mult +
 *   2^(shift-1)) >> shift in 64 bits (shift 0: acc * mult; shift 63: 0).
 * - A layer's output: clamp(zp_out + r, lo, hi), r its requantized sum.
 */
#ifndef NN_MODEL_H
#define NN_MODEL_H

#include <stdint.h>

#define NN_MAGIC 0x4e4e4643u /* "CFNN" */
#define NN_VERSION 1u
/* Inputs of one layer (Concat); the importer refuses more. */
#define NN_MAX_IN 8
/* Layers in one model; the importer refuses more. */
#define NN_MAX_LAYERS 256

typedef struct {
    uint32_t magic, version;
    uint32_t n_values, n_layers;
    uint32_t values_off; /* nn_value_t[n_values] */
    uint32_t layers_off; /* nn_layer_t[n_layers] */
    uint32_t input, output; /* value indices */
    /* Two L2 buffers of stage_bytes each, at stage_off and stage_off +
     * stage_bytes, that weights flagged NN_F_W_L3 are read into from L3
     * (layer after layer, alternating: the next layer's read runs while the
     * cluster computes the current one). 0 when no weights are in L3. */
    uint32_t stage_off, stage_bytes;
    uint32_t l3_bytes;   /* bytes the host wrote into L3 */
    uint32_t l2_bytes;   /* bytes of the L2 image, activations included */
    uint32_t l1_budget;  /* the L1 bytes the tiles were planned for */
} nn_model_t;

/* An activation, stored HWC: element (y, x, ch) at off + (y*w + x)*c + ch.
 * A vector (after Flatten, Gemm) is c x 1 x 1. */
typedef struct {
    uint32_t c, h, w;
    int32_t zp;   /* zero point, stored domain */
    uint32_t off; /* in the L2 image */
    uint32_t bytes;
} nn_value_t;

enum {
    NN_CONV = 1,   /* regular, grouped and depthwise */
    NN_DENSE = 2,  /* Gemm, MatMul */
    NN_MAXPOOL = 3,
    NN_AVGPOOL = 4,
    NN_GAP = 5,    /* GlobalAveragePool */
    NN_ADD = 6,
    NN_CONCAT = 7, /* on channels */
    NN_REQUANT = 8, /* Relu/Clip between Q/DQ, Flatten, Reshape, a new scale */
    NN_LUT = 9,    /* Sigmoid between DQ/Q */
};

/* flags */
#define NN_F_W_L3 1u          /* weights at L3 address w_off, not in L2 */
#define NN_F_COUNT_PAD 2u     /* AVGPOOL: count the pad in the divisor */
#define NN_F_POOL_RECORDS 4u  /* AVGPOOL/GAP: records, not the division */

typedef struct {
    uint32_t kind;
    uint32_t n_in;
    uint32_t in[NN_MAX_IN]; /* value indices */
    uint32_t out;
    /* Window (conv, pools): kernel, strides, pads top/left/bottom/right. */
    uint32_t kh, kw, sh, sw, pt, pl, pb, pr;
    uint32_t groups;
    int32_t lo, hi; /* the output clamp, stored domain */
    uint32_t flags;
    /* CONV: int8 weights [cout][kh][kw][cin/groups]; DENSE: [out][in],
     * `in` in the input's storage order. At w_off in L2, or in L3 with
     * NN_F_W_L3 (then read into a stage buffer first). w_bytes each. */
    uint32_t w_off, w_bytes;
    /* CONV, DENSE: int32 bias per output channel with the input's zero
     * point folded in: bias - zp_in * sum(weights of the channel), so the
     * pad is the input's zero point and the sum runs over raw inputs. */
    uint32_t b_off;
    /* Records {int32 mult; uint32 shift}: CONV, DENSE one per output
     * channel; MAXPOOL, REQUANT one; ADD two (the second input's shift
     * equals the first's: acc = (a - za)*m0 + (b - zb)*m1, then
     * (acc + 2^(s-1)) >> s); CONCAT one per input; AVGPOOL with records
     * kh*kw + 1, indexed by the window's count; GAP with records one (for
     * h*w). */
    uint32_t rq_off;
    /* LUT: 256 int8 outputs (stored domain), indexed by q + 128. */
    uint32_t lut_off;
    /* The L1 tile the host planned. l1_bytes = 2 x (the buffers of one
     * tile), each buffer rounded up to 4 bytes (A4), never above the
     * header's l1_budget:
     * CONV: tile_oh output rows x tile_oc output channels (the last tiles
     *   may be smaller); buffers: the input band A4(((tile_oh-1)*sh + kh)
     *   * (w_in + pl + pr) * c_in) with every input channel, the weights
     *   A4(tile_oc * kh * kw * c_in/groups), bias and records tile_oc * 12,
     *   the output A4(tile_oh * w_out * tile_oc).
     * DENSE: tile_oc output rows (tile_oh 1); buffers: the input A4(in),
     *   the weights A4(tile_oc * in), bias and records tile_oc * 12, the
     *   output A4(tile_oc).
     * MAXPOOL, AVGPOOL: tile_oh output rows, all channels; buffers: the
     *   input band A4(((tile_oh-1)*sh + kh) * w_in * c), the output
     *   A4(tile_oh * w_out * c) (records in L2, read by the cores).
     * GAP: tile_oh input rows; buffers: the band A4(tile_oh * w * c), plus
     *   4 * c bytes of sums once (counted twice in l1_bytes).
     * ADD, CONCAT, REQUANT, LUT: tile_oh rows; buffers: each input's rows
     *   A4(tile_oh * w * c_k), the output A4(tile_oh * w * c_out). */
    uint32_t tile_oh, tile_oc, l1_bytes;
    /* NN_F_W_L3 layers (CONV, DENSE): the FC reads the weights from L3 in
     * parts of part_oc whole output channels (each part at most the
     * header's stage_bytes; the last may be smaller), into the two stage
     * buffers in turn, and sends one cluster task per part (output
     * channels [k*part_oc, min((k+1)*part_oc, c_out))); the read of the
     * next part, of this layer or the next L3 layer, runs while the
     * cluster computes the current one (DORY's L3 double buffering). 0 for
     * layers with weights in L2 (one task for the whole layer). */
    uint32_t part_oc;
    uint32_t macs_lo, macs_hi;
} nn_layer_t;

typedef struct {
    int32_t mult;
    uint32_t shift;
} nn_record_t;

/* What the runtime reports per layer (nn_stats, after each inference):
 * cluster cycles from the task's start to its end, bytes the cluster DMA
 * moved (both ways), bytes read from L3 for the layer. */
typedef struct {
    uint32_t cycles, dma_bytes, l3_bytes, fc_wait_cycles;
} nn_layer_stats_t;

#endif
