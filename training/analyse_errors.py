"""Where the float network's misses and centre errors come from on a dataset
(numpy; docs/NN.md): detection and gross errors (> 40 px off the label) by
the label's distance and by how near the centre lies to the image's edge.

    python3 training/analyse_errors.py DIR [--checkpoint training/checkpoint.npz]
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402

GROSS_PX = 40


def main():
    ck, small, labels = export.checkpoint_and_dataset()
    head = int8_ref.float_forward(ck, netdef.to_int8(small).astype(np.float64) / 128)
    pred = evaluate.decode_float(head, export.decode_rule(ck, "float"))
    rows = []  # (distance, edge distance px, detected, centre error, distance error)
    for p, r in zip(pred, labels):
        if r["visible"]:
            edge = min(r["u"], r["v"], netdef.CAMERA - r["u"], netdef.CAMERA - r["v"])
            err = np.hypot(p[1] - r["u"], p[2] - r["v"]) if p[0] else np.nan
            rows.append((r["distance_m"], edge, p[0], err, abs(p[3] - r["distance_m"])))
    t = np.array(rows, dtype=np.float64)
    det = t[:, 2] > 0
    gross = det & (t[:, 3] > GROSS_PX)
    fine = det & ~gross
    print(f"{len(t)} visible gates: {det.sum()} detected, {gross.sum()} of them > {GROSS_PX} px off "
          f"({gross.sum() / max(det.sum(), 1):.1%}); mean error of the rest "
          f"{np.mean(t[fine, 3]):.2f} px (median {np.median(t[fine, 3]):.2f})")
    if gross.any():
        print(f"gross: reported distance off the label's by a median {np.median(t[gross, 4]):.2f} m "
              f"(the rest {np.median(t[fine, 4]):.2f} m)")
    print("label distance   gates  detected  gross")
    for lo, hi in ((0, 2), (2, 4), (4, 6), (6, 7), (7, 8.01)):
        s = (t[:, 0] >= lo) & (t[:, 0] < hi)
        print(f"  {lo}-{min(hi, 8):g} m {s.sum():10d} {det[s].mean():9.1%} "
              f"{gross[s].sum() / max(det[s].sum(), 1):6.1%}")
    print("centre to edge   gates  detected  gross")
    for lo, hi in ((0, 16), (16, 32), (32, 64), (64, 161)):
        s = (t[:, 1] >= lo) & (t[:, 1] < hi)
        print(f"  {lo}-{min(hi, 160)} px {s.sum():9d} {det[s].mean():9.1%} "
              f"{gross[s].sum() / max(det[s].sum(), 1):6.1%}")
    fp = sum(1 for p, r in zip(pred, labels) if p[0] and not r["visible"])
    print(f"false positives: {fp} of {sum(not r['visible'] for r in labels)} images without a gate")
    # The decoding's threshold (the best cell's logit > 0) against others:
    # what a firmware threshold could trade.
    best = head[..., 0].reshape(len(head), -1).max(axis=1)
    vis = np.array([r["visible"] for r in labels])
    print("best logit >  detected  false positives")
    for t in (-1.0, -0.5, 0.0, 0.5, 1.0):
        print(f"  {t:+.1f} {np.mean(best[vis] > t):15.1%} {np.mean(best[~vis] > t):12.1%}")


if __name__ == "__main__":
    main()
