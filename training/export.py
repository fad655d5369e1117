"""Quantizes the float checkpoint to int8 and writes the firmware's C
weights (numpy only; docs/NN.md, "Int8 arithmetic"):

    python3 training/export.py [--checkpoint training/checkpoint.npz] \
        [--out sim-core/firmware/src/nn] [--int8-header]

writes `weights.h` (geometry, the layer table's type) and `weights.c` (int8
weights, int32 biases and multipliers, shifts). With `--int8-header` the
int8 weights go to a third file, `weights_int8.h`, as one initializer macro
per layer that `weights.c` includes: another network with the same int8
weights (training/make_fallback.py's) includes it too instead of repeating
them, and the preprocessed `weights.c` is the same, so is the firmware. The
quantization is a pure function of the checkpoint, so a test regenerates
the files and compares them with the committed ones.

Per layer with input scale s_in (real = s_in * q) and output scale s_out:
  weights  per output channel c: s_w[c] = max|W[c]| / 127,
           Wq = clip(round(W / s_w[c]), -127, 127)                 (int8)
  bias     bq[c] = round(b[c] / (s_in * s_w[c]))                    (int32)
  requant  m[c] = s_in * s_w[c] / s_out[c] = M[c] * 2^-S, with the layer's
           shift S the largest keeping every M[c] <= 32767 and
           M[c] = round(m[c] * 2^S)                                 (int32)
  s_out    ReLU layers: act_max / 127 (act_max: the 99.99th percentile of
           the float activation, from training); the head: netdef.HEAD_UNITS
           (fixed units per channel, int16 output).
The input scale is 1/128 (pixel - 128).
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
DEFAULT_CHECKPOINT = os.path.join(HERE, "checkpoint.npz")
DEFAULT_OUT = os.path.join(REPO, "sim-core", "firmware", "src", "nn")
M_MAX = 32767


def load_checkpoint(path):
    """The checkpoint's arrays; selects its network in netdef (one without a
    `net` entry, like the committed one, is netdef's "base")."""
    with np.load(path) as z:
        ckpt = {k: z[k] for k in z.files}
    netdef.select(netdef.checkpoint_net(ckpt))
    return ckpt


def checkpoint_and_dataset(argv=None):
    """The analysis scripts' command line, `DIR [--checkpoint CKPT]`: the
    checkpoint (its net selected in netdef) and the dataset's (inputs,
    labels) at that net's input resolution."""
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--checkpoint", default=DEFAULT_CHECKPOINT)
    a = ap.parse_args(argv)
    ckpt = load_checkpoint(a.checkpoint)
    small, labels = netdef.load_dataset(a.data)
    return ckpt, small, labels


def decode_rule(ckpt, units="int8"):
    """The checkpoint's decoding rule (docs/NN.md, int8_ref step 3), or None
    for the original one (the best cell's objectness > 0). A checkpoint
    made by choose_threshold.py holds `decode` = {"rule": "nearest",
    "threshold_q": T (1/64 logit), "max_distance_mm": D}: the nearest of the
    cells whose objectness > T and distance <= D. As int8 head units, or
    with units="float" as the float head's (logit, distance / 8 m)."""
    if "decode" not in ckpt:
        return None
    d = json.loads(str(ckpt["decode"]))
    assert d["rule"] == "nearest", d
    if units == "int8":
        return {"threshold": int(d["threshold_q"]), "max_distance": int(d["max_distance_mm"])}
    return {"threshold": d["threshold_q"] / 64.0,
            "max_distance": d["max_distance_mm"] / 1000.0 / netdef.DIST_SCALE_M}


def quantize(ckpt):
    """The int8 network: one dict per layer (netdef.LAYERS order) with w
    (int8 [cout][k][k][cin]), bias (int32), mult (int32), shift, lo, hi."""
    layers = []
    s_in = 1.0 / 128.0
    geo = netdef.geometry()
    for i, (name, k, stride, pad, cin, cout, relu) in enumerate(netdef.LAYERS):
        w = ckpt[f"{name}.w"].astype(np.float64)
        b = ckpt[f"{name}.b"].astype(np.float64)
        assert w.shape == (cout, k, k, netdef.weight_cin(netdef.LAYERS[i])), (name, w.shape)
        s_w = np.abs(w).reshape(cout, -1).max(axis=1) / 127.0
        s_w[s_w == 0] = 1.0
        wq = np.clip(np.round(w / s_w[:, None, None, None]), -127, 127).astype(np.int8)
        bq = np.round(b / (s_in * s_w)).astype(np.int64)
        assert np.all(np.abs(bq) < 2**31), name
        if relu:
            s_out = np.full(cout, float(ckpt["act_max"][i]) / 127.0)
            lo, hi = 0, 127
        else:
            s_out = netdef.HEAD_UNITS.copy()
            lo, hi = -32768, 32767
        m = s_in * s_w / s_out
        shift = int(np.floor(np.log2(M_MAX / m.max())))
        assert 1 <= shift <= 40, (name, shift)
        mult = np.round(m * 2.0**shift).astype(np.int64)
        assert mult.max() <= M_MAX and mult.min() >= 0, name
        in_h, in_w, out_h, out_w = geo[i]
        layers.append({
            "name": name, "k": k, "stride": stride, "pad": pad, "cin": cin, "cout": cout,
            "relu": relu, "in_h": in_h, "in_w": in_w, "out_h": out_h, "out_w": out_w,
            "w": wq, "bias": bq.astype(np.int32), "mult": mult.astype(np.int32),
            "shift": shift, "lo": lo, "hi": hi,
        })
        if relu:
            s_in = float(ckpt["act_max"][i]) / 127.0
    return layers


def _array(ctype, name, values, per_line=16):
    vals = [str(int(v)) for v in np.asarray(values).ravel()]
    lines = [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]
    body = ",\n    ".join(lines)
    return f"static const {ctype} {name}[{len(vals)}] = {{\n    {body}\n}};\n"


def _macro(name, values, per_line=16):
    """An initializer macro: `#define NAME { v, ... }`, one line of values
    per source line (the preprocessor joins them)."""
    vals = [str(int(v)) for v in np.asarray(values).ravel()]
    lines = [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]
    body = ", \\\n    ".join(lines)
    return f"#define {name} {{ \\\n    {body} \\\n}}\n"


def int8_weights(layers):
    """Each layer's int8 weights as weights.c stores them: (name, array)."""
    out = []
    for L in layers:
        n = L["name"]
        w = L["w"]
        if netdef.depthwise(n):
            # One word per kernel row, as the firmware's depthwise kernel
            # reads them (conv.c "Depthwise"): no repacking on the cluster.
            w = np.pad(w.reshape(L["cout"], L["k"], L["k"]), ((0, 0), (0, 0), (0, 4 - L["k"])))
        out.append((n, w))
    return out


def weights_macro(name):
    """The initializer macro of a layer's int8 weights in weights_int8.h."""
    return f"NN_{name.upper()}_W"


def c_int8_header(layers, meta):
    """weights_int8.h: the int8 weights of every layer as initializer
    macros (`--int8-header`)."""
    origin = ("/* Generated by training/export.py from training/checkpoint.npz "
              "(docs/NN.md): do not edit.\n"
              f" * Checkpoint: {portable_command(meta.get('command', '?'))}\n"
              " * The int8 weights of each layer, the initializers of weights.c's\n"
              " * nn_<layer>_w (every network with these weights includes this file). */\n")
    h = origin + "#ifndef NN_WEIGHTS_INT8_H\n#define NN_WEIGHTS_INT8_H\n\n"
    for n, w in int8_weights(layers):
        h += _macro(weights_macro(n), w) + "\n"
    return h + "#endif\n"


def c_decode(rule):
    """weights.h's decoding macros (none for the original rule, so a
    checkpoint without one exports the same bytes as before)."""
    if rule is None:
        return ""
    return f"""
/* The decoding (decode.c, training/int8_ref.py step 3): the nearest (smallest
 * channel 3) of the cells whose objectness > NN_DECODE_THRESHOLD (1/64 logit)
 * and distance <= NN_DECODE_MAX_DISTANCE_MM; chosen on the validation set
 * (training/choose_threshold.py). */
#define NN_DECODE_THRESHOLD ({rule['threshold']})
#define NN_DECODE_MAX_DISTANCE_MM ({rule['max_distance']})
"""


def portable_command(command):
    """The training command as the generated files record it: an absolute
    path (a dataset or checkpoint folder of the machine that trained) is
    reduced to its last component, so the files say what was run, not
    where."""
    return " ".join(os.path.basename(t.rstrip("/")) if t.startswith("/") else t
                    for t in command.split(" "))


def c_sources(layers, meta, rule=None, int8_header=None):
    """(weights.h, weights.c) text. `int8_header`: the path weights.c
    includes the int8 weights from (`c_int8_header`'s file, as an
    `#include` names it), or None to write them in weights.c."""
    origin = ("/* Generated by training/export.py from training/checkpoint.npz "
              "(docs/NN.md): do not edit.\n"
              f" * Checkpoint: {portable_command(meta.get('command', '?'))}\n */\n")
    macs = netdef.macs()
    h = origin + f"""#ifndef NN_WEIGHTS_H
#define NN_WEIGHTS_H

#include <stdint.h>

/* Input: the 320x320 camera image averaged over 4x4 blocks, (sum + 8) >> 4,
 * minus 128 (int8, HWC with C = 1). */
#define NN_CAMERA {netdef.CAMERA}
#define NN_POOL {netdef.POOL}
#define NN_INPUT {netdef.INPUT}
/* Output: a {netdef.GRID}x{netdef.GRID} grid of {netdef.HEAD_CHANNELS} int16 channels (HWC); a cell is
 * {netdef.CELL_PX}x{netdef.CELL_PX} camera pixels. Channel 0: objectness (1/64 logit); 1, 2: centre
 * minus cell centre (1/16 px); 3: distance (mm); 4-11: corners minus cell
 * centre (1/16 px), top-left, top-right, bottom-right, bottom-left. */
#define NN_GRID {netdef.GRID}
#define NN_CELL_PX {netdef.CELL_PX}
#define NN_HEAD_CHANNELS {netdef.HEAD_CHANNELS}
#define NN_N_LAYERS {len(layers)}
/* Output channels of all layers (network.c's requantization records). */
#define NN_CHANNELS {sum(L["cout"] for L in layers)}
#define NN_MACS {sum(macs)}
#define NN_PARAMS {netdef.params()}
{c_decode(rule)}
/* One convolution: out[y][x][c] = clip((acc * mult[c] + (1 << (shift - 1)))
 * >> shift, out_min, out_max) with acc = bias[c] + sum over (ky, kx, ci) of
 * w[c][ky][kx][ci] * in[y*stride + ky - pad][x*stride + kx - pad][ci]
 * (0 outside the input), the product in 64 bits, >> arithmetic. A
 * depthwise layer (in_c == out_c) has one input channel per output channel:
 * ci runs over c alone and w is [out_c][k][k][1]. */
typedef struct {{
    uint16_t in_h, in_w, in_c;
    uint16_t out_h, out_w, out_c;
    uint8_t k, stride, pad, shift, depthwise;
    int32_t out_min, out_max; /* [0, 127] after ReLU (int8); the head: int16 */
    uint32_t macs;
    const int8_t *w;      /* [out_c][k][k][in_c]; depthwise [out_c][k][4]: a row's k
                           * taps then 4 - k zero bytes, a word per row */
    const int32_t *bias;  /* [out_c] */
    const int32_t *mult;  /* [out_c] */
}} nn_layer_t;

extern const nn_layer_t nn_layers[NN_N_LAYERS];

#endif
"""
    c = origin + '\n#include "weights.h"\n'
    if int8_header is not None:
        c += f'#include "{int8_header}"\n'
    c += "\n"
    for L, (n, w) in zip(layers, int8_weights(layers)):
        if int8_header is None:
            c += _array("int8_t", f"nn_{n}_w", w) + "\n"
        else:
            c += f"static const int8_t nn_{n}_w[{w.size}] = {weights_macro(n)};\n\n"
        c += _array("int32_t", f"nn_{n}_bias", L["bias"], 8) + "\n"
        c += _array("int32_t", f"nn_{n}_mult", L["mult"], 8) + "\n"
    c += "const nn_layer_t nn_layers[NN_N_LAYERS] = {\n"
    for L, mac in zip(layers, macs):
        n = L["name"]
        c += (f"    {{{L['in_h']}, {L['in_w']}, {L['cin']}, {L['out_h']}, {L['out_w']}, {L['cout']}, "
              f"{L['k']}, {L['stride']}, {L['pad']}, {L['shift']}, {int(netdef.depthwise(n))}, "
              f"{L['lo']}, {L['hi']}, {mac}u, "
              f"nn_{n}_w, nn_{n}_bias, nn_{n}_mult}}, /* {n} */\n")
    c += "};\n"
    return h, c


INT8_HEADER = "weights_int8.h"


def sources(checkpoint, int8_header=False):
    """The files export() writes: {name: text}."""
    ckpt = load_checkpoint(checkpoint)
    meta = json.loads(str(ckpt["meta"]))
    layers = quantize(ckpt)
    h, c = c_sources(layers, meta, decode_rule(ckpt), INT8_HEADER if int8_header else None)
    files = {"weights.h": h, "weights.c": c}
    if int8_header:
        files[INT8_HEADER] = c_int8_header(layers, meta)
    return files


def export(checkpoint, out_dir, int8_header=False):
    files = sources(checkpoint, int8_header)
    os.makedirs(out_dir, exist_ok=True)
    for name, text in files.items():
        with open(os.path.join(out_dir, name), "w") as f:
            f.write(text)
    return files


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--checkpoint", default=DEFAULT_CHECKPOINT)
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--int8-header", action="store_true",
                    help=f"the int8 weights in {INT8_HEADER}, which weights.c includes")
    a = ap.parse_args()
    files = export(a.checkpoint, a.out, a.int8_header)
    print(f"wrote {a.out}/{', '.join(files)} "
          f"({sum(netdef.macs())} MAC, {netdef.params()} parameters)")


if __name__ == "__main__":
    main()
