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
import json
import subprocess
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
from crazyflie_cosim.deck import quantize_for_deck
from crazyflie_cosim.server import find_checkout
from onnx import TensorProto, helper, numpy_helper

# MobileNetV1's depthwise-separable blocks (output channels, stride) at
# width 1 (Howard et al. 2017, Table 1).
BLOCKS = [(64, 1), (128, 2), (128, 1), (256, 2), (256, 1), (512, 2)] + [(512, 1)] * 5 + [(1024, 2), (1024, 1)]


def mobilenet(width: float, size: int, channels: int = 1, classes: int = 4, seed: int = 0) -> onnx.ModelProto:
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
    x = conv("input", channels, c, 3, 2)
    for cout, stride in BLOCKS:
        cout = max(8, int(cout * width))
        x = conv(conv(x, c, c, 3, stride, group=c), c, cout, 1, 1)
        c = cout
    nodes.append(helper.make_node("GlobalAveragePool", [x], ["pool"], name="pool"))
    nodes.append(helper.make_node("Flatten", ["pool"], ["flat"], name="flat"))
    w = rng.normal(0, np.sqrt(1 / c), (classes, c)).astype(np.float32)
    inits.extend([numpy_helper.from_array(w, "fc_w"), numpy_helper.from_array(np.zeros(classes, np.float32), "fc_b")])
    nodes.append(helper.make_node("Gemm", ["flat", "fc_w", "fc_b"], ["output"], name="fc", transB=1))
    g = helper.make_graph(nodes, "mobilenet", [helper.make_tensor_value_info("input", TensorProto.FLOAT,
                                                                              [1, channels, size, size])],
                          [helper.make_tensor_value_info("output", TensorProto.FLOAT, [1, classes])], inits)
    return helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=float, default=0.25, help="width multiplier (MobileNet's alpha)")
    ap.add_argument("--size", type=int, default=96, help="input side")
    ap.add_argument("--channels", type=int, default=1, help="input channels (1: the deck's grey camera)")
    ap.add_argument("--classes", type=int, default=4, help="outputs of the dense layer")
    ap.add_argument("--cores", default="1,2,4,8", help="cluster cores to profile")
    ap.add_argument("--mhz", default="50,100,175", help="cluster clocks to profile, MHz")
    ap.add_argument("--out", type=Path, default=Path("out/deck-mobilenet"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    root = find_checkout()
    cosim = str(root / "target" / "release" / "cosim") if root else "cosim"

    float_model = a.out / "mobilenet.onnx"
    onnx.save(mobilenet(a.width, a.size, a.channels, a.classes), float_model)
    shape = (1, a.channels, a.size, a.size)
    rng = np.random.default_rng(1)
    images = [rng.uniform(0, 1, shape).astype(np.float32) for _ in range(16)]
    q = quantize_for_deck(float_model, a.out / "mobilenet.q.onnx", images)

    subprocess.run([cosim, "nn", "import", str(q)], check=True)
    x = rng.uniform(0, 1, shape).astype(np.float32)
    np.save(a.out / "x.npy", x)
    subprocess.run([cosim, "nn", "run", str(q), "--input", str(a.out / "x.npy"),
                    "--output", str(a.out / "y.npy")], check=True)
    ours = np.load(a.out / "y.npy")
    # The QDQ graph as ONNX defines it (onnxruntime's fused int8 kernels
    # saturate on x86 CPUs without VNNI: docs/NN_ONNX.md).
    so = ort.SessionOptions()
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    (ref,) = ort.InferenceSession(str(q), so, providers=["CPUExecutionProvider"]).run(None, {"input": x})
    print(f"the deck (ISS)  {ours.ravel()[:8]}\nonnxruntime     {ref.ravel()[:8]}")

    print(f"{'cores':>5} {'MHz':>5} {'fps':>8} {'ms':>9} {'mJ':>8} {'MAC/cycle':>9}")
    for cores in map(int, a.cores.split(",")):
        for mhz in map(int, a.mhz.split(",")):
            d = a.out / f"profile-{cores}x{mhz}"
            subprocess.run([cosim, "nn", "profile", str(q), "--cores", str(cores), "--mhz", str(mhz),
                            "--out", str(d)], check=True, stdout=subprocess.DEVNULL)
            t = json.loads((d / "profile.json").read_text())["totals"]
            print(f"{cores:>5} {mhz:>5} {t['fps']:>8.1f} {t['latency_ms']:>9.3f} {t['energy_mj']:>8.3f}"
                  f" {t['mac_per_cycle']:>9.2f}")


if __name__ == "__main__":
    main()
