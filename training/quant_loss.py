"""Where a checkpoint's int8 loss comes from (numpy; docs/NN.md "A finer
input"): the float network with some layers' roundings emulated
("fake-quant": weights rounded to export.quantize's per-channel int8 grid,
a ReLU output to the layer's act_max / 127 grid, everything else float),
decoded with the checkpoint's rule, against the float and the int8
reference's figures.

    python3 training/quant_loss.py DIR [--checkpoint training/checkpoint.npz]

Rows: each layer's weights, output, and both rounded alone; then the
layers up to each one rounded together (the last such row is within the
bias and head roundings of the int8 reference).
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402


def rounded_weights(w):
    """w (cout, k, k, cin) on export.quantize's grid: per output channel
    max|w| / 127, clipped to +-127 steps."""
    s = np.abs(w).reshape(len(w), -1).max(axis=1) / 127.0
    s[s == 0] = 1.0
    s = s[:, None, None, None]
    return np.clip(np.round(w / s), -127, 127) * s


def forward(ckpt, x, weights=(), outputs=(), batch=250):
    """The float head on int8 inputs x, the weights of the layers in
    `weights` and the ReLU outputs of those in `outputs` (indices into
    netdef.LAYERS) rounded to their int8 grids."""
    heads = []
    for s0 in range(0, len(x), batch):
        a = x[s0:s0 + batch].astype(np.float64) / 128
        for i, (name, k, stride, pad, _, _, relu) in enumerate(netdef.LAYERS):
            w = ckpt[f"{name}.w"].astype(np.float64)
            if i in weights:
                w = rounded_weights(w)
            a = int8_ref.apply_weights(int8_ref._patches(a, k, stride, pad), w) + ckpt[f"{name}.b"]
            if relu:
                a = np.maximum(a, 0.0)
                if i in outputs:
                    step = ckpt["act_max"][i] / 127
                    a = np.clip(np.round(a / step), 0, 127) * step
        heads.append(a)
    return np.concatenate(heads)


def line(label, m):
    return (f"{label:<32} {m['detection_rate']:7.1%} {m['false_positive_rate']:7.1%} "
            f"{m['mean_px_error']:8.2f} {m['p95_px_error']:8.2f}")


def main():
    ckpt, small, labels = export.checkpoint_and_dataset()
    x = netdef.to_int8(small)
    rule = export.decode_rule(ckpt, "float")

    def score(**rounded):
        return evaluate.metrics(evaluate.decode_float(forward(ckpt, x, **rounded), rule), labels)

    print(f"{'rounded':<32} detected  false+  mean px   p95 px")
    print(line("none (float)", score()), flush=True)
    names = [layer[0] for layer in netdef.LAYERS]
    relu = [layer[6] for layer in netdef.LAYERS]
    for i, name in enumerate(names):
        print(line(f"{name} weights", score(weights={i})), flush=True)
        if relu[i]:
            print(line(f"{name} output", score(outputs={i})), flush=True)
            print(line(f"{name} weights + output", score(weights={i}, outputs={i})), flush=True)
    for i, name in enumerate(names):
        upto = set(range(i + 1))
        print(line(f"{names[0]}-{name} weights + outputs", score(weights=upto, outputs=upto)),
              flush=True)
    res = int8_ref.infer_batch(export.quantize(ckpt), x, export.decode_rule(ckpt))
    preds = [(r["visible"], r["u_q4"] / 16, r["v_q4"] / 16, r["distance_mm"] / 1000) for r in res]
    print(line("int8 reference", evaluate.metrics(preds, labels)))


if __name__ == "__main__":
    main()
