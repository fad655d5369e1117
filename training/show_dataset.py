"""A contact sheet of the first 16 images of a `cosim dataset` directory
with their labels drawn (numpy only; docs/NN.md):

    python3 training/show_dataset.py DIR OUT.png

Red: the labelled centre; green, blue, magenta, cyan: the corners
top-left, top-right, bottom-right, bottom-left.
"""

import os
import struct
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef  # noqa: E402

COLOURS = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 0, 255), (0, 255, 255)]


def write_png(path, rgb):
    h, w = rgb.shape[:2]
    raw = b"".join(b"\x00" + rgb[r].tobytes() for r in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def main():
    d, out = sys.argv[1], sys.argv[2]
    tiles = []
    for r in netdef.read_labels(d)[:16]:
        g = netdef.read_pgm(os.path.join(d, r["file"]))
        rgb = np.stack([g] * 3, -1).copy()
        if r["visible"]:
            c = r["corners"]
            pts = [(r["u"], r["v"])] + [(c[2 * k], c[2 * k + 1]) for k in range(4)]
            for (u, v), colour in zip(pts, COLOURS):
                iu, iv = int(np.floor(u)), int(np.floor(v))
                rgb[max(iv - 3, 0):max(iv + 4, 0), max(iu - 3, 0):max(iu + 4, 0)] = colour
        tiles.append(rgb)
    while len(tiles) % 4:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.concatenate(tiles[i:i + 4], 1) for i in range(0, len(tiles), 4)]
    write_png(out, np.concatenate(rows, 0))


if __name__ == "__main__":
    main()
