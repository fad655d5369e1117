"""What the labels' lines cost an observer that errs only in measuring
(numpy; docs/NN.md "The labels' floor"). The labelling rules (docs/NN.md
"The data") call a gate visible when its opening's centre projects inside
the image, at most 8 m away and at most 70 degrees off its normal, and
label the nearest such gate. Each rule is a hard line on a quantity the
image shows only to within a measuring error, so even a detector that
sees every gate and errs in nothing else crosses the lines now and then.

The *observer* here is that detector. It is handed every gate of
`gates.csv` (every gate whose centre is in front of the camera and not
occluded: it never misses an unoccluded gate, never reports a gate that is
not there and knows occlusion exactly), measures each one's centre with a
Gaussian error of SIGMA px per axis, its distance with a relative error of
REL (one standard deviation) and its angle off the normal with DEG
degrees, applies the rules to what it measured, and reports the nearest
gate it judged visible at the centre it measured. Scored by
`evaluate.metrics` against `labels.csv`, as §13's figures are. Its scores
are what the lines alone cost a detector of that measuring precision on
these labels; a network also misses gates, reports gates that are not
there and misjudges occlusion and which gate is nearer.

    python3 training/label_floor.py DIR [--checkpoint C] [--draws 20] [--seed 0]

With --checkpoint, it first measures the network's own precision on the
detections it placed (within 40 px of the label; int8, as `cosim nn eval`
scores it): the per-axis centre error and the relative distance error,
each a robust standard deviation (1.4826 x the median absolute error), and
adds an observer of that precision to the table. Every draw comes from
numpy's seeded generator (`--seed`), so the output is reproducible.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402
import netdef  # noqa: E402
from analyse_errors import GROSS_PX  # noqa: E402
from analyse_lines import MAX_DEG, MAX_M  # noqa: E402
# (centre px per axis, relative distance, degrees): from a perfect observer
# to worse than the 26 MMAC teacher's placement (median 2.4 px, docs/NN.md
# "A large network").
PRECISIONS = ((0.0, 0.0, 0.0), (0.5, 0.01, 1.0), (1.0, 0.02, 2.0), (2.0, 0.03, 3.0),
              (2.0, 0.05, 5.0), (3.0, 0.05, 5.0), (4.0, 0.08, 8.0))


def observe(listed, sigma_px, rel, deg, rng):
    """One draw of the observer over every image: a list of
    (visible, u, v, distance_m), as `evaluate.metrics` takes them."""
    out = []
    c = netdef.CAMERA
    for gates in listed:
        best = None
        for g in gates:
            n = rng.standard_normal(4)
            u, v = g["u"] + sigma_px * n[0], g["v"] + sigma_px * n[1]
            d = g["distance_m"] * (1.0 + rel * n[2])
            a = g["off_normal_deg"] + deg * n[3]
            if 0.0 <= u < c and 0.0 <= v < c and d <= MAX_M and a <= MAX_DEG:
                if best is None or d < best[3]:
                    best = (True, u, v, d)
        out.append(best or (False, 0.0, 0.0, 0.0))
    return out


def floor(labels, listed, sigma_px, rel, deg, draws, rng):
    """The observer's scores, each the mean over `draws` draws."""
    keys = ("detection_rate", "false_positive_rate", "mean_px_error", "gross_rate")
    runs = []
    for _ in range(draws):
        preds = observe(listed, sigma_px, rel, deg, rng)
        m = evaluate.metrics(preds, labels)
        err = [np.hypot(p[1] - r["u"], p[2] - r["v"]) for p, r in zip(preds, labels)
               if p[0] and r["visible"]]
        m["gross_rate"] = float(np.mean(np.array(err) > GROSS_PX)) if err else 0.0
        runs.append(m)
    return {k: float(np.mean([r[k] or 0.0 for r in runs])) for k in keys}


def robust_sigma(x):
    """1.4826 x the median absolute deviation: the standard deviation of a
    normal law, unmoved by the few gross errors left in."""
    x = np.asarray(x, dtype=float)
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def network_precision(data, checkpoint):
    """The int8 network's robust per-axis centre error (px) and relative
    distance error over the detections it placed within GROSS_PX."""
    import export
    import int8_ref

    ckpt, small, labels = export.checkpoint_and_dataset([data, "--checkpoint", checkpoint])
    res = int8_ref.infer_batch(export.quantize(ckpt), netdef.to_int8(small), export.decode_rule(ckpt))
    du, dv, dd, found = [], [], [], 0
    for r, lab in zip(res, labels):
        if not (r["visible"] and lab["visible"]):
            continue
        found += 1
        u, v = r["u_q4"] / 16, r["v_q4"] / 16
        if np.hypot(u - lab["u"], v - lab["v"]) > GROSS_PX:
            continue
        du.append(u - lab["u"])
        dv.append(v - lab["v"])
        dd.append(r["distance_mm"] / 1000 / lab["distance_m"] - 1.0)
    preds = [(r["visible"], r["u_q4"] / 16, r["v_q4"] / 16, r["distance_mm"] / 1000) for r in res]
    own = evaluate.metrics(preds, labels)
    own["gross_rate"] = 1.0 - len(du) / max(found, 1)
    return 0.5 * (robust_sigma(du) + robust_sigma(dv)), robust_sigma(dd), len(du), own


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--checkpoint", help="also an observer of this network's precision")
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    labels = netdef.read_labels(a.data)
    listed = netdef.read_gates(a.data, [r["file"] for r in labels])
    rng = np.random.default_rng(a.seed)
    rows = list(PRECISIONS)
    if a.checkpoint:
        px, rel, n, own = network_precision(a.data, a.checkpoint)
        print(f"{a.checkpoint}: {n} placed detections, centre "
              f"{px:.2f} px per axis, distance {rel:.1%} (robust standard deviations); "
              f"the network itself (int8): detection {own['detection_rate']:.1%}, false positives "
              f"{own['false_positive_rate']:.1%}, mean {own['mean_px_error']:.2f} px, gross "
              f"{own['gross_rate']:.1%}")
        rows.append((round(px, 2), round(rel, 4), 5.0))
    print(f"{len(labels)} images, {sum(r['visible'] for r in labels)} with a gate; "
          f"{a.draws} draws each")
    print("centre px  distance  angle deg   detection  false pos.  mean px  gross (> 40 px)")
    for px, rel, deg in rows:
        m = floor(labels, listed, px, rel, deg, a.draws, rng)
        print(f"{px:9.2f} {rel:9.1%} {deg:9.1f} {m['detection_rate']:11.1%} "
              f"{m['false_positive_rate']:11.1%} {m['mean_px_error']:8.2f} {m['gross_rate']:10.1%}")


if __name__ == "__main__":
    main()
