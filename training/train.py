"""Trains the gate network (netdef.py) on a `cosim dataset` directory, on the
CPU with JAX + optax, seeded; writes the float checkpoint (framework-neutral
.npz) with the activation ranges for int8 quantization (docs/NN.md).

    python3 training/train.py --data DIR [DIR ...] --out training/checkpoint.npz \
        [--epochs 12] [--seed 0] [--heldout DIR] [--bn] [--init NPZ] [--max-seconds S] \
        [--net base|wide|fine160]

--net picks the shape (netdef.NETS; "base" is the committed network); a
checkpoint of another shape records it, and export.py, evaluate.py and the
others then describe that shape (fine160: a 160x160 input, cached as
DIR/inputs160.npy).

--init starts from a checkpoint (or a --bn run's OUT-bn.npz), layer by layer
where the shapes match, so a new shape can reuse an older network's first
layers, and embeds a narrower layer in a wider one (embed: the wide network
starts as the narrow one's function); --max-seconds ends the schedule early
on a time budget (the checkpoint's meta records the steps done).

With --gates the targets come from each directory's gates.csv: objectness
on the cell of every visible gate (--ambiguous: gates near the labelling
rules' lines left out of it), for the "nearest" decoding whose threshold
choose_threshold.py then picks on a validation set.

With --bn every ReLU convolution is trained with batch normalisation (batch
statistics); after training the statistics are re-estimated over 4096
training images and folded into the convolution's weights and bias, so the
checkpoint (and the int8 export) is the plain network of netdef.LAYERS.

Only this script needs JAX; export.py, int8_ref.py and the tests need numpy.
"""

import argparse
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef  # noqa: E402
import evaluate  # noqa: E402
from export import portable_command  # noqa: E402


def mirrored(u, c):
    """A centre's u and the corners (u0 v0 .. u3 v3) of the image mirrored
    left-right: TL <-> TR, BR <-> BL."""
    m = [(netdef.CAMERA - c[2 * k], c[2 * k + 1]) for k in range(4)]
    m = [m[1], m[0], m[3], m[2]]
    return netdef.CAMERA - u, [x for p in m for x in p]


def cell_of(u, v):
    """The grid cell of a camera pixel, clamped to the grid (a centre just
    outside the image belongs to the edge's cell)."""
    G = netdef.GRID
    return (min(max(int(np.floor(u / netdef.CELL_PX)), 0), G - 1),
            min(max(int(np.floor(v / netdef.CELL_PX)), 0), G - 1))


def regression(u, v, c, distance_m, x, y):
    """The regression target of a gate in cell (x, y), relative to its centre."""
    cu, cv = netdef.cell_centre(x, y)
    rel = [(c[2 * k] - cu, c[2 * k + 1] - cv) for k in range(4)]
    return [(u - cu) / netdef.CELL_PX, (v - cv) / netdef.CELL_PX,
            distance_m / netdef.DIST_SCALE_M] + [q / netdef.CELL_PX for p in rel for q in p]


# The labelling rules' lines (world-server/src/dataset.rs: 8 m, the centre
# inside the image, 70 deg off the normal) and how near them a gate is
# "ambiguous" for --gates training: left out of the objectness loss (a
# "don't care" region), as the rules' yes/no there is arbitrary for a small
# CNN (docs/NN.md: the misses and false positives gather at these lines).
AMBIGUOUS_RANGE_M = (7.5, 8.5)
AMBIGUOUS_EDGE_PX = (6.0, 12.0)  # inside, outside the image's edge
AMBIGUOUS_OFF_NORMAL_DEG = (65.0, 75.0)


def ambiguous(g):
    """A gate near one of the rules' lines (and within the others' slack)."""
    u, v, C = g["u"], g["v"], netdef.CAMERA
    inside = min(u, v, C - u, C - v)  # < 0 outside the image
    if g["corners"] is None or inside < -AMBIGUOUS_EDGE_PX[1]:
        return False
    if g["distance_m"] > AMBIGUOUS_RANGE_M[1] or g["off_normal_deg"] > AMBIGUOUS_OFF_NORMAL_DEG[1]:
        return False
    return (g["distance_m"] > AMBIGUOUS_RANGE_M[0] or inside < AMBIGUOUS_EDGE_PX[0]
            or g["off_normal_deg"] > AMBIGUOUS_OFF_NORMAL_DEG[0])


def targets_all_gates(gates, mirror, ignore_neighbours, use_ambiguous):
    """--gates targets from gates.csv: objectness (n, 5, 5), its weight
    (n, 5, 5), regression (n, 5, 5, 11) and its mask (n, 5, 5).

    Objectness is 1 on the cell of EVERY strictly visible gate (a local
    question: "a visible gate's centre is here"); the regression of a gate
    (visible or ambiguous) is trained in its cell and the 8 neighbours, the
    nearer gate winning a cell two gates compete for. Weight 0 (ignored):
    the positives' neighbours (with ignore_neighbours) and, with
    use_ambiguous, the cells of gates near the rules' lines; a positive cell
    always counts. The decoding (evaluate.decode_nearest) reports the
    nearest of the cells above a threshold."""
    n, G = len(gates), netdef.GRID
    obj = np.zeros((n, G, G), np.float32)
    wobj = np.ones((n, G, G), np.float32)
    reg = np.zeros((n, G, G, 11), np.float32)
    mask = np.zeros((n, G, G), np.float32)
    for i, gs in enumerate(gates):
        positives = []
        # Farthest first, so the nearer gate's regression overwrites.
        for g in sorted(gs, key=lambda g: -g["distance_m"]):
            amb = use_ambiguous and ambiguous(g)
            if not (g["visible"] or amb) or g["corners"] is None:
                continue
            u, v, c = g["u"], g["v"], g["corners"]
            if mirror:
                u, c = mirrored(u, c)
            gx, gy = cell_of(u, v)
            if g["visible"] and not amb:
                positives.append((gx, gy))
            else:
                wobj[i, gy, gx] = 0.0
            for y in range(max(gy - 1, 0), min(gy + 2, G)):
                for x in range(max(gx - 1, 0), min(gx + 2, G)):
                    reg[i, y, x] = regression(u, v, c, g["distance_m"], x, y)
                    mask[i, y, x] = 1.0
                    if ignore_neighbours:
                        wobj[i, y, x] = 0.0
        for gx, gy in positives:
            obj[i, gy, gx] = 1.0
            wobj[i, gy, gx] = 1.0
    return obj, wobj, reg, mask


def targets(labels, mirror):
    """Objectness (n, 5, 5), regression (n, 5, 5, 11) and its mask (n, 5, 5).

    The cell holding the nearest visible gate's centre is the positive one;
    the regression is trained in it and its 8 neighbours (each relative to
    its own centre), so a neighbour that wins the argmax still places the
    gate well."""
    n, G = len(labels), netdef.GRID
    obj = np.zeros((n, G, G), np.float32)
    reg = np.zeros((n, G, G, 11), np.float32)
    mask = np.zeros((n, G, G), np.float32)
    for i, r in enumerate(labels):
        if not r["visible"]:
            continue
        u, v, c = r["u"], r["v"], list(r["corners"])
        if mirror:
            u, c = mirrored(u, c)
        gx = min(int(u // netdef.CELL_PX), G - 1)
        gy = min(int(v // netdef.CELL_PX), G - 1)
        obj[i, gy, gx] = 1.0
        for y in range(max(gy - 1, 0), min(gy + 2, G)):
            for x in range(max(gx - 1, 0), min(gx + 2, G)):
                reg[i, y, x] = regression(u, v, c, r["distance_m"], x, y)
                mask[i, y, x] = 1.0
    return obj, reg, mask


# Batch normalisation's epsilon (added to the variance).
BN_EPS = 1e-3


def init(key, bn=False):
    params = {}
    for layer in netdef.LAYERS:
        name, k, _, _, _, cout, relu = layer
        cin = netdef.weight_cin(layer)
        key, sub = jax.random.split(key)
        std = np.sqrt(2.0 / (k * k * cin))
        params[name] = {
            "w": jax.random.normal(sub, (k, k, cin, cout), jnp.float32) * std,  # HWIO
            "b": jnp.zeros((cout,), jnp.float32),
        }
        if bn and relu:
            # The bias is BN's beta; the convolution itself has none.
            params[name]["gamma"] = jnp.ones((cout,), jnp.float32)
    return params


def conv(x, w, s, p):
    """A convolution; a depthwise one (netdef.depthwise) when the weights
    span one input channel of several (HWIO with I = 1)."""
    if w.shape[2] == x.shape[-1]:
        return jax.lax.conv_general_dilated(
            x, w, (s, s), ((p, p), (p, p)), dimension_numbers=("NHWC", "HWIO", "NHWC"))
    # Depthwise as the sum of the k*k shifted inputs times their taps:
    # XLA's CPU grouped convolution (feature_group_count) trains 10x slower.
    k = w.shape[0]
    n, h, wd, _ = x.shape
    oh, ow = (h + 2 * p - k) // s + 1, (wd + 2 * p - k) // s + 1
    x = jnp.pad(x, ((0, 0), (p, p), (p, p), (0, 0)))
    return sum(x[:, ky:ky + s * (oh - 1) + 1:s, kx:kx + s * (ow - 1) + 1:s, :] * w[ky, kx, 0]
               for ky in range(k) for kx in range(k))


def forward(params, x, keep=False, layers=None):
    """x: (n, INPUT, INPUT, 1) float (int8 input / 128). Returns the head (n, 5, 5, 12)
    and, with keep, every ReLU output. `layers`: another net's (netdef.NETS
    entry) than the selected one, e.g. a distillation teacher's."""
    acts = []
    for name, _, s, p, _, _, relu in layers or netdef.LAYERS:
        x = conv(x, params[name]["w"], s, p)
        if "gamma" in params[name]:
            # Training with batch normalisation: this batch's statistics.
            mean = x.mean(axis=(0, 1, 2))
            var = x.var(axis=(0, 1, 2))
            x = (x - mean) * (params[name]["gamma"] * jax.lax.rsqrt(var + BN_EPS))
        x = x + params[name]["b"]
        if relu:
            x = jax.nn.relu(x)
            acts.append(x)
    return (x, acts) if keep else x


def smooth_l1(d, beta=0.02):
    a = jnp.abs(d)
    return jnp.where(a < beta, 0.5 * a * a / beta, a - 0.5 * beta)


def teacher_logits(path, small, n, chunk=512):
    """Distillation's targets: the objectness logits (2n, G, G) of the folded
    checkpoint `path` (any net; the one it records) on every sample, mirrored
    ones included, without the brightness augmentation (the student is to
    answer as the teacher does whatever the brightness)."""
    with np.load(path) as z:
        net = netdef.checkpoint_net(z)
        layers = netdef.NETS[net]
        params = {name: {"w": jnp.asarray(np.transpose(z[f"{name}.w"], (1, 2, 3, 0))),
                         "b": jnp.asarray(z[f"{name}.b"])} for name, *_ in layers}
    if netdef.POOLS.get(net, 4) != netdef.POOL:
        raise SystemExit(f"the teacher {net} takes another input resolution than {netdef.NET}")
    fwd = jax.jit(lambda x: forward(params, x, layers=layers)[..., 0])

    out = []
    for s in range(0, 2 * n, chunk):
        idx = np.arange(s, min(s + chunk, 2 * n))
        out.append(np.asarray(fwd(batch_inputs(small, idx, n, None, 0.0, 0.0))).astype(np.float32))
    return np.concatenate(out)


def kd_loss_fn(params, x, obj, w_obj, reg, mask, tlog, kd):
    """loss_fn plus kd x the binary cross-entropy of the objectness against
    the teacher's probabilities (sigmoid of `tlog`) over every cell, the
    ignored ones included: where the labels leave a cell free (the rules'
    lines, the positives' neighbours), the teacher still says how much a
    gate is there (knowledge distillation, Hinton et al. 2015)."""
    out = forward(params, x)
    bce = (optax.sigmoid_binary_cross_entropy(out[..., 0], obj) * w_obj).sum(axis=(1, 2))
    kdl = optax.sigmoid_binary_cross_entropy(out[..., 0], jax.nn.sigmoid(tlog)).sum(axis=(1, 2))
    return jnp.mean(bce) + kd * jnp.mean(kdl) + 4.0 * jnp.mean(regression_loss(out, reg, mask))


# The regression's weights: centre (u, v), distance, the 8 corner values.
# --centre-weight scales the centre's (the placement §13's mean error scores).
REG_WEIGHTS = [1.0, 1.0, 0.5] + [0.25] * 8


def regression_loss(out, reg, mask):
    """Per sample: the weighted smooth-L1 of the regression over the masked cells."""
    w = jnp.array(REG_WEIGHTS)
    return ((smooth_l1(out[..., 1:] - reg) * w).sum(-1) * mask).sum(axis=(1, 2))


def loss_fn(params, x, obj, w_obj, reg, mask):
    """BCE of the objectness over the cells (weighted by w_obj: 0 leaves a
    cell out) plus the weighted smooth-L1 of the regression over the masked
    cells. The labels' targets leave the centre cell's 8 neighbours out with
    --ignore-neighbours (neither pushed up nor down): a gate near a cell
    border may then raise both cells instead of splitting its probability
    between them (each below 0.5, a miss at the decoding's threshold)."""
    out = forward(params, x)
    bce = (optax.sigmoid_binary_cross_entropy(out[..., 0], obj) * w_obj).sum(axis=(1, 2))
    return jnp.mean(bce) + 4.0 * jnp.mean(regression_loss(out, reg, mask))


def fold_bn(params, calib, chunk=256):
    """The plain network (w, b per layer) equal to the batch-normalised one
    with population statistics: each layer's mean and variance are measured
    over `calib` with the layers before it already folded, then
    w' = w * gamma / sqrt(var + eps), b' = beta - mean * gamma / sqrt(var + eps)."""
    folded, x = {}, calib
    for name, _, s, p, _, _, relu in netdef.LAYERS:
        w, b = params[name]["w"], params[name]["b"]
        if "gamma" in params[name]:
            y = np.concatenate([np.asarray(conv(x[i:i + chunk], w, s, p))
                                for i in range(0, len(x), chunk)]).astype(np.float64)
            mean, var = y.mean(axis=(0, 1, 2)), y.var(axis=(0, 1, 2))
            scale = np.asarray(params[name]["gamma"], np.float64) / np.sqrt(var + BN_EPS)
            w = jnp.asarray(np.asarray(w, np.float64) * scale, jnp.float32)
            b = jnp.asarray(np.asarray(b, np.float64) - mean * scale, jnp.float32)
        folded[name] = {"w": w, "b": b}
        x = np.concatenate([np.asarray(conv(x[i:i + chunk], w, s, p) + b)
                            for i in range(0, len(x), chunk)])
        if relu:
            x = np.maximum(x, 0.0)
    return folded


def raw_path(out):
    """Where a --bn run keeps its network before folding: OUT-bn.npz."""
    return os.path.splitext(out)[0] + "-bn.npz"


def embed(fresh, stored):
    """A wider layer holding a narrower one: the stored weights in the
    leading input and output channels, the new output channels' weights
    fresh, and the new input channels' weights into the stored outputs
    zero (Net2Net-style widening, Chen et al. 2016, with zeros instead of
    copies). Embedded in every layer of a widened network, the new channels
    reach the head through zero weights only, so the widened network starts
    as the stored one's function (batch norm's statistics of the stored
    channels included) and training grows the new channels from there."""
    _, _, cin, cout = stored.shape
    out = np.array(fresh)
    out[:, :, :, :cout] = 0.0
    out[:, :, :cin, :cout] = stored
    return out


def refine(params, calib):
    """fine160's conv0 and conv1 (netdef) started from an 80x80 network's
    conv1, already embedded by load_init in conv1's input channel 0: conv0's
    channels 0 and 1 compute +- the 2x2 mean of the 160x160 input under the
    window's lower-right 2x2 taps (for output pixel i, input rows 2i and
    2i+1: the 4x4 block of the 80x80 input pixel i), so that
    relu(c0) - relu(c1) is the 80x80 input, and conv1 weighs channel 1 with
    minus the stored weights. The network then computes the 80x80 network's
    function on the 160x160 input (up to the 80x80 input's rounding, and
    with batch norm to conv0's batch statistics: gamma and beta are set from
    `calib`'s so that conv0's normalisation is about the identity). conv0's
    other 6 channels reach conv1 through zero weights, as embed's new
    channels do."""
    w0 = np.array(params["conv0"]["w"])  # HWIO (3, 3, 1, 8), fresh
    w0[..., :2] = 0.0
    w0[1:, 1:, 0, 0] = 0.25
    w0[1:, 1:, 0, 1] = -0.25
    layer0 = {"w": jnp.asarray(w0), "b": np.array(params["conv0"]["b"])}
    if "gamma" in params["conv0"]:
        gamma = np.array(params["conv0"]["gamma"])
        z = np.asarray(conv(jnp.asarray(calib), jnp.asarray(w0[..., :1]), 2, 1)).astype(np.float64)
        mean, std = z.mean(), np.sqrt(z.var() + BN_EPS)
        gamma[:2] = std
        layer0["b"][:2] = (mean, -mean)
        layer0["gamma"] = jnp.asarray(gamma)
    else:
        layer0["b"][:2] = 0.0
    layer0["b"] = jnp.asarray(layer0["b"])
    w1 = np.array(params["conv1"]["w"])  # (3, 3, 8, 8), the stored in input channel 0
    w1[:, :, 1, :] = -w1[:, :, 0, :]
    return {**params, "conv0": layer0, "conv1": {**params["conv1"], "w": jnp.asarray(w1)}}


def load_init(path, params, calib=None):
    """params with every layer that `path` holds in the same shape replaced
    by the stored one (a further cycle, or a new shape started from an older
    network's matching layers), and every layer it holds narrower (fewer
    input or output channels, same kernel) embedded in the new one (embed;
    the per-channel bias and gamma of the new channels fresh); the others
    keep their fresh initialisation. `path` is a checkpoint (OHWI weights)
    or a --bn run's unfolded network (raw_path's file, HWIO and gamma).
    A fine160 network (a conv0) from an 80x80 one (none) is refined (refine,
    with the float inputs `calib`) to start as the stored network's function."""
    out, loaded, widened = {}, [], []
    with np.load(path) as z:
        raw = "conv1.gamma" in z.files
        for name, layer in params.items():
            if f"{name}.w" not in z.files:
                out[name] = layer
                continue
            w = z[f"{name}.w"] if raw else np.transpose(z[f"{name}.w"], (1, 2, 3, 0))
            shape = layer["w"].shape
            if w.shape == shape:
                out[name] = {k: (jnp.asarray(w) if k == "w" else jnp.asarray(z[f"{name}.{k}"]))
                             if f"{name}.{k}" in z.files else v for k, v in layer.items()}
                loaded.append(name)
            elif w.shape[:2] == shape[:2] and w.shape[2] <= shape[2] and w.shape[3] <= shape[3]:
                out[name] = {"w": jnp.asarray(embed(layer["w"], w))}
                for k, v in layer.items():
                    if k != "w":
                        v = np.array(v)
                        if f"{name}.{k}" in z.files:
                            v[:w.shape[3]] = z[f"{name}.{k}"]
                        out[name][k] = jnp.asarray(v)
                widened.append(name)
            else:
                out[name] = layer
    refined = "conv0" in params and "conv0" not in loaded and "conv1" in widened
    if refined:
        out = refine(out, calib)
    print(f"from {path}: {', '.join(loaded) or 'no layer'}"
          + (f"; widened: {', '.join(widened)}" if widened else "")
          + ("; conv0 and conv1 refined from conv1" if refined else ""), flush=True)
    return out


def load_inputs(directory):
    """A dataset's inputs at the selected net's resolution, cached beside it
    (inputs80.npy, inputs160.npy) after the first read: 100,000 PGMs take
    minutes to decode, the cache a second."""
    labels = netdef.read_labels(directory)
    cache = os.path.join(directory, f"inputs{netdef.INPUT}.npy")
    if os.path.exists(cache):
        small = np.load(cache)
        if len(small) == len(labels):
            return small, labels
    small, labels = netdef.load_dataset(directory)
    np.save(cache, small)
    return small, labels


def batch_inputs(small, idx, n, rng, gain, offset):
    """The float inputs of samples idx (idx >= n: image idx - n mirrored
    left-right), each with a random brightness gain and offset (photometric
    augmentation) applied to the input's uint8 image, rounded and clipped as
    a real image would be. `rng` may be None without augmentation."""
    x = small[idx % n].astype(np.float32)
    flip = idx >= n
    x[flip] = x[flip, :, ::-1]
    if gain or offset:
        g = rng.uniform(1 - gain, 1 + gain, (len(idx), 1, 1)).astype(np.float32)
        o = rng.uniform(-offset, offset, (len(idx), 1, 1)).astype(np.float32)
        x = np.clip(np.round((x - 128) * g + 128 + o), 0, 255)
    return ((x - 128) / 128.0)[..., None]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True, nargs="+", help="cosim dataset directories")
    ap.add_argument("--out", required=True)
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--warmup", type=int, default=0, help="linear warm-up steps")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--heldout", help="a dataset to report accuracy on at the end")
    ap.add_argument("--limit", type=int, help="use only the first N images of each directory")
    ap.add_argument("--init", help="start from this checkpoint (a further cosine cycle)")
    ap.add_argument("--bn", action="store_true", help="train with batch normalisation (folded at the end)")
    ap.add_argument("--gain", type=float, default=0.0, help="brightness gain augmentation, +-")
    ap.add_argument("--offset", type=float, default=0.0, help="brightness offset augmentation, +- levels")
    ap.add_argument("--max-seconds", type=float,
                    help="stop the schedule early after this much training time (a shared machine's budget)")
    ap.add_argument("--ignore-neighbours", action="store_true",
                    help="leave the centre cell's 8 neighbours out of the objectness loss")
    ap.add_argument("--gates", action="store_true",
                    help="targets from gates.csv: objectness on every visible gate's cell")
    ap.add_argument("--ambiguous", action="store_true",
                    help="with --gates: leave gates near the labelling rules' lines out of the objectness")
    ap.add_argument("--net", default="base", choices=sorted(netdef.NETS),
                    help="the network's shape (netdef.NETS; the checkpoint records it)")
    ap.add_argument("--teacher", help="a folded checkpoint whose objectness the network also "
                    "learns (distillation; docs/NN.md \"A large network\")")
    ap.add_argument("--kd", type=float, default=1.0, help="the distillation term's weight")
    ap.add_argument("--centre-weight", type=float, default=1.0,
                    help="scale of the centre's weight in the regression loss")
    a = ap.parse_args()
    netdef.select(a.net)
    if not a.centre_weight > 0:
        raise SystemExit("--centre-weight must be > 0")
    REG_WEIGHTS[0] = REG_WEIGHTS[1] = a.centre_weight
    t0 = time.time()
    parts = [load_inputs(d) for d in a.data]
    small = np.concatenate([p[0][:a.limit] for p in parts])
    labels = [r for p in parts for r in p[1][:a.limit]]
    n = len(labels)
    # Samples 0..n-1 the images, n..2n-1 the same mirrored (labels mirrored).
    if a.gates:
        gates = [g for d, p in zip(a.data, parts)
                 for g in netdef.read_gates(d, [r["file"] for r in p[1][:a.limit]])]
        t = [targets_all_gates(gates, m, a.ignore_neighbours, a.ambiguous) for m in (False, True)]
        obj, wobj, reg, mask = (np.concatenate(p) for p in zip(*t))
        print(f"objectness: {obj.sum() / 2:.0f} positive cells, "
              f"{(wobj == 0).sum() / 2:.0f} ignored", flush=True)
    else:
        o1, r1, m1 = targets(labels, False)
        o2, r2, m2 = targets(labels, True)
        obj, reg, mask = (np.concatenate(p) for p in ((o1, o2), (r1, r2), (m1, m2)))
        wobj = 1.0 - (1.0 if a.ignore_neighbours else 0.0) * (mask - obj)
    print(f"loaded {n} images (x2 mirrored) in {time.time() - t0:.1f} s", flush=True)

    tlog = None
    if a.teacher:
        t0 = time.time()
        tlog = teacher_logits(a.teacher, small, n)
        print(f"teacher's objectness on {2 * n} samples in {time.time() - t0:.0f} s", flush=True)
    key = jax.random.PRNGKey(a.seed)
    params = init(key, a.bn)
    if a.init:
        calib = batch_inputs(small, np.arange(min(n, 1024)), n, None, 0.0, 0.0)
        params = load_init(a.init, params, calib)
    steps_per_epoch = 2 * n // a.batch
    total_steps = a.epochs * steps_per_epoch
    if a.warmup:
        sched = optax.warmup_cosine_decay_schedule(0.0, a.lr, a.warmup, total_steps)
    else:
        sched = optax.cosine_decay_schedule(a.lr, total_steps)
    opt = optax.adamw(sched, weight_decay=1e-4)
    state = opt.init(params)

    @jax.jit
    def step(params, state, xb, ob, wb, rb, mb, tb):
        if tb is None:
            loss, g = jax.value_and_grad(loss_fn)(params, xb, ob, wb, rb, mb)
        else:
            loss, g = jax.value_and_grad(kd_loss_fn)(params, xb, ob, wb, rb, mb, tb, a.kd)
        upd, state = opt.update(g, state, params)
        return optax.apply_updates(params, upd), state, loss

    rng = np.random.default_rng(a.seed)
    t1 = time.time()
    done = 0
    for epoch in range(a.epochs):
        perm = rng.permutation(2 * n)
        total = 0.0
        for s in range(steps_per_epoch):
            if a.max_seconds and time.time() - t1 > a.max_seconds:
                break
            idx = np.sort(perm[s * a.batch:(s + 1) * a.batch])
            xb = batch_inputs(small, idx, n, rng, a.gain, a.offset)
            params, state, loss = step(params, state, xb, obj[idx], wobj[idx], reg[idx], mask[idx],
                                       None if tlog is None else tlog[idx])
            total += float(loss)
            done += 1
            if s % 100 == 0:
                print(f"  step {s}: {float(loss):.4f} ({time.time() - t1:.0f} s)", flush=True)
        print(f"epoch {epoch + 1}/{a.epochs}: loss {total / max(done - epoch * steps_per_epoch, 1):.4f} "
              f"({time.time() - t1:.0f} s)", flush=True)
        if done < (epoch + 1) * steps_per_epoch:
            print(f"stopped at --max-seconds after {done} of {total_steps} steps", flush=True)
            break
    train_s = time.time() - t1

    # Activation ranges for int8 (docs/NN.md): the 99.99th percentile of each
    # ReLU output over 2048 training images.
    calib = batch_inputs(small, rng.permutation(2 * n)[:4096], n, rng, 0.0, 0.0)
    if a.bn:
        # The unfolded network, for a further cycle (--init with --bn).
        np.savez(raw_path(a.out), **{f"{name}.{k}": np.asarray(v)
                                    for name, layer in params.items() for k, v in layer.items()})
        params = fold_bn(params, calib)
    calib = calib[:2048]
    acts = [[] for _ in range(len(netdef.LAYERS) - 1)]
    for s in range(0, len(calib), 256):
        _, a_l = forward(params, calib[s:s + 256], keep=True)
        for k, t in enumerate(a_l):
            acts[k].append(np.asarray(t).ravel())
    act_max = np.array([np.percentile(np.concatenate(t), 99.99) for t in acts], np.float64)

    ckpt = {}
    for name, *_ in netdef.LAYERS:
        w = np.asarray(params[name]["w"])  # HWIO -> OHWI ([cout][kh][kw][cin])
        ckpt[f"{name}.w"] = np.transpose(w, (3, 0, 1, 2)).astype(np.float32)
        ckpt[f"{name}.b"] = np.asarray(params[name]["b"]).astype(np.float32)
    ckpt["act_max"] = act_max
    if a.net != "base":
        # The committed checkpoint has no entry: "base" (export.load_checkpoint).
        ckpt["net"] = np.array(a.net)
    meta = {"net": a.net, "command": portable_command(" ".join(sys.argv)), "images": n, "epochs": a.epochs,
            "batch": a.batch, "lr": a.lr, "seed": a.seed, "bn": a.bn,
            "ignore_neighbours": a.ignore_neighbours, "gates": a.gates,
            "ambiguous": a.ambiguous, "teacher": a.teacher, "kd": a.kd if a.teacher else None,
            "train_seconds": round(train_s, 1),
            "steps": done, "scheduled_steps": total_steps,
            "jax": jax.__version__, "optax": optax.__version__}
    ckpt["meta"] = np.array(json.dumps(meta))
    np.savez(a.out, **ckpt)
    print(f"trained in {train_s:.0f} s -> {a.out}; act_max {np.round(act_max, 3).tolist()}")
    if a.heldout:
        hs, hl = netdef.load_dataset(a.heldout)
        head = np.asarray(forward(params, netdef.to_int8(hs).astype(np.float32) / 128.0))
        print("float on", a.heldout, json.dumps(evaluate.metrics(evaluate.decode_float(head), hl)))


if __name__ == "__main__":
    main()
