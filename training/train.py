"""Trains the gate network (netdef.py) on a `cosim dataset` directory, on the
CPU with JAX + optax, seeded; writes the float checkpoint (framework-neutral
.npz) with the activation ranges for int8 quantization (docs/NN.md).

    python3 training/train.py --data DIR --out training/checkpoint.npz \
        [--epochs 12] [--seed 0] [--heldout DIR]

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
            u = netdef.CAMERA - u
            m = [(netdef.CAMERA - c[2 * k], c[2 * k + 1]) for k in range(4)]
            # TL <-> TR, BR <-> BL
            m = [m[1], m[0], m[3], m[2]]
            c = [x for p in m for x in p]
        gx = min(int(u // netdef.CELL_PX), G - 1)
        gy = min(int(v // netdef.CELL_PX), G - 1)
        obj[i, gy, gx] = 1.0
        for y in range(max(gy - 1, 0), min(gy + 2, G)):
            for x in range(max(gx - 1, 0), min(gx + 2, G)):
                cu, cv = netdef.cell_centre(x, y)
                rel = [(c[2 * k] - cu, c[2 * k + 1] - cv) for k in range(4)]
                reg[i, y, x] = [(u - cu) / netdef.CELL_PX, (v - cv) / netdef.CELL_PX,
                                r["distance_m"] / netdef.DIST_SCALE_M] + [
                    q / netdef.CELL_PX for p in rel for q in p]
                mask[i, y, x] = 1.0
    return obj, reg, mask


def init(key):
    params = {}
    for name, k, _, _, cin, cout, _ in netdef.LAYERS:
        key, sub = jax.random.split(key)
        std = np.sqrt(2.0 / (k * k * cin))
        params[name] = {
            "w": jax.random.normal(sub, (k, k, cin, cout), jnp.float32) * std,  # HWIO
            "b": jnp.zeros((cout,), jnp.float32),
        }
    return params


def forward(params, x, keep=False):
    """x: (n, 80, 80, 1) float (int8 input / 128). Returns the head (n, 5, 5, 12)
    and, with keep, every ReLU output."""
    acts = []
    for name, _, s, p, _, _, relu in netdef.LAYERS:
        x = jax.lax.conv_general_dilated(
            x, params[name]["w"], (s, s), ((p, p), (p, p)),
            dimension_numbers=("NHWC", "HWIO", "NHWC")) + params[name]["b"]
        if relu:
            x = jax.nn.relu(x)
            acts.append(x)
    return (x, acts) if keep else x


def smooth_l1(d, beta=0.02):
    a = jnp.abs(d)
    return jnp.where(a < beta, 0.5 * a * a / beta, a - 0.5 * beta)


def loss_fn(params, x, obj, reg, mask):
    out = forward(params, x)
    bce = optax.sigmoid_binary_cross_entropy(out[..., 0], obj).sum(axis=(1, 2))
    w = jnp.array([1.0, 1.0, 0.5] + [0.25] * 8)
    r = (smooth_l1(out[..., 1:] - reg) * w).sum(-1) * mask
    return jnp.mean(bce) + 4.0 * jnp.mean(r.sum(axis=(1, 2)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--heldout", help="a dataset to report accuracy on at the end")
    ap.add_argument("--limit", type=int, help="use only the first N images")
    ap.add_argument("--init", help="start from this checkpoint (a further cosine cycle)")
    a = ap.parse_args()
    t0 = time.time()
    small, labels = netdef.load_dataset(a.data, a.limit)
    x = np.concatenate([small, small[:, :, ::-1]])  # horizontal mirror: twice the data
    o1, r1, m1 = targets(labels, False)
    o2, r2, m2 = targets(labels, True)
    obj, reg, mask = (np.concatenate(p) for p in ((o1, o2), (r1, r2), (m1, m2)))
    x = (netdef.to_int8(x).astype(np.float32) / 128.0)
    print(f"loaded {len(labels)} images (x2 mirrored) in {time.time() - t0:.1f} s", flush=True)

    key = jax.random.PRNGKey(a.seed)
    params = init(key)
    if a.init:
        with np.load(a.init) as z:
            params = {name: {"w": jnp.asarray(np.transpose(z[f"{name}.w"], (1, 2, 3, 0))),
                             "b": jnp.asarray(z[f"{name}.b"])} for name, *_ in netdef.LAYERS}
    steps_per_epoch = len(x) // a.batch
    sched = optax.cosine_decay_schedule(a.lr, a.epochs * steps_per_epoch)
    opt = optax.adamw(sched, weight_decay=1e-4)
    state = opt.init(params)

    @jax.jit
    def step(params, state, xb, ob, rb, mb):
        loss, g = jax.value_and_grad(loss_fn)(params, xb, ob, rb, mb)
        upd, state = opt.update(g, state, params)
        return optax.apply_updates(params, upd), state, loss

    rng = np.random.default_rng(a.seed)
    t1 = time.time()
    for epoch in range(a.epochs):
        perm = rng.permutation(len(x))
        total = 0.0
        for s in range(steps_per_epoch):
            idx = np.sort(perm[s * a.batch:(s + 1) * a.batch])
            params, state, loss = step(params, state, x[idx], obj[idx], reg[idx], mask[idx])
            total += float(loss)
            if s % 100 == 0:
                print(f"  step {s}: {float(loss):.4f} ({time.time() - t1:.0f} s)", flush=True)
        print(f"epoch {epoch + 1}/{a.epochs}: loss {total / steps_per_epoch:.4f} "
              f"({time.time() - t1:.0f} s)", flush=True)
    train_s = time.time() - t1

    # Activation ranges for int8 (docs/NN.md): the 99.99th percentile of each
    # ReLU output over 2048 training images.
    calib = x[rng.permutation(len(x))[:2048]]
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
    meta = {"command": " ".join(sys.argv), "images": len(labels), "epochs": a.epochs,
            "batch": a.batch, "lr": a.lr, "seed": a.seed, "train_seconds": round(train_s, 1),
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
