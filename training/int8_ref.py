"""The bit-exact int8 reference of the gate network (numpy only): exactly the
integer arithmetic the firmware does, step by step as docs/NN.md
("Int8 arithmetic") describes it, so a cluster kernel can be checked
against it bit for bit.

    python3 training/int8_ref.py IMAGE.pgm...   # prints each image's outputs

1. Input: the 320x320 uint8 image; each 4x4 block -> (sum + 8) >> 4 (uint8,
   80x80); minus 128 -> int8. HWC, C = 1.
2. Each layer (netdef.LAYERS, parameters from export.quantize):
   acc[y][x][c] = bias[c] + sum_{ky,kx,ci} w[c][ky][kx][ci] *
                  in[y*stride + ky - pad][x*stride + kx - pad][ci]
   with in = 0 outside the input (zero padding), int8 x int8 products,
   int32 sums (they cannot overflow: |acc| < 576 * 127 * 128 + |bias|);
   out = clip((acc * mult[c] + (1 << (shift - 1))) >> shift, lo, hi):
   the product in int64, >> arithmetic (floor), so the rounding is half up;
   [lo, hi] = [0, 127] after a ReLU (the clip is the ReLU), the head's is
   the int16 range. No pooling layers.
3. Output decoding, from the head's int16 grid h[5][5][12]:
   best = the first maximum of h[..][..][0] in raster order (row 0 first);
   visible = h[best][0] > 0. With a checkpoint's "nearest" rule
   (export.decode_rule: threshold T, maximum distance D): the candidates
   are the cells with h[..][..][0] > T and h[..][..][3] <= D; best = the
   one with the smallest h[..][..][3] (the first in raster order on a
   tie), visible = 1; without a candidate, best as above, visible = 0.
   With (gx, gy) the best cell and
   (cu, cv) = (64 gx + 32, 64 gy + 32) its centre in camera pixels:
   u_q4 = 16 cu + h[best][1], v_q4 = 16 cv + h[best][2] (1/16 px),
   distance_mm = h[best][3], corner k: (16 cu + h[best][4 + 2k],
   16 cv + h[best][5 + 2k]); score = h[best][0] (1/64 logit).

The matrix products run in float64: every product and partial sum is an
integer below 2^31, which float64 represents exactly whatever the order of
summation, so the result is the integer one (and BLAS-fast).
"""

import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef  # noqa: E402


def _patches(x, k, stride, pad):
    """(n, h, w, c) -> (n, oh, ow, k*k*c) in [ky][kx][ci] order, zero padded."""
    n, h, w, c = x.shape
    if pad:
        x = np.pad(x, ((0, 0), (pad, pad), (pad, pad), (0, 0)))
    oh = (h + 2 * pad - k) // stride + 1
    ow = (w + 2 * pad - k) // stride + 1
    cols = [x[:, ky:ky + stride * oh:stride, kx:kx + stride * ow:stride, :]
            for ky in range(k) for kx in range(k)]
    return np.concatenate(cols, axis=-1)


def apply_weights(p, w):
    """Patches (n, oh, ow, k*k*cin) of _patches times weights
    [cout][k][k][wcin]: the (n, oh, ow, cout) sums; a depthwise layer's
    (wcin = 1 of cin = cout channels, netdef.depthwise) take each output
    channel's taps from its own input channel."""
    cout = w.shape[0]
    taps = w.shape[1] * w.shape[2]
    if p.shape[-1] == w[0].size:
        return p @ w.reshape(cout, -1).T
    p = p.reshape(p.shape[:-1] + (taps, cout))
    return np.einsum("...tc,tc->...c", p, w.reshape(cout, taps).T)


def layer_int8(layer, x):
    """One layer on int8/int16 activations (n, h, w, cin) -> (n, oh, ow, cout)."""
    p = _patches(x.astype(np.float64), layer["k"], layer["stride"], layer["pad"])
    acc = apply_weights(p, layer["w"].astype(np.float64)).astype(np.int64)
    acc += layer["bias"].astype(np.int64)
    assert np.all(np.abs(acc) < 2**31), "int32 accumulator overflow"
    shift = layer["shift"]
    y = (acc * layer["mult"].astype(np.int64) + (1 << (shift - 1))) >> shift
    y = np.clip(y, layer["lo"], layer["hi"])
    return y.astype(np.int8 if layer["hi"] == 127 else np.int16)


def head_int8(q, x):
    """int8 input (n, INPUT, INPUT, 1) -> the head's int16 grid (n, 5, 5, 12)."""
    for layer in q:
        x = layer_int8(layer, x)
    return x


def pick_cell(obj, dist, rule):
    """(best cell's raster index, visible) from the grid's objectness and
    distance channels (flat, any numeric type; step 3 above): without a rule
    the first maximum of the objectness, visible when > 0; with the
    "nearest" rule (export.decode_rule) the nearest of the cells whose
    objectness > threshold and distance <= max_distance, else the first
    maximum, not visible. The float decoding uses it too, in float units."""
    if rule is not None:
        cand = (obj > rule["threshold"]) & (dist <= rule["max_distance"])
        if cand.any():
            d = np.where(cand, dist, np.inf)
            return int(np.argmin(d)), True  # numpy: the first minimum
    best = int(np.argmax(obj))  # numpy: the first maximum
    return best, rule is None and bool(obj[best] > 0)


def decode(head, rule=None):
    """One image's int16 head (5, 5, 12) -> its integer outputs. `rule`:
    export.decode_rule's int8 rule, or None (the best cell's objectness > 0)."""
    flat = head.reshape(-1, netdef.HEAD_CHANNELS).astype(np.int64)
    best, visible = pick_cell(flat[:, 0], flat[:, 3], rule)
    gy, gx = divmod(best, netdef.GRID)
    h = flat[best]
    cu = 16 * (netdef.CELL_PX * gx + netdef.CELL_PX // 2)
    cv = 16 * (netdef.CELL_PX * gy + netdef.CELL_PX // 2)
    return {
        "visible": bool(visible),
        "score": int(h[0]),
        "cell": [gx, gy],
        "u_q4": int(cu + h[1]),
        "v_q4": int(cv + h[2]),
        "distance_mm": int(h[3]),
        "corners_q4": [int((cu, cv)[j % 2] + h[4 + j]) for j in range(8)],
    }


def heads_batch(q, x, batch=256):
    """int8 inputs (n, INPUT, INPUT, 1) -> the int16 heads (n, 5, 5, 12)."""
    return np.concatenate([head_int8(q, x[s:s + batch]) for s in range(0, len(x), batch)])


def infer_batch(q, x, rule=None, batch=256):
    """int8 inputs (n, INPUT, INPUT, 1) -> list of decoded outputs."""
    return [decode(h, rule) for h in heads_batch(q, x, batch)]


def infer_image(q, image, rule=None):
    """A 320x320 uint8 camera image -> (its int8 input, head, decoded outputs)."""
    x = netdef.to_int8(netdef.downsample(image[None]))
    head = head_int8(q, x)[0]
    return x[0], head, decode(head, rule)


def float_forward(ckpt, x, batch=256):
    """The float network (numpy) on float inputs (n, INPUT, INPUT, 1): the
    head; `batch` images at a time (a 160x160 input's patches are large)."""
    if len(x) > batch:
        return np.concatenate([float_forward(ckpt, x[s:s + batch], batch)
                               for s in range(0, len(x), batch)])
    for name, k, stride, pad, _, cout, relu in netdef.LAYERS:
        p = _patches(x, k, stride, pad)
        x = apply_weights(p, ckpt[f"{name}.w"].astype(np.float64)) + ckpt[f"{name}.b"]
        if relu:
            x = np.maximum(x, 0.0)
    return x


def main():
    import export

    ckpt = export.load_checkpoint(export.DEFAULT_CHECKPOINT)
    q, rule = export.quantize(ckpt), export.decode_rule(ckpt)
    for path in sys.argv[1:]:
        _, _, out = infer_image(q, netdef.read_pgm(path), rule)
        print(path, json.dumps(out))


if __name__ == "__main__":
    main()
