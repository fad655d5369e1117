"""The fallback network: the depthwise-separable checkpoint
(training/sep/checkpoint.npz) with some activation ranges scaled, so that
the export gives layers whose requantization cannot take the kernels'
clip-first form (docs/NN_KERNELS.md "Int8 arithmetic", sim-core/firmware/src/nn/
requant.c) and the firmware runs its 64-bit forms instead: conv1, dw3, pw4
and pw7 the fast one (shift >= 25: hi * 2^shift overflows int32), dw4,
pw3 and the head the general one (shift < 15). Its outputs mean nothing;
it exists so that the kernels' fallback paths (conv.c: the depthwise
kernel for a one-plane layer and for both strides, the 2x4 kernel's CHW,
HWC and int16 outputs) run in a test: nn_eval_fallback.elf on the golden
images equals training/fallback/golden.json bit for bit
(tests/tests/e2e/nn_eval.rs), and tests/test_nn.py checks the committed files
are this script's output (numpy only):

    python3 training/make_fallback.py
"""

import hashlib
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import export  # noqa: E402
import make_golden  # noqa: E402
import netdef  # noqa: E402

SEP_CHECKPOINT = os.path.join(export.HERE, "sep", "checkpoint.npz")
OUT = os.path.join(export.DEFAULT_OUT, "fallback")
# The scaling changes activation ranges only, so the int8 weights are the
# sep network's: weights.c includes sep's weights_int8.h (`export.py
# --int8-header`) rather than repeating them.
SEP_INT8_HEADER = "../sep/" + export.INT8_HEADER
GOLDEN = os.path.join(export.HERE, "fallback", "golden.json")

# act_max factors: a larger range lowers a layer's real multiplier (a larger
# shift) and raises the next layer's (a smaller shift).
SCALES = {"conv1": 30.0, "dw3": 3000.0, "dw4": 1.0 / 300.0, "pw7": 100.0}
# The layers whose requantization the scaling takes out of the clip-first
# form, and the form they take (requant.c, network.c make_records).
FAST = ("conv1", "dw3", "pw4", "pw7")
GENERAL = ("pw3", "dw4", "head")


def checkpoint():
    """The sep checkpoint's arrays with SCALES applied (selects "sep")."""
    ckpt = dict(export.load_checkpoint(SEP_CHECKPOINT))
    names = [layer[0] for layer in netdef.LAYERS]
    act = ckpt["act_max"].astype(np.float64)
    for name, f in SCALES.items():
        act[names.index(name)] *= f
    ckpt["act_max"] = act.astype(ckpt["act_max"].dtype)
    meta = json.loads(str(ckpt["meta"]))
    meta["command"] = ("training/make_fallback.py: training/sep/checkpoint.npz with act_max scaled "
                       + ", ".join(f"{n} x{f:g}" for n, f in SCALES.items()))
    ckpt["meta"] = np.array(json.dumps(meta))
    return ckpt


def clip_first(bias, mult, shift, lo, hi):
    """requant.c's nn_rq_make: whether the clip-first form is exact for a
    channel (Python integers, so every product is exact)."""
    if mult <= 0 or lo >= hi or not 1 <= shift <= 31:
        return False
    rnd, unit = 1 << (shift - 1), 1 << shift
    a_hi = -((rnd - hi * unit) // mult)
    a_lo = ((lo + 1) * unit - rnd - 1) // mult

    def f(a):
        return (a * mult + rnd) >> shift

    if f(a_lo) != lo or f(a_hi) != hi:
        return False
    if a_lo * mult + rnd < -2**31 or a_hi * mult + rnd > 2**31 - 1:
        return False
    return a_lo - bias >= -2**31 and a_hi - bias <= 2**31 - 1


def layer_forms(q):
    """Each quantized layer's requantization form as the firmware picks it."""
    forms = {}
    for L in q:
        if all(clip_first(int(b), int(m), L["shift"], L["lo"], L["hi"])
               for b, m in zip(L["bias"], L["mult"])):
            forms[L["name"]] = "clip"
        else:
            forms[L["name"]] = "fast" if L["shift"] >= 15 else "general"
    return forms


def sources():
    """(weights.h, weights.c) of the fallback network."""
    ckpt = checkpoint()
    layers = export.quantize(ckpt)
    sep = export.int8_weights(export.quantize(export.load_checkpoint(SEP_CHECKPOINT)))
    for (n, w), (m, v) in zip(export.int8_weights(layers), sep):
        if n != m or not np.array_equal(w, v):
            raise ValueError(f"{n}: int8 weights differ from the sep network's ({SEP_INT8_HEADER})")
    return export.c_sources(layers, json.loads(str(ckpt["meta"])), export.decode_rule(ckpt),
                            SEP_INT8_HEADER)


def golden():
    """The int8 reference's outputs on the golden images (make_golden's
    fields; the checkpoint is the sep one's, by its SHA-256, and SCALES)."""
    ckpt = checkpoint()
    q, rule = export.quantize(ckpt), export.decode_rule(ckpt)
    files = [r["file"] for r in netdef.read_labels(make_golden.GOLDEN)]
    with open(SEP_CHECKPOINT, "rb") as f:
        ck = hashlib.sha256(f.read()).hexdigest()
    return {"checkpoint_sha256": ck, "act_max_scales": SCALES,
            "images": [make_golden.golden_entry(q, rule, os.path.join(make_golden.GOLDEN, f))
                       for f in files]}


def main():
    h, c = sources()
    os.makedirs(OUT, exist_ok=True)
    for name, text in (("weights.h", h), ("weights.c", c)):
        with open(os.path.join(OUT, name), "w") as f:
            f.write(text)
    g = golden()
    os.makedirs(os.path.dirname(GOLDEN), exist_ok=True)
    with open(GOLDEN, "w") as f:
        json.dump(g, f, indent=1)
        f.write("\n")
    forms = layer_forms(export.quantize(checkpoint()))
    print(f"wrote {OUT}/weights.h, weights.c and {GOLDEN}; forms: "
          + ", ".join(f"{n} {v}" for n, v in forms.items()))


if __name__ == "__main__":
    main()
