"""`cosim nn import` against onnxruntime (docs/NN_ONNX.md).

Small float networks are written with ``onnx.helper``, quantized by
onnxruntime's own ``quantize_static`` (QDQ format, per-channel int8
weights, uint8 or int8 activations, calibrated on seeded random data), run
by onnxruntime for the reference output, and run by the host's integer
reference (``cosim nn import --input --output``). Every output value must
be within one output quantization step of onnxruntime's, and at least 99 %
of them equal to it."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx", reason="onnx is not installed (python/requirements-test.txt)")
ort = pytest.importorskip("onnxruntime", reason="onnxruntime is not installed (python/requirements-test.txt)")
from crazyflie_cosim.deck import quantize_for_deck  # noqa: E402
from onnx import TensorProto, helper, numpy_helper
from onnxruntime.quantization import (
    CalibrationDataReader,
    QuantFormat,
    QuantType,
    quantize_static,
)

# Inputs per model: the agreement is counted over all of their outputs.
RUNS = 4


class Net:
    """A float graph under construction: nodes and seeded initializers."""

    def __init__(self, name: str, shape: list[int], seed: int):
        self.name = name
        self.shape = shape
        self.rng = np.random.default_rng(seed)
        self.nodes: list = []
        self.inits: list = []
        self.count = 0

    def _name(self, op: str) -> str:
        self.count += 1
        return f"{op.lower()}{self.count}"

    def const(self, name: str, a: np.ndarray) -> str:
        self.inits.append(numpy_helper.from_array(a, name))
        return name

    def node(self, op: str, inputs: list[str], **attrs) -> str:
        n = self._name(op)
        self.nodes.append(helper.make_node(op, inputs, [n], name=n, **attrs))
        return n

    def conv(self, x: str, cin: int, cout: int, k: int, stride: int = 1, pads=None, group: int = 1) -> str:
        n = self._name("Conv")
        fan_in = cin // group * k * k
        w = self.rng.normal(0, 1 / np.sqrt(fan_in), (cout, cin // group, k, k)).astype(np.float32)
        b = self.rng.normal(0, 0.1, cout).astype(np.float32)
        pads = pads if pads is not None else [k // 2] * 4
        self.const(n + "_w", w)
        self.const(n + "_b", b)
        self.nodes.append(
            helper.make_node(
                "Conv",
                [x, n + "_w", n + "_b"],
                [n],
                name=n,
                kernel_shape=[k, k],
                strides=[stride, stride],
                pads=pads,
                group=group,
            )
        )
        return n

    def gemm(self, x: str, fin: int, fout: int) -> str:
        n = self._name("Gemm")
        w = self.rng.normal(0, 1 / np.sqrt(fin), (fout, fin)).astype(np.float32)
        b = self.rng.normal(0, 0.1, fout).astype(np.float32)
        self.const(n + "_w", w)
        self.const(n + "_b", b)
        self.nodes.append(helper.make_node("Gemm", [x, n + "_w", n + "_b"], [n], name=n, transB=1))
        return n

    def matmul(self, x: str, fin: int, fout: int) -> str:
        n = self._name("MatMul")
        w = self.rng.normal(0, 1 / np.sqrt(fin), (fin, fout)).astype(np.float32)
        self.const(n + "_w", w)
        self.nodes.append(helper.make_node("MatMul", [x, n + "_w"], [n], name=n))
        return n

    def relu6(self, x: str) -> str:
        lo = self.const(self._name("lo"), np.array(0.0, np.float32))
        hi = self.const(self._name("hi"), np.array(6.0, np.float32))
        return self.node("Clip", [x, lo, hi])

    def save(self, out: str, path: Path) -> Path:
        g = helper.make_graph(
            self.nodes,
            self.name,
            [helper.make_tensor_value_info("input", TensorProto.FLOAT, self.shape)],
            [helper.make_empty_tensor_value_info(out)],
            self.inits,
        )
        m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 13)], ir_version=8)
        # The output's shape as ONNX's shape inference gives it.
        m = onnx.shape_inference.infer_shapes(m)
        onnx.checker.check_model(m)
        onnx.save(m, path)
        return path


def mobilenet_block(net: Net, x: str, c: int) -> str:
    """A MobileNetV2 inverted residual: 1x1 expand + ReLU6, 3x3 depthwise
    + ReLU6, 1x1 project (linear), added to its input."""
    e = net.relu6(net.conv(x, c, 4 * c, 1))
    d = net.relu6(net.conv(e, 4 * c, 4 * c, 3, group=4 * c))
    p = net.conv(d, 4 * c, c, 1)
    return net.node("Add", [p, x])


def build(name: str, seed: int) -> tuple[Net, str]:
    """The named test network: (graph, output tensor)."""
    if name in ("gemm", "matmul", "sigmoid"):
        net = Net(name, [1, 32], seed)
        if name == "gemm":
            return net, net.gemm(net.node("Relu", [net.gemm("input", 32, 24)]), 24, 10)
        if name == "matmul":
            return net, net.matmul(net.node("Relu", [net.matmul("input", 32, 16)]), 16, 8)
        return net, net.node("Sigmoid", [net.gemm(net.node("Relu", [net.gemm("input", 32, 16)]), 16, 4)])
    net = Net(name, [1, 3, 16, 16] if name.startswith("conv3x3") else [1, 8, 12, 12], seed)
    x = "input"
    if name == "conv3x3_s1":
        return net, net.conv(x, 3, 8, 3, pads=[1, 1, 1, 1])
    if name == "conv3x3_s2":
        return net, net.conv(x, 3, 8, 3, stride=2, pads=[1, 0, 1, 1])
    if name == "depthwise":
        return net, net.conv(x, 8, 8, 3, group=8)
    if name == "grouped":
        return net, net.conv(x, 8, 12, 3, stride=2, group=4)
    if name == "conv1x1":
        return net, net.conv(x, 8, 16, 1)
    if name == "relu":
        return net, net.node("Relu", [net.conv(x, 8, 8, 3)])
    if name == "clip":
        return net, net.relu6(net.conv(x, 8, 8, 3))
    if name == "maxpool":
        c = net.node("Relu", [net.conv(x, 8, 8, 3)])
        m = net.node("MaxPool", [c], kernel_shape=[3, 3], strides=[2, 2], pads=[1, 1, 1, 1])
        return net, net.conv(m, 8, 8, 1)
    if name == "avgpool":
        # The pad counted: every window holds 9, and no sum is half-way
        # (test_avgpool_ties has the other case).
        c = net.node("Relu", [net.conv(x, 8, 8, 3)])
        a = net.node("AveragePool", [c], kernel_shape=[3, 3], strides=[1, 1], pads=[1, 1, 1, 1], count_include_pad=1)
        return net, net.conv(a, 8, 8, 1)
    if name == "avgpool_edges":
        c = net.node("Relu", [net.conv(x, 8, 8, 3)])
        return net, net.node("AveragePool", [c], kernel_shape=[3, 3], strides=[1, 1], pads=[1, 1, 1, 1])
    if name == "avgpool_2x2":
        c = net.node("Relu", [net.conv(x, 8, 8, 3)])
        return net, net.node("AveragePool", [c], kernel_shape=[2, 2], strides=[2, 2])
    if name == "globalavgpool":
        c = net.node("Relu", [net.conv(x, 8, 16, 3)])
        g = net.node("GlobalAveragePool", [c])
        return net, net.gemm(net.node("Flatten", [g]), 16, 10)
    if name == "add":
        c = net.conv(net.node("Relu", [net.conv(x, 8, 8, 3)]), 8, 8, 3)
        return net, net.node("Relu", [net.node("Add", [c, x])])
    if name == "concat":
        a = net.node("Relu", [net.conv(x, 8, 6, 3)])
        b = net.node("Relu", [net.conv(x, 8, 4, 1)])
        return net, net.conv(net.node("Concat", [a, b], axis=1), 10, 8, 1)
    if name == "flatten":
        c = net.node("Relu", [net.conv(x, 8, 4, 3, stride=2)])
        return net, net.gemm(net.node("Flatten", [c]), 4 * 6 * 6, 10)
    if name == "reshape":
        c = net.node("Relu", [net.conv(x, 8, 4, 3, stride=2)])
        shape = net.const("shape", np.array([1, -1], np.int64))
        return net, net.gemm(net.node("Reshape", [c, shape]), 4 * 6 * 6, 10)
    if name.startswith("mobilenet_body"):
        # The same blocks, their feature map as the output.
        s = net.relu6(net.conv(x, 8, 16, 3, stride=2))
        return net, mobilenet_block(net, mobilenet_block(net, s, 16), 16)
    if name.startswith("mobilenet"):
        # A stem, two inverted residual blocks, a head: GAP, Flatten, Gemm,
        # Sigmoid.
        s = net.relu6(net.conv(x, 8, 16, 3, stride=2))
        b = mobilenet_block(net, mobilenet_block(net, s, 16), 16)
        g = net.node("GlobalAveragePool", [b])
        return net, net.node("Sigmoid", [net.gemm(net.node("Flatten", [g]), 16, 4)])
    raise ValueError(name)


class Reader(CalibrationDataReader):
    def __init__(self, shape: list[int], seed: int, n: int = 32):
        rng = np.random.default_rng(seed)
        self.data = iter([{"input": rng.normal(0, 1, shape).astype(np.float32)} for _ in range(n)])

    def get_next(self):
        return next(self.data, None)


def quantized(tmp: Path, name: str, activation=QuantType.QUInt8, symmetric=False) -> tuple[Path, Net]:
    net, out = build(name.removesuffix("_sym"), seed=sum(map(ord, name)))
    f = net.save(out, tmp / f"{name}.onnx")
    q = tmp / f"{name}.q.onnx"
    rng = np.random.default_rng(1)
    calibration = [rng.normal(0, 1, net.shape).astype(np.float32) for _ in range(32)]
    if not symmetric:
        # What a user calls (crazyflie_cosim.deck).
        acts = "uint8" if activation == QuantType.QUInt8 else "int8"
        return quantize_for_deck(f, q, calibration, activations=acts), net
    quantize_static(
        str(f),
        str(q),
        Reader(net.shape, seed=1),
        quant_format=QuantFormat.QDQ,
        per_channel=True,
        weight_type=QuantType.QInt8,
        activation_type=activation,
        # Symmetric activations keep a Relu or Clip as its own node between
        # DequantizeLinear and QuantizeLinear (asymmetric ones fold it into
        # the previous output's range).
        extra_options={"ActivationSymmetric": symmetric},
    )
    return q, net


def reference_session(path: Path):
    """onnxruntime running the QDQ graph as ONNX defines it:
    DequantizeLinear, the float op, QuantizeLinear. Its graph optimizations
    (off here) fuse those into int8 kernels, which on x86 CPUs without
    VNNI multiply uint8 by int8 with pairwise sums saturating at int16
    (onnxruntime's quantization documentation, "reduce_range"): tens of
    steps off on such machines, exact on others."""
    so = ort.SessionOptions()
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


def beyond_one_step(off: np.ndarray) -> float:
    """The share of values more than one step off. onnxruntime computes the
    QDQ graph in float (reference_session): where an intermediate layer's
    sum lies within float noise of a rounding tie, it may round the other
    way, one step, and the next layer multiplies that step by its scale
    ratio (a residual Add by s_in/s_out, up to 2 in the test networks).
    Single layers are never more than one step off."""
    return float(np.mean(off > 1 + 1e-3))


def output_scale(path: Path) -> float:
    """The scale of the DequantizeLinear the graph's output comes from
    (through an output Sigmoid, if any)."""
    m = onnx.load(path)
    g = m.graph
    inits = {t.name: numpy_helper.to_array(t) for t in g.initializer}
    by_out = {o: n for n in g.node for o in n.output}
    n = by_out[g.output[0].name]
    if n.op_type == "Sigmoid":
        n = by_out[n.input[0]]
    assert n.op_type == "DequantizeLinear", n.op_type
    return float(inits[n.input[1]])


def steps_off(ours: np.ndarray, ref: np.ndarray, scale: float, sigmoid: bool) -> np.ndarray:
    """|ours − ref| in output quantization steps (before an output Sigmoid:
    both are taken back through the logit)."""
    if sigmoid:
        ours, ref = (np.log(v / (1 - v)) for v in (ours.astype(np.float64), ref.astype(np.float64)))
    return np.abs(ours.astype(np.float64) - ref.astype(np.float64)) / scale


MODELS = [
    "conv3x3_s1",
    "conv3x3_s2",
    "depthwise",
    "grouped",
    "conv1x1",
    "relu",
    "clip",
    "relu_sym",
    "clip_sym",
    "maxpool",
    "avgpool",
    "globalavgpool",
    "add",
    "concat",
    "gemm",
    "matmul",
    "flatten",
    "reshape",
    "sigmoid",
    "mobilenet",
    "mobilenet_int8",
    "mobilenet_body",
    "mobilenet_body_int8",
]


def run_import(binaries, model, x, where):
    """`cosim nn import MODEL --input X --output Y` on `x`; returns Y."""
    where.mkdir(parents=True, exist_ok=True)
    xp, yp = where / "x.npy", where / "y.npy"
    np.save(xp, x)
    r = subprocess.run(
        [binaries["cosim"], "nn", "import", model, "--input", xp, "--output", yp],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    return np.load(yp)


@pytest.mark.parametrize("name", MODELS)
def test_agrees_with_onnxruntime(name, tmp_path, binaries):
    sym = name.endswith("_sym")
    act = QuantType.QInt8 if name.endswith("_int8") or sym else QuantType.QUInt8
    q, net = quantized(tmp_path, name, act, symmetric=sym)
    table = subprocess.run(
        [binaries["cosim"], "nn", "import", q], check=False, capture_output=True, text=True, timeout=120
    )
    assert table.returncode == 0, table.stderr
    total = table.stdout.splitlines()[-1].split()
    assert total[0] == "total", table.stdout
    if name == "conv3x3_s1":
        # Cout·Hout·Wout·Cin·Kh·Kw; int8 weights and int32 biases.
        assert total[-2:] == [str(8 * 16 * 16 * 3 * 9), str(8 * 3 * 9 + 4 * 8)], table.stdout
    if name == "relu_sym":
        assert "Relu" in table.stdout, table.stdout
    if name == "gemm":
        assert total[-2:] == [str(32 * 24 + 24 * 10), str(32 * 24 + 24 * 10 + 4 * (24 + 10))], table.stdout
    sess = reference_session(q)
    scale = output_scale(q)
    sigmoid = name == "sigmoid" or name in ("mobilenet", "mobilenet_int8")
    rng = np.random.default_rng(7)
    offs = []
    for k in range(RUNS):
        x = rng.normal(0, 1, net.shape).astype(np.float32)
        ours = run_import(binaries, q, x, tmp_path / f"run{k}")
        (ref,) = sess.run(None, {"input": x})
        assert ours.shape == ref.shape and ours.dtype == np.float32
        offs.append(steps_off(ours, ref, scale, sigmoid).ravel())
    off = np.concatenate(offs)
    exact = float(np.mean(off < 1e-3))
    print(f"{name}: {off.size} values, {100 * exact:.2f} % exact, max {off.max():.3f} steps off")
    assert beyond_one_step(off) <= 0.001, f"{name}: {off.max()} steps off"
    assert exact >= 0.99, f"{name}: {100 * exact:.2f} % exact"


def window_sums(q: np.ndarray, zp: int, k: int, stride: int, pad: int) -> tuple[np.ndarray, np.ndarray]:
    """Each AveragePool window's sum of (q - zp) and its count (the pad not
    counted)."""
    v = np.pad(q.astype(np.int64) - zp, ((0, 0), (0, 0), (pad, pad), (pad, pad)))
    ones = np.pad(np.ones_like(q, np.int64), ((0, 0), (0, 0), (pad, pad), (pad, pad)))
    ho = (v.shape[2] - k) // stride + 1
    wo = (v.shape[3] - k) // stride + 1
    win = lambda a: sum(
        a[:, :, i : i + stride * ho : stride, j : j + stride * wo : stride] for i in range(k) for j in range(k)
    )
    return win(v), win(ones)


@pytest.mark.parametrize("name,k,stride,pad", [("avgpool_edges", 3, 1, 1), ("avgpool_2x2", 2, 2, 0)])
def test_avgpool_ties(name, k, stride, pad, tmp_path, binaries):
    """An average pool that keeps its input's scale rounds sum / count. Where
    the sum is exactly half-way (3 over 6 inputs, 2 over 4), the integer
    reference rounds half to even, and onnxruntime, which sums dequantized
    floats, lands either side of the half by float32 rounding: the two
    differ there by one step, and nowhere else."""
    q, net = quantized(tmp_path, name)
    m = onnx.load(q)
    pool = next(n for n in m.graph.node if n.op_type == "AveragePool")
    dq = next(n for n in m.graph.node if n.output[0] == pool.input[0])
    inits = {t.name: numpy_helper.to_array(t) for t in m.graph.initializer}
    zp = int(inits[dq.input[2]])
    # The pool's quantized input as a second output of onnxruntime's run.
    m.graph.output.append(helper.make_empty_tensor_value_info(dq.input[0]))
    probe = tmp_path / "probe.onnx"
    onnx.save(m, probe)
    sess = reference_session(probe)
    scale = output_scale(q)
    rng = np.random.default_rng(7)
    offs, ties = [], []
    for i in range(RUNS):
        x = rng.normal(0, 1, net.shape).astype(np.float32)
        ours = run_import(binaries, q, x, tmp_path / f"run{i}")
        ref, pool_in = sess.run(None, {"input": x})
        sums, counts = window_sums(pool_in, zp, k, stride, pad)
        offs.append(np.abs(ours.astype(np.float64) - ref) / scale)
        ties.append(2 * (sums % counts) == counts)
    off, tie = np.concatenate(offs).ravel(), np.concatenate(ties).ravel()
    assert off.shape == tie.shape
    differ = off > 1e-3
    print(
        f"{name}: {off.size} values, {100 * np.mean(~differ):.2f} % exact, max {off.max():.3f} steps off; "
        f"{100 * tie.mean():.2f} % half-way sums, {100 * differ[tie].mean():.1f} % of them differ"
    )
    assert off.max() <= 1 + 1e-3
    assert not differ[~tie].any(), "a difference where the sum is not half-way"
    # Both roundings do occur at ties (else the case is not exercised).
    assert tie.any() and differ.any()


def test_unsupported_op_is_one_line_naming_node_and_op(tmp_path, binaries):
    """A Softmax mid-graph: refused on one line naming the node and its op,
    with a non-zero exit."""
    net = Net("softmax", [1, 8, 12, 12], seed=3)
    c = net.conv("input", 8, 8, 3)
    s = net.node("Softmax", [c], axis=1)
    out = net.conv(s, 8, 8, 1)
    f = net.save(out, tmp_path / "softmax.onnx")
    rng = np.random.default_rng(1)
    q = quantize_for_deck(f, tmp_path / "softmax.q.onnx",
                          [rng.normal(0, 1, net.shape).astype(np.float32) for _ in range(32)])
    np.save(tmp_path / "x.npy", rng.normal(0, 1, net.shape).astype(np.float32))
    for cmd in (["import"], ["run", "--input", tmp_path / "x.npy"], ["profile", "--out", tmp_path / "p"]):
        r = subprocess.run([binaries["cosim"], "nn", cmd[0], q, *cmd[1:]], check=False, capture_output=True,
                           text=True, timeout=60)
        assert r.returncode != 0, cmd
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1, r.stderr
        assert '"softmax2"' in lines[0] and "(Softmax)" in lines[0], lines[0]


# On the simulated deck: `cosim nn run`, the generic runtime on the ISS.


def run_deck(binaries, model, x, where, *extra) -> tuple[np.ndarray, str]:
    """`cosim nn run MODEL --input X --output Y` on `x`; returns Y and the
    command's report line."""
    where.mkdir(parents=True, exist_ok=True)
    xp, yp = where / "x.npy", where / "y.npy"
    np.save(xp, x)
    r = subprocess.run(
        [binaries["cosim"], "nn", "run", model, "--input", xp, "--output", yp, *extra],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    return np.load(yp), r.stderr


@pytest.mark.parametrize("name", MODELS + ["avgpool_edges", "avgpool_2x2"])
def test_deck_equals_the_reference_and_onnxruntime(name, tmp_path, binaries):
    """The runtime on the ISS computes what the host's integer reference
    computes, bit for bit, so it is within one step of onnxruntime and
    equal to it on at least 90 % of the values (the pools with half-way
    sums: 98 %; the others: 100 %), and the argmax is onnxruntime's."""
    sym = name.endswith("_sym")
    act = QuantType.QInt8 if name.endswith("_int8") or sym else QuantType.QUInt8
    q, net = quantized(tmp_path, name, act, symmetric=sym)
    sess = reference_session(q)
    scale = output_scale(q)
    sigmoid = name == "sigmoid" or name in ("mobilenet", "mobilenet_int8")
    x = np.random.default_rng(11).normal(0, 1, net.shape).astype(np.float32)
    ours, _ = run_deck(binaries, q, x, tmp_path / "deck")
    reference = run_import(binaries, q, x, tmp_path / "reference")
    (ort_y,) = sess.run(None, {"input": x})
    assert ours.shape == ort_y.shape and ours.dtype == np.float32
    assert np.array_equal(ours, reference), f"{name}: the deck differs from the integer reference"
    off = steps_off(ours, ort_y, scale, sigmoid).ravel()
    exact = float(np.mean(off < 1e-3))
    print(f"{name} on the deck: {off.size} values, {100 * exact:.2f} % exact, max {off.max():.3f} steps off")
    assert beyond_one_step(off) <= 0.001 and exact >= 0.9
    if ours.ndim == 2 and ours.shape[1] > 1:
        assert np.argmax(ours) == np.argmax(ort_y)


def big_dense(tmp: Path) -> tuple[Path, Net]:
    """Weights (530 kB) beyond the deck's 512 kB L2: they must stream from
    the HyperRAM."""
    net = Net("big_dense", [1, 1024], seed=5)
    out = net.gemm(net.node("Relu", [net.gemm("input", 1024, 512)]), 512, 10)
    f = net.save(out, tmp / "big_dense.onnx")
    rng = np.random.default_rng(1)
    cal = [rng.normal(0, 1, net.shape).astype(np.float32) for _ in range(32)]
    return quantize_for_deck(f, tmp / "big_dense.q.onnx", cal), net


def l3_bytes(report: str) -> int:
    return int(report.split(" B from L3")[0].rsplit(maxsplit=1)[-1])


def test_weights_beyond_l2_stream_from_l3(tmp_path, binaries):
    q, net = big_dense(tmp_path)
    x = np.random.default_rng(3).normal(0, 1, net.shape).astype(np.float32)
    ours, report = run_deck(binaries, q, x, tmp_path / "deck")
    assert l3_bytes(report) >= 1024 * 512 + 512 * 10, report
    assert np.array_equal(ours, run_import(binaries, q, x, tmp_path / "reference"))
    (ort_y,) = reference_session(q).run(None, {"input": x})
    assert steps_off(ours, ort_y, output_scale(q), False).max() <= 1 + 1e-3
    assert np.argmax(ours) == np.argmax(ort_y)


@pytest.mark.parametrize("n", [16, 64, 100, 200, 400])
def test_l3_waits_end_whatever_their_length(n, tmp_path, binaries):
    """A Gemm 128 -> n from L3: the FC polls the µDMA's count of finished
    transfers while the read runs, and the ISS skips that loop's idle
    iterations; with these lengths an iteration straddles the transfer's
    end (once a lost wake-up: the run stalled)."""
    net = Net(f"g{n}", [1, 128], seed=n)
    f = net.save(net.gemm("input", 128, n), tmp_path / "g.onnx")
    rng = np.random.default_rng(1)
    q = quantize_for_deck(f, tmp_path / "g.q.onnx", [rng.normal(0, 1, net.shape).astype(np.float32) for _ in range(8)])
    x = rng.normal(0, 1, net.shape).astype(np.float32)
    ours, report = run_deck(binaries, q, x, tmp_path / "deck", "--weights", "l3")
    assert l3_bytes(report) == 128 * n
    assert np.array_equal(ours, run_import(binaries, q, x, tmp_path / "reference"))


def test_weights_forced_to_l3_give_the_same_output_later(tmp_path, binaries):
    q, net = quantized(tmp_path, "mobilenet_body")
    x = np.random.default_rng(4).normal(0, 1, net.shape).astype(np.float32)
    in_l2, r2 = run_deck(binaries, q, x, tmp_path / "l2")
    in_l3, r3 = run_deck(binaries, q, x, tmp_path / "l3", "--weights", "l3")
    assert np.array_equal(in_l2, in_l3)
    assert l3_bytes(r2) == 0 and l3_bytes(r3) > 0, (r2, r3)
    ms = [float(r.split(": ")[2].split(" ms")[0]) for r in (r2, r3)]
    assert ms[1] > ms[0], ms


def test_profile_counts_macs_and_its_layers_add_up(tmp_path, binaries):
    q, _ = quantized(tmp_path, "mobilenet")
    out = tmp_path / "profile"
    r = subprocess.run([binaries["cosim"], "nn", "profile", q, "--cores", "4", "--mhz", "100", "--out", out],
                       check=False, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    p = json.loads((out / "profile.json").read_text())
    assert (out / "profile.png").stat().st_size > 10_000
    assert (p["cores"], p["mhz"]) == (4, 100)
    table = subprocess.run([binaries["cosim"], "nn", "import", q], check=True, capture_output=True, text=True)
    rows = [line.split() for line in table.stdout.splitlines()[1:-2]]
    assert [layer["name"] for layer in p["layers"]] == [row[0] for row in rows]
    assert [layer["macs"] for layer in p["layers"]] == [int(row[-2]) for row in rows]
    t = p["totals"]
    assert t["macs"] == sum(layer["macs"] for layer in p["layers"]) == int(table.stdout.split()[-2])
    assert t["cycles"] == sum(layer["cycles"] for layer in p["layers"]) > 0
    assert sum(layer["latency_ms"] for layer in p["layers"]) == pytest.approx(t["latency_ms"], rel=0.05)
    assert sum(layer["energy_uj"] for layer in p["layers"]) == pytest.approx(1e3 * t["energy_mj"], rel=0.05)
    assert t["fps"] == pytest.approx(1e3 / t["latency_ms"])
    for layer in p["layers"]:
        assert layer["l1_bytes"] <= 64 * 1024
        if layer["macs"]:
            assert layer["mac_per_cycle"] == pytest.approx(layer["macs"] / layer["cycles"])
