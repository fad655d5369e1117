"""How much of the int8 network's error lies at the labelling rules' lines
(numpy; docs/NN.md "Accuracy"): the rules (docs/NN.md "The data") call a
gate visible when its opening's centre projects inside the image, at most
8 m away and at most 70 degrees off its normal. A gate just across one of
those lines looks like one just inside it, so this script

1. sorts the false positives by the listed gate nearest the reported centre
   (`gates.csv`): its centre just outside the image, beyond 8 m, beyond 70
   degrees, or no listed gate near the report (an occluded gate, or one
   whose centre lies far outside);
2. scores the images again without those that have a gate within a band
   around a line (any gate of `gates.csv` whose centre lies within PX
   pixels of the image's edge, either side, or within M metres of 8 m, or
   within DEG degrees of 70, the other rules holding within their band),
   for widening bands. This is an analysis, not the evaluation: §13's
   figures are over every image (`evaluate.py`, `cosim nn eval`).

    python3 training/analyse_lines.py DIR [--checkpoint training/checkpoint.npz]

DIR needs `gates.csv` (every `cosim dataset` since it was added).
"""

import argparse
import collections
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402

NEAR_REPORT_PX = 60
BANDS = ((8, 0.25, 3), (16, 0.5, 5), (32, 1.0, 10))  # (px, m, degrees)
MAX_M, MAX_DEG = 8.0, 70.0


def edge_px(g):
    """Distance of a gate's centre to the image's edge (negative outside)."""
    c = netdef.CAMERA
    return min(g["u"], g["v"], c - g["u"], c - g["v"])


def near_a_line(g, px, m, deg):
    e, d, a = edge_px(g), g["distance_m"], g["off_normal_deg"]
    inside, near, square = e >= -px, d <= MAX_M + m, a <= MAX_DEG + deg
    return ((abs(e) <= px and near and square)
            or (abs(d - MAX_M) <= m and inside and square)
            or (abs(a - MAX_DEG) <= deg and inside and near))


def why_reported(p, listed):
    """The false positive's cause: the listed gate nearest the report."""
    best = min(listed, key=lambda g: np.hypot(g["u"] - p[1], g["v"] - p[2]), default=None)
    if best is None or np.hypot(best["u"] - p[1], best["v"] - p[2]) > NEAR_REPORT_PX:
        return "no listed gate near the report"
    if not best["in_image"]:
        return "its centre outside the image"
    if best["distance_m"] > MAX_M:
        return "beyond 8 m"
    if best["off_normal_deg"] > MAX_DEG:
        return "beyond 70 degrees"
    return "other"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--checkpoint", default=export.DEFAULT_CHECKPOINT)
    a = ap.parse_args()
    ckpt, small, labels = export.checkpoint_and_dataset([a.data, "--checkpoint", a.checkpoint])
    listed = netdef.read_gates(a.data, [r["file"] for r in labels])
    x = netdef.to_int8(small)
    res = int8_ref.infer_batch(export.quantize(ckpt), x, export.decode_rule(ckpt))
    pred = [(r["visible"], r["u_q4"] / 16, r["v_q4"] / 16, r["distance_mm"] / 1000) for r in res]

    fps = [(p, g, why_reported(p, g))
           for p, r, g in zip(pred, labels, listed) if p[0] and not r["visible"]]
    causes = collections.Counter(why for _, _, why in fps)
    outside = [min(abs(edge_px(g)) for g in gs if not g["in_image"]) for _, gs, why in fps
               if why == "its centre outside the image"]
    print(f"false positives (int8): {len(fps)} of {sum(not r['visible'] for r in labels)} "
          "images without a visible gate; the listed gate nearest the report:")
    for why, n in causes.most_common():
        print(f"  {why:34s} {n:4d}")
    if outside:
        print(f"  (centres outside: median {np.median(outside):.0f} px beyond the edge, "
              f"{np.mean(np.array(outside) <= 32):.0%} within 32 px)")

    print("images left out          images  with gate  detection  false pos.  mean px  median px")
    for px, m, deg in ((0, 0.0, 0),) + BANDS:
        keep = [not any(near_a_line(g, px, m, deg) for g in gs) if px else True for gs in listed]
        ms = evaluate.metrics([p for p, k in zip(pred, keep) if k],
                              [r for r, k in zip(labels, keep) if k])
        band = f"{px} px, {m} m, {deg} deg" if px else "none"
        print(f"  {band:22s} {ms['images']:7d} {ms['with_gate']:10d} {ms['detection_rate']:10.1%} "
              f"{ms['false_positive_rate']:11.1%} {ms['mean_px_error']:8.2f} {ms['median_px_error']:10.2f}")


if __name__ == "__main__":
    main()
