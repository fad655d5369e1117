"""Writes training/golden/golden.json: the int8 reference's outputs on the
committed golden images (training/golden/*.pgm, made by
`cosim dataset scenarios/worlds/thesis-course-perturbed-s1.toml --count 8
--seed 22 --out training/golden`), for the firmware's future e2e test and
for tests/test_nn.py (numpy only):

    python3 training/make_golden.py
    python3 training/make_golden.py --checkpoint training/sep/checkpoint.npz \
        --out training/sep/golden.json     # the depthwise-separable network's

Per image: the int8 input's and every layer's output's SHA-256 (bytes in
HWC order, int8, the head int16 little-endian), the head's 300 int16
values and the decoded outputs.
"""

import argparse
import hashlib
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import export  # noqa: E402
import int8_ref  # noqa: E402
import netdef  # noqa: E402

GOLDEN = os.path.join(export.HERE, "golden")


def sha(a):
    return hashlib.sha256(np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()).hexdigest()


def golden_entry(q, rule, path):
    image = netdef.read_pgm(path)
    x = netdef.to_int8(netdef.downsample(image[None]))
    layers, a = [], x
    for layer in q:
        a = int8_ref.layer_int8(layer, a)
        layers.append(sha(a[0]))
    head = a[0]
    return {
        "file": os.path.basename(path),
        "input_sha256": sha(x[0]),
        "layer_sha256": layers,
        "head": head.ravel().astype(int).tolist(),
        "outputs": int8_ref.decode(head, rule),
    }


def golden(checkpoint=export.DEFAULT_CHECKPOINT):
    ckpt = export.load_checkpoint(checkpoint)
    q, rule = export.quantize(ckpt), export.decode_rule(ckpt)
    files = [r["file"] for r in netdef.read_labels(GOLDEN)]
    with open(checkpoint, "rb") as f:
        ck = hashlib.sha256(f.read()).hexdigest()
    return {"checkpoint_sha256": ck,
            "images": [golden_entry(q, rule, os.path.join(GOLDEN, f)) for f in files]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--checkpoint", default=export.DEFAULT_CHECKPOINT)
    ap.add_argument("--out", default=os.path.join(GOLDEN, "golden.json"),
                    help="where to write (the golden images stay training/golden's)")
    a = ap.parse_args()
    g = golden(a.checkpoint)
    with open(a.out, "w") as f:
        json.dump(g, f, indent=1)
        f.write("\n")
    for e in g["images"]:
        print(e["file"], json.dumps(e["outputs"]))


if __name__ == "__main__":
    main()
