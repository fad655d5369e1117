#!/usr/bin/env python3
"""The simulated AI deck beside published GAP8 measurements, on the same
network shapes (docs/NN_SILICON.md).

Builds, with random weights (weights do not change a layer's cycles), the
shapes whose GAP8 figures are published, quantizes them for the deck
(`crazyflie_cosim.deck.quantize_for_deck`) and profiles them with `cosim nn
profile` at the published operating points:

- PULP-NN's benchmark convolution (Garofalo et al. 2020): 16x16x32 input,
  64 filters 3x3, stride 1, pad 1; 8 cores (MAC/cycle).
- DORY's 1.0-MobileNetV1-128 (Burrello et al. 2021): 3x128x128 input,
  1000 classes; 8 cores at 100 MHz (fps, pJ/MAC, each layer's MAC/cycle).
- PULP-DroNet (Palossi et al. 2019): DroNet's ResNet-8 on a 200x200 grey
  frame, two outputs; 8 cores at 100 MHz (fps, mJ per frame).

    python examples/python/deck_silicon.py [--out out/deck-silicon] [--only pulpnn,dory,dronet]

Prints one line per figure and writes out/deck-silicon/silicon.json.
Needs onnx and onnxruntime and the binaries built (cargo build --release
-p scenarios).
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnx
from crazyflie_cosim.deck import quantize_for_deck
from crazyflie_cosim.server import find_checkout
from onnx import TensorProto, helper, numpy_helper

sys.path.insert(0, str(Path(__file__).resolve().parent))
from deck_mobilenet import mobilenet  # noqa: E402


class Graph:
    """A float graph with seeded He-normal weights and zero biases."""

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)
        self.nodes, self.inits = [], []

    def conv(self, x, cin, cout, k, stride=1, pad=None, relu=True):
        n = f"conv{len(self.nodes)}"
        w = self.rng.normal(0, np.sqrt(2 / (cin * k * k)), (cout, cin, k, k)).astype(np.float32)
        self.inits += [numpy_helper.from_array(w, n + "_w"),
                       numpy_helper.from_array(np.zeros(cout, np.float32), n + "_b")]
        p = k // 2 if pad is None else pad
        self.nodes.append(helper.make_node("Conv", [x, n + "_w", n + "_b"], [n], name=n, kernel_shape=[k, k],
                                           strides=[stride, stride], pads=[p] * 4))
        return self.op("Relu", [n]) if relu else n

    def op(self, op, inputs, **attrs):
        n = f"{op.lower()}{len(self.nodes)}"
        self.nodes.append(helper.make_node(op, inputs, [n], name=n, **attrs))
        return n

    def dense(self, x, fin, fout):
        n = f"fc{len(self.nodes)}"
        w = self.rng.normal(0, np.sqrt(1 / fin), (fout, fin)).astype(np.float32)
        self.inits += [numpy_helper.from_array(w, n + "_w"),
                       numpy_helper.from_array(np.zeros(fout, np.float32), n + "_b")]
        self.nodes.append(helper.make_node("Gemm", [x, n + "_w", n + "_b"], [n], name=n, transB=1))
        return n

    def model(self, name, shape, out):
        g = helper.make_graph(self.nodes, name, [helper.make_tensor_value_info("input", TensorProto.FLOAT, shape)],
                              [helper.make_empty_tensor_value_info(out)], self.inits)
        m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)
        return onnx.shape_inference.infer_shapes(m)


def pulpnn_layer():
    g = Graph(1)
    return g.model("pulpnn_conv", [1, 32, 16, 16], g.conv("input", 32, 64, 3)), [1, 32, 16, 16]


def dronet():
    """DroNet (Loquercio et al. 2018, Fig. 2): a 5x5/2 conv, a 3x3/2 max
    pool, three residual blocks (32, 64, 128 channels, each two 3x3 convs,
    the first of stride 2, and a 1x1/2 shortcut), then the two heads as one
    dense layer of two outputs."""
    g = Graph(2)
    x = g.op("MaxPool", [g.conv("input", 1, 32, 5, 2)], kernel_shape=[3, 3], strides=[2, 2], pads=[1, 1, 1, 1])
    c = 32
    for cout in (32, 64, 128):
        a = g.conv(g.conv(x, c, cout, 3, 2), cout, cout, 3, relu=False)
        s = g.conv(x, c, cout, 1, 2, pad=0, relu=False)
        x = g.op("Relu", [g.op("Add", [a, s])])
        c = cout
    f = g.op("Flatten", [x])
    return g.model("dronet", [1, 1, 200, 200], g.dense(f, 128 * 7 * 7, 2)), [1, 1, 200, 200]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/deck-silicon"))
    ap.add_argument("--only", default="pulpnn,dory,dronet")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    root = find_checkout()
    cosim = str(root / "target" / "release" / "cosim") if root else "cosim"
    cases = {
        # (cores, cluster MHz, supply V): the published operating points.
        "pulpnn": (pulpnn_layer, [(8, 175, 1.2), (1, 175, 1.2)]),
        "dory": (lambda: (mobilenet(1.0, 128, 3, 1000), [1, 3, 128, 128]), [(8, 100, 1.0)]),
        "dronet": (dronet, [(8, 100, 1.0), (8, 175, 1.2)]),
    }
    results = {}
    for key in a.only.split(","):
        build, points = cases[key]
        model, shape = build()
        f = a.out / f"{key}.onnx"
        onnx.save(model, f)
        rng = np.random.default_rng(1)
        q = quantize_for_deck(f, a.out / f"{key}.q.onnx",
                              [rng.uniform(0, 1, shape).astype(np.float32) for _ in range(8)])
        for cores, mhz, vdd in points:
            d = a.out / f"{key}-{cores}x{mhz}"
            subprocess.run([cosim, "nn", "profile", str(q), "--cores", str(cores), "--mhz", str(mhz),
                            "--vdd", str(vdd), "--out", str(d)], check=True, stdout=subprocess.DEVNULL)
            p = json.loads((d / "profile.json").read_text())
            t = p["totals"]
            results[f"{key}-{cores}x{mhz}"] = p
            print(f"{key} {cores} cores {mhz} MHz {vdd} V: {t['macs'] / 1e6:.2f} MMAC, {t['mac_per_cycle']:.2f} MAC/cycle, "
                  f"{t['latency_ms']:.2f} ms ({t['fps']:.1f} fps), {t['energy_mj']:.3f} mJ "
                  f"({1e9 * t['energy_mj'] / t['macs']:.1f} pJ/MAC), L3 {t['l3_bytes']} B")
    (a.out / "silicon.json").write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
