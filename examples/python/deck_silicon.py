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

DORY's MobileNet and DroNet hold activations beyond the deck's 512 kB L2
(a 64x64x64 map is 256 kB), which DORY and GreenWaves' tools keep in L3;
the runtime keeps activations in L2, so these two run in segments: each
segment (a conv and its ReLU, a residual block, the head) is cut out of the
float model with onnx.utils.extract_model, quantized and profiled on its
own, and the segments' cycles, times and energies add up (the traffic of
activations through L3 between segments is not counted).

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
        self.cuts = []

    def const_scalar(self, v: float) -> str:
        n = f"c{len(self.inits)}"
        self.inits.append(numpy_helper.from_array(np.array(v, np.float32), n))
        return n

    def conv(self, x, cin, cout, k, stride=1, pad=None, relu=True, group=1):
        n = f"conv{len(self.nodes)}"
        w = self.rng.normal(0, np.sqrt(2 / (cin // group * k * k)), (cout, cin // group, k, k)).astype(np.float32)
        self.inits += [numpy_helper.from_array(w, n + "_w"),
                       numpy_helper.from_array(np.zeros(cout, np.float32), n + "_b")]
        p = k // 2 if pad is None else pad
        self.nodes.append(helper.make_node("Conv", [x, n + "_w", n + "_b"], [n], name=n, kernel_shape=[k, k],
                                           strides=[stride, stride], pads=[p] * 4, group=group))
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

    def cut(self, x):
        """Marks `x` as a segment boundary."""
        self.cuts.append(x)
        return x

    def model(self, name, shape, out):
        g = helper.make_graph(self.nodes, name, [helper.make_tensor_value_info("input", TensorProto.FLOAT, shape)],
                              [helper.make_empty_tensor_value_info(out)], self.inits)
        m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)
        return onnx.shape_inference.infer_shapes(m)


def pulpnn_layer():
    g = Graph(1)
    return g.model("pulpnn_conv", [1, 32, 16, 16], g.conv("input", 32, 64, 3)), [1, 32, 16, 16]


def dronet_cuts(model):
    """The segment boundaries of dronet(): after the pool (the first conv
    with it: a pool alone is left in float by the quantizer) and after each
    residual block."""
    names = [n.output[0] for n in model.graph.node]
    pools = [o for o in names if o.startswith("maxpool")]
    relus_after_add = [names[i + 1] for i, o in enumerate(names) if o.startswith("add")]
    # The head (Flatten, Gemm) stays with the last block: a Flatten at a
    # graph input is left in float by the quantizer.
    return pools + relus_after_add[:-1]


def mobilenet_cuts(model):
    """After every conv's ReLU."""
    return [n.output[0] for n in model.graph.node if n.op_type == "Relu"]


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


def segments(model, cuts, where: Path, key: str):
    """The float model cut at the tensors `cuts`: (file, input shape) per
    segment, in order."""
    full = where / f"{key}.float.onnx"
    onnx.save(model, full)
    shapes = {v.name: [d.dim_value for d in v.type.tensor_type.shape.dim]
              for v in list(model.graph.value_info) + list(model.graph.input)}
    bounds = ["input"] + cuts + [model.graph.output[0].name]
    out = []
    for i, (a, b) in enumerate(zip(bounds, bounds[1:])):
        f = where / f"{key}.seg{i:02d}.onnx"
        onnx.utils.extract_model(str(full), str(f), [a], [b])
        # The segment's input named as the deck's tools expect it.
        m = onnx.load(f)
        for n in m.graph.node:
            n.input[:] = ["input" if x == a else x for x in n.input]
        m.graph.input[0].name = "input"
        onnx.save(m, f)
        out.append((f, shapes[a]))
    return out


def profile(cosim, q: Path, cores, mhz, vdd, d: Path) -> dict:
    subprocess.run([cosim, "nn", "profile", str(q), "--cores", str(cores), "--mhz", str(mhz),
                    "--vdd", str(vdd), "--out", str(d)], check=True, stdout=subprocess.DEVNULL)
    return json.loads((d / "profile.json").read_text())


def dronet_v3(tiny: bool):
    """PULP-Dronet v3 and Tiny-PULP-Dronet v3 (pulp-platform/pulp-dronet,
    tiny-pulp-dronet-v3/model/dronet_v3.py): a 5x5/2 conv and a 2x2/2 max
    pool, then three blocks, each halving the map: v3's residual blocks
    (3x3/2 and 3x3 convs with ReLU6, a 1x1/2 bypass with ReLU6, added) at
    depth 1 (32, 32, 64, 128 channels); Tiny's depthwise-separable blocks
    without bypass (3x3/2 depthwise, 1x1, 3x3 depthwise, 1x1, each with
    ReLU6) at depth 0.125 (4, 4, 8, 16 channels); a dense layer of two
    outputs."""
    g = Graph(3 if tiny else 4)
    c = 4 if tiny else 32

    def relu6(x):
        lo, hi = g.const_scalar(0.0), g.const_scalar(6.0)
        return g.op("Clip", [x, lo, hi])

    x = g.op("MaxPool", [relu6(g.conv("input", 1, c, 5, 2, relu=False))], kernel_shape=[2, 2], strides=[2, 2])
    for cout in (c, 2 * c, 4 * c):
        if tiny:
            d = relu6(g.conv(x, c, c, 3, 2, relu=False, group=c))
            p = relu6(g.conv(d, c, cout, 1, relu=False))
            d = relu6(g.conv(p, cout, cout, 3, relu=False, group=cout))
            x = g.cut(relu6(g.conv(d, cout, cout, 1, relu=False)))
        else:
            a = relu6(g.conv(relu6(g.conv(x, c, cout, 3, 2, relu=False)), cout, cout, 3, relu=False))
            b = relu6(g.conv(x, c, cout, 1, 2, pad=0, relu=False))
            x = g.cut(g.op("Add", [a, b]))
        c = cout
    g.cuts.pop()  # the head stays with the last block
    return g.model("dronet_v3", [1, 1, 200, 200], g.dense(g.op("Flatten", [x]), c * 7 * 7, 2)), g.cuts


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/deck-silicon"))
    ap.add_argument("--only", default="pulpnn,dory,dronet,dronet3,tiny3")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    root = find_checkout()
    cosim = str(root / "target" / "release" / "cosim") if root else "cosim"
    mb = mobilenet(1.0, 128, 3, 1000)
    dn, dn_shape = dronet()
    v3, v3_cuts = dronet_v3(tiny=False)
    tiny, _ = dronet_v3(tiny=True)
    cases = {
        # (model files with input shapes, [(cores, cluster MHz, supply V)]):
        # the published operating points.
        "pulpnn": (lambda: [(a.out / "pulpnn.onnx", pulpnn_layer())], [(8, 175, 1.2), (1, 175, 1.2)]),
        "dory": (lambda: segments(onnx.shape_inference.infer_shapes(mb), mobilenet_cuts(mb), a.out, "dory"),
                 [(8, 100, 1.0)]),
        "dronet": (lambda: segments(dn, dronet_cuts(dn), a.out, "dronet"), [(8, 100, 1.0), (8, 175, 1.2)]),
        # Both measured by their application at FC 250 MHz, cluster 175 MHz,
        # 1.2 V (tiny-pulp-dronet-v3's gap8-dronet-app main.c).
        "dronet3": (lambda: segments(onnx.shape_inference.infer_shapes(v3), v3_cuts, a.out, "dronet3"),
                    [(8, 175, 1.2)]),
        "tiny3": (lambda: segments(onnx.shape_inference.infer_shapes(tiny), [], a.out, "tiny3"), [(8, 175, 1.2)]),
    }
    results = {}
    for key in a.only.split(","):
        build, points = cases[key]
        parts = build()
        if key == "pulpnn":
            (f, (m, shape)), = parts
            onnx.save(m, f)
            parts = [(f, shape)]
        rng = np.random.default_rng(1)
        quantized = [quantize_for_deck(f, f.with_suffix(".q.onnx"),
                                       [rng.uniform(0, 1, shape).astype(np.float32) for _ in range(4)])
                     for f, shape in parts]
        for cores, mhz, vdd in points:
            profiles = [profile(cosim, q, cores, mhz, vdd, a.out / f"{key}-{cores}x{mhz}" / q.stem)
                        for q in quantized]
            layers = [layer for p in profiles for layer in p["layers"]]
            macs = sum(p["totals"]["macs"] for p in profiles)
            cycles = sum(p["totals"]["cycles"] for p in profiles)
            ms = sum(p["totals"]["latency_ms"] for p in profiles)
            mj = sum(p["totals"]["energy_mj"] for p in profiles)
            l3 = sum(p["totals"]["l3_bytes"] for p in profiles)
            results[f"{key}-{cores}x{mhz}"] = {"cores": cores, "mhz": mhz, "vdd": vdd, "segments": len(profiles),
                                               "macs": macs, "cycles": cycles, "latency_ms": ms, "energy_mj": mj,
                                               "l3_bytes": l3, "layers": layers}
            print(f"{key} {cores} cores {mhz} MHz {vdd} V ({len(profiles)} segments): {macs / 1e6:.2f} MMAC, "
                  f"{macs / cycles:.2f} MAC/cycle, {ms:.2f} ms ({1e3 / ms:.2f} fps), {mj:.3f} mJ "
                  f"({1e9 * mj / macs:.1f} pJ/MAC, {mj / ms * 1e3:.1f} mW), L3 {l3} B")
            for layer in layers:
                if layer["macs"]:
                    print(f"    {layer['name']:<12} {layer['op']:<10} {layer['macs'] / 1e6:7.2f} MMAC"
                          f" {layer['mac_per_cycle']:6.2f} MAC/cycle {layer['latency_ms']:8.3f} ms"
                          f" {1e3 * layer['energy_uj'] / max(layer['latency_ms'], 1e-9) / 1e3:6.1f} mW")
    (a.out / "silicon.json").write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
