"""Chooses the "nearest" decoding's threshold on a VALIDATION set (never the
held-out one) and stores it in a checkpoint (numpy only; docs/NN.md):

    python3 training/choose_threshold.py VAL_DIR --checkpoint CKPT [--write]

The decoding (int8_ref step 3): among the cells whose objectness > T (1/64
logit) and distance <= D (mm), the nearest. For each T and D it prints the
int8 network's detection rate, false positives and centre errors on the
set, and picks the (T, D) with the fewest misses plus false positives
(detection rate - false-positive rate highest; on a tie the higher T). With
--write the checkpoint gets `decode` = {"rule": "nearest", "threshold_q":
T, "max_distance_mm": D, "chosen_on": VAL_DIR, "command": ...}: the export
(weights.h's NN_DECODE_* macros), the reference and the evaluation then
use it.
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402

THRESHOLDS_Q = range(-128, 193, 16)  # 1/64 logit: -2 to +3
MAX_DISTANCES_MM = (8000, 8500, 9000, 32767)  # 32767: no limit (int16)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data", help="the validation dataset")
    ap.add_argument("--checkpoint", default=export.DEFAULT_CHECKPOINT)
    ap.add_argument("--write", action="store_true", help="store the choice in the checkpoint")
    a = ap.parse_args()
    ckpt = export.load_checkpoint(a.checkpoint)  # selects the net, its input resolution
    small, labels = netdef.load_dataset(a.data)
    heads = int8_ref.heads_batch(export.quantize(ckpt), netdef.to_int8(small))
    best = None
    print("   T    D mm  detected  false pos  mean px  p95 px")
    for d in MAX_DISTANCES_MM:
        for t in THRESHOLDS_Q:
            rule = {"threshold": t, "max_distance": d}
            res = [int8_ref.decode(h, rule) for h in heads]
            m = evaluate.metrics([(r["visible"], r["u_q4"] / 16, r["v_q4"] / 16,
                                   r["distance_mm"] / 1000) for r in res], labels)
            print(f"{t:5d} {d:6d} {m['detection_rate']:9.1%} {m['false_positive_rate']:9.1%} "
                  f"{m['mean_px_error'] or 0:8.2f} {m['p95_px_error'] or 0:7.2f}")
            key = (m["detection_rate"] - m["false_positive_rate"], t)
            if best is None or key > best[0]:
                best = (key, t, d, m)
    _, t, d, m = best
    print(f"chosen: T = {t} (1/64 logit), D = {d} mm: {json.dumps(m)}")
    if a.write:
        ckpt["decode"] = np.array(json.dumps({
            "rule": "nearest", "threshold_q": t, "max_distance_mm": d,
            "chosen_on": a.data, "command": " ".join(sys.argv)}))
        np.savez(a.checkpoint, **ckpt)
        print(f"wrote the rule into {a.checkpoint}")


if __name__ == "__main__":
    main()
