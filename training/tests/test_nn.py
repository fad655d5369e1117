"""The committed network's artefacts agree with each other (numpy only, no
JAX): `python3 -m pytest training/tests` (docs/NN.md).

- the committed C weights are exactly the export of the committed checkpoint;
- the int8 reference reproduces the committed golden outputs bit for bit;
- the int8 arithmetic is the documented one, on a layer small enough to
  compute by hand;
- int8 and float agree on the golden images (same cell, centre within 4 px).
"""

import json
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import make_fallback  # noqa: E402
import make_golden  # noqa: E402
import netdef  # noqa: E402


# The committed networks: (checkpoint, C weights directory, golden outputs).
# The depthwise-separable one (docs/NN.md "Depthwise-separable") is built
# into nn_eval_sep.elf, whose e2e test checks it against its golden file.
SEP = os.path.join(os.path.dirname(HERE), "sep")
NETWORKS = [
    (export.DEFAULT_CHECKPOINT, export.DEFAULT_OUT, os.path.join(make_golden.GOLDEN, "golden.json")),
    (os.path.join(SEP, "checkpoint.npz"), os.path.join(export.DEFAULT_OUT, "sep"),
     os.path.join(SEP, "golden.json")),
]
# The networks exported with `--int8-header` (their int8 weights in
# weights_int8.h, which the fallback network's weights.c includes too).
INT8_HEADER = {os.path.join(export.DEFAULT_OUT, "sep")}


@pytest.mark.parametrize("checkpoint, out, _", NETWORKS)
def test_committed_c_weights_are_the_export_of_the_checkpoint(checkpoint, out, _, base_net):
    files = export.sources(checkpoint, out in INT8_HEADER)
    assert (export.INT8_HEADER in files) == os.path.exists(os.path.join(out, export.INT8_HEADER))
    for name, want in files.items():
        with open(os.path.join(out, name)) as f:
            assert f.read() == want, f"{out}/{name} differs: run python3 training/export.py"


@pytest.mark.parametrize("checkpoint, _, golden", NETWORKS)
def test_int8_reference_reproduces_the_golden_outputs(checkpoint, _, golden, base_net):
    with open(golden) as f:
        committed = json.load(f)
    assert len(committed["images"]) >= 5
    assert any(e["outputs"]["visible"] for e in committed["images"])
    assert committed == make_golden.golden(checkpoint)


def test_fallback_network_is_the_scaled_sep_checkpoint_out_of_the_clip_first_form(base_net):
    """training/make_fallback.py's network, which nn_eval_fallback.elf runs
    against training/fallback/golden.json (tests/tests/e2e/nn_eval.rs): the
    committed files are the script's output, and the layers it means to
    take out of the kernels' clip-first requantization are out of it, in
    the forms it names (so the e2e test runs the fallback paths)."""
    h, c = make_fallback.sources()
    for name, want in (("weights.h", h), ("weights.c", c)):
        with open(os.path.join(make_fallback.OUT, name)) as f:
            assert f.read() == want, f"{name} differs: run python3 training/make_fallback.py"
    with open(make_fallback.GOLDEN) as f:
        assert json.load(f) == json.loads(json.dumps(make_fallback.golden()))
    forms = make_fallback.layer_forms(export.quantize(make_fallback.checkpoint()))
    assert sorted(n for n, f in forms.items() if f == "fast") == sorted(make_fallback.FAST)
    assert sorted(n for n, f in forms.items() if f == "general") == sorted(make_fallback.GENERAL)
    # The committed networks take the clip-first form in every layer.
    for checkpoint, _, _ in NETWORKS:
        q = export.quantize(export.load_checkpoint(checkpoint))
        assert set(make_fallback.layer_forms(q).values()) == {"clip"}, checkpoint


def test_requantization_rounds_half_up_and_pads_with_zeros():
    # One 3x3 stride-2 convolution, 1 -> 1 channel, on a 2x2 input of 1s:
    # output (0, 0) sees in[0..1][0..1] at taps (1..2, 1..2), the rest is
    # padding.
    layer = {"k": 3, "stride": 2, "pad": 1, "cout": 1,
             "w": np.arange(1, 10, dtype=np.int8).reshape(1, 3, 3, 1),
             "bias": np.array([-3], np.int32), "mult": np.array([3], np.int32),
             "shift": 2, "lo": 0, "hi": 127}
    x = np.ones((1, 2, 2, 1), np.int8)
    acc = (5 + 6 + 8 + 9) - 3  # 25
    got = int8_ref.layer_int8(layer, x)
    assert got.shape == (1, 1, 1, 1)
    assert int(got[0, 0, 0, 0]) == (acc * 3 + 2) >> 2 == 19  # 75/4 = 18.75
    # Exactly half: 2 * 3 = 6, 6/4 = 1.5 -> 2 (half up); negative: ReLU clip.
    layer["bias"] = np.array([2 - 28], np.int32)
    assert int(int8_ref.layer_int8(layer, x)[0, 0, 0, 0]) == 2
    layer["bias"] = np.array([-30 - 28], np.int32)
    assert int(int8_ref.layer_int8(layer, x)[0, 0, 0, 0]) == 0
    # -1.5 rounds half up to -1 (the head's clip range keeps the sign).
    layer.update(lo=-32768, hi=32767, bias=np.array([-2 - 28], np.int32))
    assert int(int8_ref.layer_int8(layer, x)[0, 0, 0, 0]) == -1


def test_downsampling_rounds_the_block_mean():
    img = np.zeros((1, 320, 320), np.uint8)
    img[0, :4, 0] = 1  # sum 4 -> (4+8)>>4 = 0
    img[0, :4, 4:8] = 1  # sum 16 -> 1
    img[0, :4, 8:12] = [[1, 1, 0, 0]] * 4  # sum 8 -> (8+8)>>4 = 1 (half up)
    small = netdef.downsample(img)
    assert small[0, 0, :3].tolist() == [0, 1, 1]


def test_int8_agrees_with_float_on_the_golden_images():
    """Where both decodings report a gate clearly (the float objectness
    half a logit above the threshold), they place it within 4 px."""
    ckpt = export.load_checkpoint(export.DEFAULT_CHECKPOINT)
    q, rule = export.quantize(ckpt), export.decode_rule(ckpt)
    rule_f = export.decode_rule(ckpt, "float")
    threshold = 0.0 if rule_f is None else rule_f["threshold"]
    compared = 0
    for r in netdef.read_labels(make_golden.GOLDEN):
        image = netdef.read_pgm(os.path.join(make_golden.GOLDEN, r["file"]))
        x, head, out = int8_ref.infer_image(q, image, rule)
        f = int8_ref.float_forward(ckpt, x[None].astype(np.float64) / 128.0)
        visible, fu, fv, _ = evaluate.decode_float(f, rule_f)[0]
        if out["visible"] and visible and f[0, ..., 0].max() > threshold + 0.5:
            assert abs(out["u_q4"] / 16 - fu) < 4 and abs(out["v_q4"] / 16 - fv) < 4
            compared += 1
    assert compared >= 3


def test_folding_batch_norm_keeps_the_network():
    """train.fold_bn: the plain network it returns computes, on a batch,
    what the batch-normalised one computes with that batch's statistics
    (needs JAX; skipped where only numpy is installed)."""
    pytest.importorskip("jax")
    import jax
    import jax.numpy as jnp

    import train

    params = train.init(jax.random.PRNGKey(0), bn=True)
    rng = np.random.default_rng(0)
    for layer in params.values():
        if "gamma" in layer:
            layer["gamma"] = jnp.asarray(rng.uniform(0.5, 2.0, layer["gamma"].shape), jnp.float32)
            layer["b"] = jnp.asarray(rng.normal(0.0, 0.3, layer["b"].shape), jnp.float32)
    x = rng.normal(0.0, 0.5, (64, netdef.INPUT, netdef.INPUT, 1)).astype(np.float32)
    want = np.asarray(train.forward(params, x))
    folded = train.fold_bn(params, x, chunk=16)
    assert all(set(layer) == {"w", "b"} for layer in folded.values())
    got = np.asarray(train.forward(folded, x))
    assert np.abs(got - want).max() < 1e-4 * np.abs(want).max()


def test_nearest_decoding_takes_the_nearest_cell_above_the_threshold():
    """The "nearest" rule as decode.c and nn_selftest.c: candidates strictly
    above the threshold and within the distance limit, the nearest wins, the
    first in raster order on a tie; none: not visible, the first maximum."""
    G, C = netdef.GRID, netdef.HEAD_CHANNELS
    rule = {"threshold": 100, "max_distance": 8000}
    head = np.zeros((G, G, C), np.int16)
    head[..., 0] = 100  # at the threshold: not a candidate (distance 0)
    cell = lambda i: head[i // G, i % G]  # noqa: E731
    cell(7)[[0, 3]] = (300, 4321)  # the most certain, farther
    cell(18)[[0, 1, 3]] = (101, -16, 3000)  # nearer: wins
    cell(20)[[0, 3]] = (101, 3000)  # as near, later
    cell(3)[[0, 3]] = (400, 8001)  # beyond the limit
    out = int8_ref.decode(head, rule)
    assert out["visible"] and out["cell"] == [18 % G, 18 // G] and out["distance_mm"] == 3000
    assert out["u_q4"] == 16 * (netdef.CELL_PX * (18 % G) + netdef.CELL_PX // 2) - 16
    for i in (3, 7, 18, 20):
        cell(i)[0] = 100
    out = int8_ref.decode(head, rule)
    assert not out["visible"] and out["cell"] == [0, 0]
    # The float decoding takes the same cell with the rule in float units.
    f = head.astype(np.float64)
    f[..., 0] /= 64
    f[..., 3] /= 8000
    f[18 // G, 18 % G, 0] = 101 / 64
    vis, _, _, d = evaluate.decode_float(f[None], {"threshold": 100 / 64, "max_distance": 1.0})[0]
    assert vis and abs(d - 3000 / 8000 * netdef.DIST_SCALE_M) < 1e-12


def test_export_writes_a_decoding_rule_only_when_the_checkpoint_has_one():
    ckpt = export.load_checkpoint(export.DEFAULT_CHECKPOINT)
    q, meta = export.quantize(ckpt), json.loads(str(ckpt["meta"]))
    plain, _ = export.c_sources(q, meta, None)
    ruled, _ = export.c_sources(q, meta, {"threshold": 96, "max_distance": 8000})
    assert "NN_DECODE" not in plain
    assert "#define NN_DECODE_THRESHOLD (96)" in ruled
    assert "#define NN_DECODE_MAX_DISTANCE_MM (8000)" in ruled
    ckpt["decode"] = np.array(json.dumps({"rule": "nearest", "threshold_q": 96,
                                          "max_distance_mm": 8000}))
    assert export.decode_rule(ckpt) == {"threshold": 96, "max_distance": 8000}
    assert export.decode_rule(ckpt, "float")["threshold"] == 1.5


def test_every_visible_gate_is_a_positive_and_the_nearer_gate_wins_a_cell():
    """train.targets_all_gates (needs JAX; skipped where only numpy is)."""
    pytest.importorskip("jax")
    import train

    def gate(u, v, d, visible=True, off=10.0):
        c = [u - 10, v - 10, u + 10, v - 10, u + 10, v + 10, u - 10, v + 10]
        return {"u": u, "v": v, "distance_m": d, "off_normal_deg": off,
                "in_image": True, "visible": visible, "corners": c}

    near, far = gate(100, 100, 3.0), gate(140, 100, 6.0)  # cells (1, 1), (2, 1)
    edge = gate(316, 200, 4.0)  # 4 px from the edge: ambiguous
    hidden = gate(40, 300, 5.0, visible=False, off=80.0)  # too oblique: a negative
    obj, w, reg, mask = train.targets_all_gates([[far, near, edge, hidden]], False, True, True)
    assert obj[0, 1, 1] == 1 and obj[0, 1, 2] == 1 and obj.sum() == 2
    assert w[0, 1, 1] == 1 and w[0, 1, 2] == 1  # positives count
    assert w[0, 0, 0] == 0  # a positive's neighbour
    assert w[0, 3, 4] == 0 and obj[0, 3, 4] == 0  # the ambiguous gate's cell
    assert w[0, 4, 0] == 1 and obj[0, 4, 0] == 0  # the oblique gate: a negative
    # Cell (2, 1) neighbours both gates' cells: the nearer one's regression.
    assert abs(reg[0, 1, 2, 2] - 3.0 / netdef.DIST_SCALE_M) < 1e-6
    assert abs(reg[0, 1, 3, 2] - 6.0 / netdef.DIST_SCALE_M) < 1e-6
    assert mask[0, 4, 0] == 0


@pytest.fixture
def base_net():
    """Tests that select another network leave netdef on the committed one."""
    yield
    netdef.select("base")


def test_a_checkpoint_selects_its_network(tmp_path, base_net):
    """export.load_checkpoint: no `net` entry is the committed "base"
    network, `net` = "wide" makes every script (export, the int8 reference)
    describe the wide one."""
    netdef.select("wide")
    export.load_checkpoint(export.DEFAULT_CHECKPOINT)
    assert netdef.NET == "base" and sum(netdef.macs()) == 3_360_000
    netdef.select("wide")
    ckpt = _random_checkpoint("wide")
    ckpt["meta"] = np.array(json.dumps({"command": "test"}))
    np.savez(tmp_path / "wide.npz", **ckpt)
    netdef.select("base")
    loaded = export.load_checkpoint(str(tmp_path / "wide.npz"))
    assert netdef.NET == "wide" and sum(netdef.macs()) == 4_992_000 <= 5_000_000
    h, _ = export.c_sources(export.quantize(loaded), {"command": "test"})
    assert "#define NN_MACS 4992000" in h and "#define NN_GRID 5" in h
    head = int8_ref.head_int8(export.quantize(loaded), np.zeros((1, 80, 80, 1), np.int8))
    assert head.shape == (1, netdef.GRID, netdef.GRID, netdef.HEAD_CHANNELS)
    with pytest.raises(ValueError):
        netdef.select("huge")


def _saved_base_bn(path):
    """A base network with batch normalisation, random non-zero biases and
    scales, saved unfolded at `path` as train.py saves OUT-bn.npz (needs
    JAX): its parameters and the generator that drew them, for the test's
    further draws."""
    import jax
    import jax.numpy as jnp

    import train

    netdef.select("base")
    params = train.init(jax.random.PRNGKey(0), bn=True)
    rng = np.random.default_rng(1)
    for layer in params.values():
        layer["b"] = jnp.asarray(rng.normal(0.0, 0.3, layer["b"].shape), jnp.float32)
        if "gamma" in layer:
            layer["gamma"] = jnp.asarray(rng.uniform(0.5, 2.0, layer["gamma"].shape), jnp.float32)
    np.savez(path, **{f"{n}.{k}": np.asarray(v)
                      for n, layer in params.items() for k, v in layer.items()})
    return params, rng


def test_widening_keeps_the_network(tmp_path, base_net):
    """train.load_init from a narrower network's unfolded checkpoint: the
    wide network computes what the stored one does (the new channels reach
    the head through zero weights), batch norm's batch statistics included
    (needs JAX; skipped where only numpy is installed)."""
    pytest.importorskip("jax")
    import jax

    import train

    params, rng = _saved_base_bn(tmp_path / "base-bn.npz")
    x = rng.normal(0.0, 0.5, (16, netdef.INPUT, netdef.INPUT, 1)).astype(np.float32)
    want = np.asarray(train.forward(params, x))
    netdef.select("wide")
    wide = train.load_init(str(tmp_path / "base-bn.npz"), train.init(jax.random.PRNGKey(2), bn=True))
    assert wide["conv6"]["w"].shape == (3, 3, 64, 128)
    assert np.any(np.asarray(wide["conv6"]["w"])[..., 64:] != 0)  # new channels are not dead
    got = np.asarray(train.forward(wide, x))
    assert np.abs(got - want).max() < 1e-4 * np.abs(want).max()


def test_the_fine_net_takes_a_160_input_of_2x2_means(base_net):
    """NETS["fine160"]: the 160x160 input (the rounded mean of each 2x2
    block, half up), within DESIGN.md §13's 5 MMAC, the base network's 5x5
    grid and 12 head channels; selecting "base" again gives the 80x80."""
    netdef.select("fine160")
    assert (netdef.POOL, netdef.INPUT, netdef.GRID) == (2, 160, 5)
    assert sum(netdef.macs()) == 4_627_200 <= 5_000_000
    assert netdef.geometry()[-1][2:] == (5, 5) and netdef.LAYERS[-1][5] == 12
    img = np.zeros((1, 320, 320), np.uint8)
    img[0, :2, 0] = 1  # sum 2 -> (2+2)>>2 = 1 (half up)
    img[0, 0, 2] = 1  # sum 1 -> (1+2)>>2 = 0
    img[0, :2, 4:6] = 255  # sum 1020 -> 255
    small = netdef.downsample(img)
    assert small.shape == (1, 160, 160) and small[0, 0, :3].tolist() == [1, 0, 255]
    head = int8_ref.head_int8(export.quantize(_random_checkpoint("fine160")),
                              netdef.to_int8(small))
    assert head.shape == (1, 5, 5, netdef.HEAD_CHANNELS)
    netdef.select("base")
    assert (netdef.POOL, netdef.INPUT) == (4, 80)


def _random_checkpoint(net):
    """A checkpoint of netdef's selected shape with random weights."""
    rng = np.random.default_rng(0)
    ckpt = {f"{n}.{p}": rng.normal(0.0, 0.1, s).astype(np.float32)
            for (n, k, _, _, _, cout, _), cin in ((layer, netdef.weight_cin(layer))
                                                  for layer in netdef.LAYERS)
            for p, s in (("w", (cout, k, k, cin)), ("b", (cout,)))}
    ckpt["act_max"] = np.ones(len(netdef.LAYERS) - 1)
    ckpt["net"] = np.array(net)
    return ckpt


def test_refining_keeps_the_network(tmp_path, base_net):
    """train.load_init of a base network's unfolded checkpoint into the
    fine160 shape (train.refine): on a 160x160 input the fine network
    computes what the base network computes on its 2x2 means (the 80x80
    input), batch norm included when conv0's statistics are those of the
    batch (needs JAX)."""
    pytest.importorskip("jax")
    import jax

    import train

    params, rng = _saved_base_bn(tmp_path / "base-bn.npz")
    fine_x = rng.normal(0.0, 0.5, (16, 160, 160, 1)).astype(np.float32)
    coarse_x = fine_x.reshape(16, 80, 2, 80, 2, 1).mean(axis=(2, 4))
    want = np.asarray(train.forward(params, coarse_x))
    netdef.select("fine160")
    fine = train.load_init(str(tmp_path / "base-bn.npz"),
                           train.init(jax.random.PRNGKey(2), bn=True), fine_x)
    assert np.any(np.asarray(fine["conv0"]["w"])[..., 2:] != 0)  # new channels are not dead
    got = np.asarray(train.forward(fine, fine_x))
    assert np.abs(got - want).max() < 1e-3 * np.abs(want).max()


def test_quant_loss_emulates_the_exports_grids():
    """quant_loss.py: the weights it rounds are export.quantize's int8
    weights times their scale; nothing rounded is the float network; every
    layer rounded comes four times nearer the int8 reference's head on the
    golden images than the float network does (the bias and head roundings
    are not emulated)."""
    import quant_loss

    ckpt = export.load_checkpoint(export.DEFAULT_CHECKPOINT)
    q = export.quantize(ckpt)
    for (name, *_), layer in zip(netdef.LAYERS, q):
        w = ckpt[f"{name}.w"].astype(np.float64)
        s = np.abs(w).reshape(len(w), -1).max(axis=1) / 127.0
        assert np.allclose(quant_loss.rounded_weights(w) / s[:, None, None, None], layer["w"])
    small, _ = netdef.load_dataset(make_golden.GOLDEN)
    x = netdef.to_int8(small)
    float_head = int8_ref.float_forward(ckpt, x.astype(np.float64) / 128)
    assert np.allclose(quant_loss.forward(ckpt, x), float_head)
    every = set(range(len(netdef.LAYERS)))
    emulated = quant_loss.forward(ckpt, x, weights=every, outputs=every)
    int8_head = int8_ref.heads_batch(q, x) * netdef.HEAD_UNITS
    # Measured: 0.19 against the float network's 1.25 (objectness logits).
    assert np.abs(emulated - int8_head).max() < 0.25 * np.abs(float_head - int8_head).max()


def test_analyse_lines_finds_the_gates_at_the_rules_lines():
    import analyse_lines as al

    def gate(u, v, d, a, inside=None):
        c = netdef.CAMERA
        inside = 0 <= u < c and 0 <= v < c if inside is None else inside
        return {"u": u, "v": v, "distance_m": d, "off_normal_deg": a, "in_image": inside}

    assert al.edge_px(gate(5, 160, 3, 0)) == 5
    assert al.edge_px(gate(-7, 160, 3, 0)) == -7
    assert al.edge_px(gate(160, 318, 3, 0)) == 2
    band = (16, 0.5, 5)
    assert al.near_a_line(gate(-10, 160, 3, 20), *band)       # just outside the edge
    assert al.near_a_line(gate(12, 160, 3, 20), *band)        # just inside
    assert not al.near_a_line(gate(40, 160, 3, 20), *band)    # well inside, near, square
    assert al.near_a_line(gate(160, 160, 8.3, 20), *band)     # just beyond 8 m
    assert not al.near_a_line(gate(160, 160, 9.0, 20), *band)  # well beyond
    assert al.near_a_line(gate(160, 160, 4, 73), *band)       # just beyond 70 degrees
    assert not al.near_a_line(gate(-40, 160, 8.2, 20), *band)  # far outside: no line near
    # A false positive's cause is the listed gate nearest the report.
    report = (True, 5.0, 160.0, 3.0)
    assert al.why_reported(report, [gate(-6, 160, 3, 20)]) == "its centre outside the image"
    assert al.why_reported(report, [gate(20, 150, 8.4, 20)]) == "beyond 8 m"
    assert al.why_reported(report, [gate(20, 150, 5, 75)]) == "beyond 70 degrees"
    assert al.why_reported(report, [gate(200, 160, 5, 20)]) == "no listed gate near the report"
    assert al.why_reported(report, []) == "no listed gate near the report"
    # Unambiguous images: every listed gate clearly visible or clearly not.
    assert al.unambiguous([gate(160, 160, 3, 20), gate(-80, 160, 5, 20), gate(100, 100, 12, 20)])
    assert not al.unambiguous([gate(160, 160, 3, 20), gate(-20, 160, 5, 20)])  # near the edge
    assert not al.unambiguous([gate(160, 160, 1.2, 20)])  # close up
    assert not al.unambiguous([gate(160, 160, 7.5, 20)])  # near 8 m
    assert not al.unambiguous([gate(160, 160, 4, 68)])  # near 70 degrees
    assert al.unambiguous([])
    assert [al.distance_band(d) for d in (0.9, 1.7, 4.0, 7.9)] == \
        ["0-1.5 m", "1.5-2 m", "2-6 m", "6-8 m"]
    # A detection's error cause: what lies at the reported centre.
    label = {"u": 100.0, "v": 100.0, "distance_m": 4.0}
    at = gate(100, 100, 4.0, 10)  # the label's own row
    other = dict(gate(250, 100, 3.0, 10), visible=True)
    hidden = dict(gate(250, 100, 3.0, 75), visible=False)
    assert al.error_cause((True, 110.0, 105.0, 4.0), label, [at, other]) == "placed"
    assert al.error_cause((True, 245.0, 100.0, 3.0), label, [at, other]) == "gross: another visible gate"
    assert al.error_cause((True, 245.0, 100.0, 3.0), label, [at, hidden]) == \
        "gross: a gate not visible, nearer"
    assert al.error_cause((True, 160.0, 250.0, 3.0), label, [at, other]) == \
        "gross: no listed gate at the report"


def test_label_floor_observer_applies_the_rules_to_what_it_measures():
    import label_floor as lf

    def gate(u, v, d, a):
        c = netdef.CAMERA
        return {"u": u, "v": v, "distance_m": d, "off_normal_deg": a,
                "in_image": 0 <= u < c and 0 <= v < c}

    images = [
        [gate(100, 100, 5.0, 10), gate(200, 150, 3.0, 20)],   # the nearer one
        [gate(100, 100, 5.0, 10), gate(200, 150, 3.0, 75)],   # the nearer one beyond 70 deg
        [gate(-3, 100, 2.0, 10), gate(160, 160, 8.3, 10)],    # outside, beyond 8 m: none
        [],
    ]
    labels = [{"visible": True, "u": 200.0, "v": 150.0, "distance_m": 3.0},
              {"visible": True, "u": 100.0, "v": 100.0, "distance_m": 5.0},
              {"visible": False}, {"visible": False}]
    rng = np.random.default_rng(0)
    exact = lf.observe(images, 0.0, 0.0, 0.0, rng)
    assert [p[0] for p in exact] == [True, True, False, False]
    assert exact[0][1:] == (200.0, 150.0, 3.0) and exact[1][1:] == (100.0, 100.0, 5.0)
    m = lf.floor(labels, images, 0.0, 0.0, 0.0, 3, rng)
    assert m == {"detection_rate": 1.0, "false_positive_rate": 0.0, "mean_px_error": 0.0,
                 "gross_rate": 0.0}
    # A gate 0.05 m beyond 8 m, measured with a 5 % error, is judged visible
    # with the probability of the normal law: Phi(-0.05 / (0.05 * 8.05)) = 0.45.
    far = [[gate(160, 160, 8.05, 10)]] * 4000
    seen = np.mean([p[0] for p in lf.observe(far, 0.0, 0.05, 0.0, rng)])
    assert abs(seen - 0.4506) < 0.03
    # The measured centre is what is reported: a 2 px error per axis has a
    # mean radial error of 2 * sqrt(pi / 2) = 2.51 px.
    near = [[gate(160, 160, 3.0, 10)]] * 4000
    err = [np.hypot(p[1] - 160, p[2] - 160) for p in lf.observe(near, 2.0, 0.0, 0.0, rng)]
    assert abs(np.mean(err) - 2.507) < 0.1


def test_distillation_targets_are_the_teachers_objectness(tmp_path, base_net):
    """train.teacher_logits: the objectness of a folded checkpoint of another
    net (the "teacher", 26 MMAC, over DESIGN.md §13's 5: it only teaches) on
    every sample, mirrored ones included, is the float network's
    (int8_ref.float_forward); kd_loss_fn with kd = 0 is loss_fn (needs JAX)."""
    pytest.importorskip("jax")
    import jax

    import train

    netdef.select("teacher")
    assert sum(netdef.macs()) == 26_092_800 and netdef.params() == 745_068
    teacher = _random_checkpoint("teacher")
    np.savez(tmp_path / "teacher.npz", **teacher)
    rng = np.random.default_rng(3)
    small = rng.integers(0, 256, (3, netdef.INPUT, netdef.INPUT)).astype(np.uint8)
    netdef.select("base")
    got = train.teacher_logits(str(tmp_path / "teacher.npz"), small, 3, chunk=4)
    x = train.batch_inputs(small, np.arange(6), 3, None, 0.0, 0.0).astype(np.float64)
    netdef.select("teacher")
    want = int8_ref.float_forward(teacher, x)[..., 0]
    netdef.select("base")
    assert got.shape == (6, netdef.GRID, netdef.GRID)
    assert np.abs(got - want).max() < 1e-4 * np.abs(want).max()
    mirrored = train.teacher_logits(str(tmp_path / "teacher.npz"), small[:, :, ::-1].copy(), 3)
    assert np.allclose(got[3:], mirrored[:3], rtol=0, atol=1e-5 * np.abs(want).max())
    params = train.init(jax.random.PRNGKey(0))
    xb = x[:2].astype(np.float32)
    obj = np.zeros((2, 5, 5), np.float32)
    obj[0, 2, 3] = 1
    w, reg, mask = np.ones_like(obj), np.zeros((2, 5, 5, 11), np.float32), obj.copy()
    plain = float(train.loss_fn(params, xb, obj, w, reg, mask))
    assert float(train.kd_loss_fn(params, xb, obj, w, reg, mask, got[:2], 0.0)) == plain
    assert float(train.kd_loss_fn(params, xb, obj, w, reg, mask, got[:2], 1.0)) > plain


def test_depthwise_layers_convolve_each_channel_alone(base_net):
    """NETS["sep"]'s depthwise layers ("dw..."): in the int8 reference each
    output channel sums its own input channel's 3x3 window (checked against
    a plain loop, stride 2 and padding included), the network stays within
    DESIGN.md section 13's 5 MMAC, and the C export stores each kernel row
    as a word (k taps, then zeros) for the cluster's depthwise kernel."""
    netdef.select("sep")
    assert sum(netdef.macs()) == 4_400_800 <= 5_000_000
    rng = np.random.default_rng(3)
    c, k = 8, 3
    layer = {"k": k, "stride": 2, "pad": 1, "cout": c,
             "w": rng.integers(-127, 128, (c, k, k, 1)).astype(np.int8),
             "bias": rng.integers(-500, 500, c).astype(np.int32),
             "mult": rng.integers(1, 32767, c).astype(np.int32),
             "shift": 16, "lo": 0, "hi": 127}
    x = rng.integers(0, 128, (2, 7, 7, c)).astype(np.int8)
    got = int8_ref.layer_int8(layer, x)
    assert got.shape == (2, 4, 4, c)
    xp = np.pad(x.astype(np.int64), ((0, 0), (1, 1), (1, 1), (0, 0)))
    for n in range(2):
        for y in range(4):
            for xx in range(4):
                for ch in range(c):
                    win = xp[n, 2 * y:2 * y + 3, 2 * xx:2 * xx + 3, ch]
                    acc = int((win * layer["w"][ch, :, :, 0]).sum()) + int(layer["bias"][ch])
                    want = min(max((acc * int(layer["mult"][ch]) + (1 << 15)) >> 16, 0), 127)
                    assert got[n, y, xx, ch] == want
    ckpt = _random_checkpoint("sep")
    q = export.quantize(ckpt)
    assert q[1]["name"] == "dw2" and q[1]["w"].shape == (16, 3, 3, 1)
    _, c_text = export.c_sources(q, {"command": "test"})
    row = q[1]["w"][0, 0, :, 0]
    assert c_text.split("nn_dw2_w[192] = {")[1].split(",")[:4] == [
        f"\n    {row[0]}", f" {row[1]}", f" {row[2]}", " 0"]
    head = int8_ref.head_int8(q, rng.integers(-128, 128, (1, 80, 80, 1)).astype(np.int8))
    assert head.shape == (1, netdef.GRID, netdef.GRID, netdef.HEAD_CHANNELS)


def test_training_depthwise_is_the_grouped_convolution(base_net):
    """train.conv computes a depthwise layer as the sum of shifted inputs
    (XLA's grouped convolution trains 10x slower on CPU): it equals
    lax.conv_general_dilated with one group per channel, stride 1 and 2,
    and the float network trained this way is the one int8_ref.py and the
    export describe (needs JAX)."""
    pytest.importorskip("jax")
    import jax
    import jax.numpy as jnp

    import train

    rng = np.random.default_rng(4)
    for stride, size in ((1, 10), (2, 9)):
        x = jnp.asarray(rng.normal(size=(3, size, size, 12)).astype(np.float32))
        w = jnp.asarray(rng.normal(size=(3, 3, 1, 12)).astype(np.float32))
        want = jax.lax.conv_general_dilated(
            x, w, (stride, stride), ((1, 1), (1, 1)), dimension_numbers=("NHWC", "HWIO", "NHWC"),
            feature_group_count=12)
        got = train.conv(x, w, stride, 1)
        assert got.shape == want.shape
        assert np.abs(np.asarray(got) - np.asarray(want)).max() < 1e-4
    netdef.select("sep")
    params = train.init(jax.random.PRNGKey(1))
    x = rng.normal(0.0, 0.5, (4, 80, 80, 1)).astype(np.float32)
    want = np.asarray(train.forward(params, x))
    ckpt = {f"{n}.{k}": (np.transpose(np.asarray(v), (3, 0, 1, 2)) if k == "w" else np.asarray(v))
            for n, layer in params.items() for k, v in layer.items()}
    got = int8_ref.float_forward(ckpt, x.astype(np.float64))
    assert np.abs(got - want).max() < 1e-3 * np.abs(want).max()
