"""The gate network's definition, shared by training, export and the int8
reference (numpy only; docs/NN.md).

Input: the 320x320 camera image averaged over 4x4 blocks (integer, rounded)
to 80x80, minus 128, as int8 (float: that / 128). Six 3x3 convolutions with
ReLU (four of stride 2) down to a 5x5 grid, then a 1x1 head: 12 channels per
grid cell (one cell = 16x16 input pixels = 64x64 camera pixels):

  0     objectness logit: "the nearest visible gate's centre is in this cell"
        (train.py --gates: "a visible gate's centre is in this cell", and
        the decoding reports the nearest such cell, docs/NN.md)
  1, 2  centre - cell centre, (u, v), in cells (64 px)
  3     distance / 8 m
  4-11  the opening's corners - cell centre, (u0 v0 u1 v1 u2 v2 u3 v3), in cells

That is NETS["base"], the committed network; NETS["wide"] widens conv4-conv6
(same input, grid and head channels, so decode.c and nn_race.c are
unchanged); NETS["fine160"] takes a 160x160 input (2x2 block means, POOLS)
through two stride-2 layers into the base network's conv2-head;
NETS["teacher"] is a large network (26 MMAC) that only trains and teaches. A
checkpoint records its net and export.load_checkpoint selects it
(select()), so every script follows the checkpoint's shape, input
resolution included.

Layout everywhere: activations HWC (channel fastest), weights
[cout][kh][kw][cin] (the dot product runs over cin, 4 int8 per SIMD word).
"""

import csv
import os

import numpy as np

CAMERA = 320
POOL = 4  # camera pixels per input pixel (each way): the selected net's POOLS entry
INPUT = CAMERA // POOL  # 80 (160 for "fine160")
GRID = 5
CELL_PX = CAMERA // GRID  # 64 camera pixels per grid cell
DIST_SCALE_M = 8.0

# name, kernel, stride, pad, cin, cout, relu
_BASE = [
    ("conv1", 3, 2, 1, 1, 8, True),
    ("conv2", 3, 2, 1, 8, 16, True),
    ("conv3", 3, 2, 1, 16, 32, True),
    ("conv4", 3, 1, 1, 32, 32, True),
    ("conv5", 3, 2, 1, 32, 64, True),
    ("conv6", 3, 1, 1, 64, 64, True),
    ("head", 1, 1, 0, 64, 12, False),
]
NETS = {
    # The committed network (3.36 MMAC).
    "base": _BASE,
    # Its conv1-conv3 with conv4-conv6 widened to use DESIGN.md §13's
    # 5 MMAC (4.99 MMAC; docs/NN.md "A wider network"). conv6 keeps 64
    # input channels so the firmware's 9 KiB weight slot still takes
    # 16-channel tiles (576 bytes a channel), which keep 8 cores busy on 5x5.
    "wide": _BASE[:3] + [
        ("conv4", 3, 1, 1, 32, 48, True),
        ("conv5", 3, 2, 1, 48, 64, True),
        ("conv6", 3, 1, 1, 64, 128, True),
        ("head", 1, 1, 0, 128, 12, False),
    ],
    # A 160x160 input (2x2 means) for the far gates and the centres
    # (docs/NN.md "A finer input": at 8 m the 0.8 m opening is 8.5 pixels
    # of the 80x80 input and its bars half a pixel). conv0 and conv1 take it
    # to conv1's 40x40x8 of the base network, whose conv2-head follow
    # unchanged: 4.63 MMAC, within DESIGN.md §13's 5.
    "fine160": [
        ("conv0", 3, 2, 1, 1, 8, True),
        ("conv1", 3, 2, 1, 8, 8, True),
    ] + _BASE[1:],
    # Not for the cluster: a network five times over DESIGN.md §13's 5 MMAC
    # (26.1 MMAC, 745,068 parameters), trained to measure what capacity buys
    # on these labels and to teach the small networks (train.py --teacher;
    # docs/NN.md "A large network").
    "teacher": [
        ("conv1", 3, 2, 1, 1, 16, True),
        ("conv2", 3, 2, 1, 16, 32, True),
        ("conv3", 3, 2, 1, 32, 64, True),
        ("conv4", 3, 1, 1, 64, 96, True),
        ("conv5", 3, 2, 1, 96, 128, True),
        ("conv6", 3, 1, 1, 128, 192, True),
        ("conv7", 3, 1, 1, 192, 192, True),
        ("head", 1, 1, 0, 192, 12, False),
    ],
    # The teacher's widths within DESIGN.md §13's 5 MMAC: after conv1,
    # depthwise-separable layers (MobileNet's trade): a 3x3 per channel
    # ("dw": cin == cout, one weight per tap and channel) then a 1x1
    # across channels ("pw"), each with ReLU. 4.40 MMAC, 101,164
    # parameters; the same 7 3x3 layers' receptive field as the teacher
    # (docs/NN.md "Depthwise-separable").
    "sep": [
        ("conv1", 3, 2, 1, 1, 16, True),
        ("dw2", 3, 2, 1, 16, 16, True),
        ("pw2", 1, 1, 0, 16, 32, True),
        ("dw3", 3, 2, 1, 32, 32, True),
        ("pw3", 1, 1, 0, 32, 64, True),
        ("dw4", 3, 1, 1, 64, 64, True),
        ("pw4", 1, 1, 0, 64, 96, True),
        ("dw4b", 3, 1, 1, 96, 96, True),
        ("pw4b", 1, 1, 0, 96, 96, True),
        ("dw5", 3, 2, 1, 96, 96, True),
        ("pw5", 1, 1, 0, 96, 128, True),
        ("dw6", 3, 1, 1, 128, 128, True),
        ("pw6", 1, 1, 0, 128, 192, True),
        ("dw7", 3, 1, 1, 192, 192, True),
        ("pw7", 1, 1, 0, 192, 192, True),
        ("head", 1, 1, 0, 192, 12, False),
    ],
}
# Camera pixels per input pixel (each way) of each net; every other net 4.
POOLS = {"fine160": 2}
NET = "base"
LAYERS = NETS[NET]
HEAD_CHANNELS = 12


def checkpoint_net(ckpt):
    """The net a checkpoint (its arrays, or the open .npz) records; one
    without a `net` entry, like the committed one, is "base"."""
    return str(ckpt["net"]) if "net" in ckpt else "base"


def select(name):
    """Make `name` (a key of NETS) the network every function here and the
    scripts describe; a checkpoint records its net (export.load_checkpoint
    selects it), the committed one has none and is "base"."""
    global NET, LAYERS, POOL, INPUT
    if name not in NETS:
        raise ValueError(f"unknown network {name!r} (known: {', '.join(NETS)})")
    NET, LAYERS = name, NETS[name]
    POOL = POOLS.get(name, 4)
    INPUT = CAMERA // POOL

# The head's int16 output units (in the float head's units): objectness in
# 1/64 logit, offsets in 1/16 camera pixel (1/(16 CELL_PX) cell), distance
# in mm (1/8000 of 8 m).
_Q4 = 1 / (16 * CELL_PX)
HEAD_UNITS = np.array([1 / 64, _Q4, _Q4, 1 / 8000] + [_Q4] * 8, dtype=np.float64)


def geometry():
    """(in_h, in_w, out_h, out_w) of each layer."""
    out, h = [], INPUT
    for _, k, s, p, _, _, _ in LAYERS:
        o = (h + 2 * p - k) // s + 1
        out.append((h, h, o, o))
        h = o
    return out


def depthwise(name):
    """A depthwise layer ("dw..."): each output channel convolves its own
    input channel alone (cin == cout; weights [cout][k][k][1])."""
    return name.startswith("dw")


def weight_cin(layer):
    """The input channels one output channel's weights span."""
    name, _, _, _, cin, _, _ = layer
    return 1 if depthwise(name) else cin


def macs():
    """Multiply-accumulates per inference, per layer."""
    return [
        oh * ow * layer[5] * layer[1] ** 2 * weight_cin(layer)
        for (_, _, oh, ow), layer in zip(geometry(), LAYERS)
    ]


def params():
    return sum(layer[1] ** 2 * weight_cin(layer) * layer[5] + layer[5] for layer in LAYERS)


def read_pgm(path):
    """A binary (P5) 8-bit PGM as a (h, w) uint8 array."""
    with open(path, "rb") as f:
        data = f.read()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    if fields[0] != b"P5" or int(fields[3]) != 255:
        raise ValueError(f"{path}: not an 8-bit binary PGM")
    w, h = int(fields[1]), int(fields[2])
    pixels = np.frombuffer(data, dtype=np.uint8, count=w * h, offset=pos + 1)
    return pixels.reshape(h, w)


def downsample(images):
    """(n, 320, 320) uint8 -> (n, INPUT, INPUT) uint8: the rounded mean of
    each POOL x POOL block, (sum + POOL^2 / 2) >> log2(POOL^2): for the 80x80
    input (sum + 8) >> 4, exactly as the firmware does it."""
    n, area = images.shape[0], POOL * POOL
    s = images.reshape(n, INPUT, POOL, INPUT, POOL).astype(np.int32).sum(axis=(2, 4))
    return ((s + area // 2) // area).astype(np.uint8)


def to_int8(small):
    """(n, INPUT, INPUT) uint8 -> (n, INPUT, INPUT, 1) int8: pixel - 128."""
    return (small.astype(np.int16) - 128).astype(np.int8)[..., None]


def read_labels(directory):
    """labels.csv as a list of dicts: file, visible (bool), u, v, distance_m,
    corners (8 floats) for visible rows."""
    rows = []
    with open(os.path.join(directory, "labels.csv"), newline="") as f:
        for r in csv.DictReader(f):
            vis = r["gate_visible"] == "1"
            row = {"file": r["file"], "visible": vis}
            if vis:
                row["u"] = float(r["u"])
                row["v"] = float(r["v"])
                row["distance_m"] = float(r["distance_m"])
                row["corners"] = [float(x) for x in r["corners"].split()]
            rows.append(row)
    return rows


def read_gates(directory, files):
    """gates.csv (every gate in front of the camera and not occluded, with
    the labels' strict verdict; docs/NN.md) as one list per image of `files`
    (labels.csv's order): dicts with u, v, distance_m, off_normal_deg,
    in_image, visible (bools) and corners (8 floats, or None when a corner
    lies behind the camera)."""
    index = {f: i for i, f in enumerate(files)}
    out = [[] for _ in files]
    with open(os.path.join(directory, "gates.csv"), newline="") as f:
        for r in csv.DictReader(f):
            i = index.get(r["file"])
            if i is None:
                continue
            out[i].append({
                "u": float(r["u"]), "v": float(r["v"]),
                "distance_m": float(r["distance_m"]),
                "off_normal_deg": float(r["off_normal_deg"]),
                "in_image": r["in_image"] == "1", "visible": r["visible"] == "1",
                "corners": [float(x) for x in r["corners"].split()] if r["corners"] else None,
            })
    return out


def load_dataset(directory, limit=None):
    """(inputs (n, INPUT, INPUT) uint8, labels) of a `cosim dataset` directory."""
    labels = read_labels(directory)[:limit]
    small = np.empty((len(labels), INPUT, INPUT), dtype=np.uint8)
    for i, r in enumerate(labels):
        small[i] = downsample(read_pgm(os.path.join(directory, r["file"]))[None])[0]
    return small, labels


def cell_centre(gx, gy):
    """Camera pixel of a grid cell's centre."""
    return gx * CELL_PX + CELL_PX / 2, gy * CELL_PX + CELL_PX / 2
