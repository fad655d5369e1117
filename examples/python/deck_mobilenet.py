#!/usr/bin/env python3
"""A MobileNet-style network of your own onto the simulated AI deck, no
training needed (docs/NN_ONNX.md).

Builds a float MobileNetV1-style network with random weights (a 3x3
stride-2 stem, depthwise-separable blocks, global average pooling, a dense
layer) as ONNX, quantizes it for the deck with
`crazyflie_cosim.deck.quantize_for_deck` (onnxruntime's static quantizer:
QDQ, per-channel int8 weights, uint8 activations; calibrated on random
images), then has `cosim nn import` read it: the per-layer table (MACs,
weight bytes) and one inference of the host's integer reference, checked
against onnxruntime on the same file.

    python examples/python/deck_mobilenet.py [--width 0.25] [--size 96] [--out out/deck-mobilenet]

Needs onnx and onnxruntime (pip install onnx onnxruntime) and the binaries
built (cargo build --release -p scenarios).
"""

import argparse
import subprocess
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
from crazyflie_cosim.deck import quantize_for_deck
from crazyflie_cosim.server import find_checkout
from onnx import TensorProto, helper, numpy_helper

# MobileNetV1's depthwise-separable blocks (output channels, stride) at
# width 1 (Howard et al. 2017, Table 1), up to the 7x7 stage.
BLOCKS = [(64, 1), (128, 2), (128, 1), (256, 2), (256, 1), (512, 2), (512, 1), (1024, 2)]


def mobilenet(width: float, size: int, seed: int = 0) -> onnx.ModelProto:
    rng = np.random.default_rng(seed)
    nodes, inits = [], []

    def conv(x, cin, cout, k, stride, group=1):
        n = f"conv{len(nodes)}"
        w = rng.normal(0, np.sqrt(2 / (cin // group * k * k)), (cout, cin // group, k, k)).astype(np.float32)
        inits.extend([numpy_helper.from_array(w, n + "_w"),
                      numpy_helper.from_array(np.zeros(cout, np.float32), n + "_b")])
        nodes.append(helper.make_node("Conv", [x, n + "_w", n + "_b"], [n], name=n, kernel_shape=[k, k],
                                      strides=[stride, stride], pads=[k // 2] * 4, group=group))
        r = n + "_relu"
        nodes.append(helper.make_node("Relu", [n], [r], name=r))
        return r

    c = max(8, int(32 * width))
    x = conv("input", 1, c, 3, 2)
    for cout, stride in BLOCKS:
        cout = max(8, int(cout * width))
        x = conv(conv(x, c, c, 3, stride, group=c), c, cout, 1, 1)
        c = cout
    nodes.append(helper.make_node("GlobalAveragePool", [x], ["pool"], name="pool"))
    nodes.append(helper.make_node("Flatten", ["pool"], ["flat"], name="flat"))
    w = rng.normal(0, np.sqrt(1 / c), (4, c)).astype(np.float32)
    inits.extend([numpy_helper.from_array(w, "fc_w"), numpy_helper.from_array(np.zeros(4, np.float32), "fc_b")])
    nodes.append(helper.make_node("Gemm", ["flat", "fc_w", "fc_b"], ["output"], name="fc", transB=1))
    g = helper.make_graph(nodes, "mobilenet", [helper.make_tensor_value_info("input", TensorProto.FLOAT,
                                                                              [1, 1, size, size])],
                          [helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, 4])], inits)
    return helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=float, default=0.25, help="width multiplier (MobileNet's alpha)")
    ap.add_argument("--size", type=int, default=96, help="input side (grey images)")
    ap.add_argument("--out", type=Path, default=Path("out/deck-mobilenet"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    root = find_checkout()
    cosim = str(root / "target" / "release" / "cosim") if root else "cosim"

    float_model = a.out / "mobilenet.onnx"
    onnx.save(mobilenet(a.width, a.size), float_model)
    rng = np.random.default_rng(1)
    images = [rng.uniform(0, 1, (1, 1, a.size, a.size)).astype(np.float32) for _ in range(16)]
    q = quantize_for_deck(float_model, a.out / "mobilenet.q.onnx", images)

    subprocess.run([cosim, "nn", "import", str(q)], check=True)
    x = rng.uniform(0, 1, (1, 1, a.size, a.size)).astype(np.float32)
    np.save(a.out / "x.npy", x)
    subprocess.run([cosim, "nn", "import", str(q), "--input", str(a.out / "x.npy"),
                    "--output", str(a.out / "y.npy")], check=True)
    ours = np.load(a.out / "y.npy")
    (ref,) = ort.InferenceSession(str(q), providers=["CPUExecutionProvider"]).run(None, {"input": x})
    print(f"integer reference {ours.ravel()}\nonnxruntime       {ref.ravel()}")


if __name__ == "__main__":
    main()
