"""Accuracy of the gate network on a `cosim dataset` directory, float and
int8, numpy only (docs/NN.md):

    python3 training/evaluate.py DIR [--checkpoint training/checkpoint.npz]

Prints JSON: per model, images, detection_rate (visible gates found),
false_positive_rate (a gate reported in an image without one),
mean_px_error / median_px_error / p95_px_error (centre, on the 320x320 image, over the
detected gates) and mean_distance_error_m.
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef  # noqa: E402


def decode_float(head, rule=None):
    """Float head (n, 5, 5, 12) -> list of (visible, u, v, distance_m) in
    camera pixels, with the int8 decoding's rule (int8_ref.pick_cell; `rule`
    in float units, export.decode_rule(ckpt, "float"); None: the first
    maximum in raster order, visible when its logit > 0)."""
    import int8_ref

    out = []
    for h in head:
        flat = h.reshape(-1, netdef.HEAD_CHANNELS)
        best, visible = int8_ref.pick_cell(flat[:, 0], flat[:, 3], rule)
        gy, gx = divmod(best, netdef.GRID)
        cu, cv = netdef.cell_centre(gx, gy)
        c = h[gy, gx]
        out.append((visible, cu + c[1] * netdef.CELL_PX,
                    cv + c[2] * netdef.CELL_PX, c[3] * netdef.DIST_SCALE_M))
    return out


def metrics(preds, labels):
    vis = [r["visible"] for r in labels]
    n_vis = sum(vis)
    found = [p for p, r in zip(preds, labels) if r["visible"] and p[0]]
    fp = sum(1 for p, r in zip(preds, labels) if not r["visible"] and p[0])
    err = np.array([np.hypot(p[1] - r["u"], p[2] - r["v"])
                    for p, r in zip(preds, labels) if r["visible"] and p[0]])
    derr = np.array([abs(p[3] - r["distance_m"])
                     for p, r in zip(preds, labels) if r["visible"] and p[0]])
    return {
        "images": len(labels),
        "with_gate": n_vis,
        "detection_rate": round(len(found) / max(n_vis, 1), 4),
        "false_positive_rate": round(fp / max(len(labels) - n_vis, 1), 4),
        "mean_px_error": round(float(err.mean()), 2) if len(err) else None,
        "median_px_error": round(float(np.median(err)), 2) if len(err) else None,
        "p95_px_error": round(float(np.percentile(err, 95)), 2) if len(err) else None,
        "mean_distance_error_m": round(float(derr.mean()), 3) if len(derr) else None,
    }


def main():
    import export
    import int8_ref

    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--checkpoint", default=os.path.join(here, "checkpoint.npz"))
    a = ap.parse_args()
    ckpt = export.load_checkpoint(a.checkpoint)  # selects the net, its input resolution
    small, labels = netdef.load_dataset(a.data)
    x = netdef.to_int8(small)
    head = int8_ref.float_forward(ckpt, x.astype(np.float64) / 128.0)
    q = export.quantize(ckpt)
    res = int8_ref.infer_batch(q, x, export.decode_rule(ckpt))
    int8_preds = [(r["visible"], r["u_q4"] / 16, r["v_q4"] / 16, r["distance_mm"] / 1000) for r in res]
    print(json.dumps({"data": a.data, "macs": int(sum(netdef.macs())), "params": netdef.params(),
                      "decode": json.loads(str(ckpt["decode"])) if "decode" in ckpt else "best cell > 0",
                      "float": metrics(decode_float(head, export.decode_rule(ckpt, "float")), labels),
                      "int8": metrics(int8_preds, labels)}, indent=1))


if __name__ == "__main__":
    main()
