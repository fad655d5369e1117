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
   for widening bands;
3. scores the unambiguous images alone: those whose every listed gate is
   clearly visible (2-6 m, its centre at least 32 px inside the image, at
   most 60 degrees off its normal) or clearly not (beyond 9 m, its centre
   more than 48 px outside, or beyond 80 degrees);
4. splits the mean centre error by the label's distance and, for the gross
   errors (> 40 px), by what lies at the reported centre: another visible
   gate, a listed gate that is not visible (nearer or farther than the
   label's), or no listed gate; each group's share of the mean.

This is an analysis, not the evaluation: §13's figures are over every image
(`evaluate.py`, `cosim nn eval`).

    python3 training/analyse_lines.py DIR [--checkpoint training/checkpoint.npz]

DIR needs `gates.csv` (every `cosim dataset` since it was added).
"""

import argparse
import collections
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import analyse_errors  # noqa: E402
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402

NEAR_REPORT_PX = 60
GROSS_PX = analyse_errors.GROSS_PX
# An unambiguous image's gates: clearly visible or clearly not (item 3).
CLEAR_IN = {"m": (2.0, 6.0), "px": 32, "deg": 60.0}
CLEAR_OUT = {"m": 9.0, "px": 48, "deg": 80.0}
DISTANCE_BANDS_M = (1.5, 2.0, 6.0)
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


def clearly_in(g):
    lo, hi = CLEAR_IN["m"]
    return (lo <= g["distance_m"] <= hi and edge_px(g) >= CLEAR_IN["px"]
            and g["off_normal_deg"] <= CLEAR_IN["deg"])


def clearly_out(g):
    return (g["distance_m"] > CLEAR_OUT["m"] or edge_px(g) < -CLEAR_OUT["px"]
            or g["off_normal_deg"] > CLEAR_OUT["deg"])


def unambiguous(listed):
    """Every listed gate of the image clearly visible or clearly not."""
    return all(clearly_in(g) or clearly_out(g) for g in listed)


def distance_band(d):
    edges = DISTANCE_BANDS_M
    for lo, hi in zip((0.0,) + edges, edges):
        if d < hi:
            return f"{lo:g}-{hi:g} m"
    return f"{edges[-1]:g}-8 m"


def error_cause(p, label, listed):
    """A detection's class: "placed" (within GROSS_PX of the label's centre)
    or, for a gross error, what lies at the reported centre."""
    if np.hypot(p[1] - label["u"], p[2] - label["v"]) <= GROSS_PX:
        return "placed"
    others = [g for g in listed if np.hypot(g["u"] - label["u"], g["v"] - label["v"]) > 1e-3]
    near = min(others, key=lambda g: np.hypot(g["u"] - p[1], g["v"] - p[2]), default=None)
    if near is None or np.hypot(near["u"] - p[1], near["v"] - p[2]) > GROSS_PX:
        return "gross: no listed gate at the report"
    if near["visible"]:
        return "gross: another visible gate"
    side = "nearer" if near["distance_m"] < label["distance_m"] else "farther"
    return f"gross: a gate not visible, {side}"


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

    keep = [unambiguous(gs) for gs in listed]
    ms = evaluate.metrics([p for p, k in zip(pred, keep) if k], [r for r, k in zip(labels, keep) if k])
    print(f"unambiguous images only: {ms['images']} ({ms['with_gate']} with a gate): detection "
          f"{ms['detection_rate']:.1%}, false positives {ms['false_positive_rate']:.1%}, mean "
          f"{ms['mean_px_error']:.2f} px, median {ms['median_px_error']:.2f} px")

    found = [(p, r, gs) for p, r, gs in zip(pred, labels, listed) if r["visible"] and p[0]]
    groups = collections.defaultdict(list)
    for p, r, gs in found:
        groups[(distance_band(r["distance_m"]), error_cause(p, r, gs))].append(
            np.hypot(p[1] - r["u"], p[2] - r["v"]))
    print(f"the mean centre error ({len(found)} detections) by the label's distance and cause:")
    print("  distance  cause                                  count  mean px  share of the mean")
    for (band, cause), e in sorted(groups.items()):
        print(f"  {band:9s} {cause:38s} {len(e):5d} {np.mean(e):8.1f} {np.sum(e) / len(found):9.2f} px")


if __name__ == "__main__":
    main()
