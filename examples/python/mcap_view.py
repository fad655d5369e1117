#!/usr/bin/env python3
"""A picture of a run.mcap, drawn from the file alone with the `mcap`
package and matplotlib: what Foxglove's layout (docs/foxglove-layout.json)
shows, where Foxglove itself cannot run.  Not a Foxglove screenshot.

Top view of the scene (`/scene` cubes, every drone's `/tf` path, the radio
links of `/radio/links`), one camera frame (`/<drone>/camera`), and the
battery's voltage and SOC (`/<drone>/battery`).

    python examples/python/mcap_view.py RUN.mcap [OUT.png] [--drone NAME]
"""

import argparse
import math
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import Polygon
from crazyflie_cosim.outputs import read_mcap


def cube_footprint(c):
    """The four corners (x, y) of a yawed cube primitive."""
    p, q, s = c["pose"]["position"], c["pose"]["orientation"], c["size"]
    yaw = 2 * math.atan2(q["z"], q["w"])
    cy, sy = math.cos(yaw), math.sin(yaw)
    hx, hy = s["x"] / 2, s["y"] / 2
    return [(p["x"] + cy * dx - sy * dy, p["y"] + sy * dx + cy * dy) for dx, dy in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mcap")
    ap.add_argument("out", nargs="?")
    ap.add_argument("--drone", help="whose camera and battery (default: the first)")
    a = ap.parse_args()
    out = Path(a.out or Path(a.mcap).with_suffix(".png"))

    scene, paths, links, images, battery = None, defaultdict(list), [], defaultdict(list), defaultdict(list)
    for m in read_mcap(a.mcap):
        if m.topic == "/scene" and scene is None:
            scene = m.data
        elif m.topic == "/tf":
            t = m.data["translation"]
            paths[m.data["child_frame_id"]].append((t["x"], t["y"]))
        elif m.topic == "/radio/links":
            pts = m.data["entities"][0]["lines"][0]["points"]
            links.append([(p["x"], p["y"]) for p in pts])
        elif m.topic.endswith("/camera"):
            images[m.topic.split("/")[1]].append(m)
        elif m.topic.endswith("/battery"):
            battery[m.topic.split("/")[1]].append((m.log_time * 1e-9, m.data["voltage_v"], m.data["soc"]))
    drone = a.drone or next(iter(paths), None)

    fig = plt.figure(figsize=(13, 7.5))
    top = fig.add_axes([0.04, 0.08, 0.52, 0.85])
    cam = fig.add_axes([0.60, 0.45, 0.36, 0.48])
    bat = fig.add_axes([0.62, 0.08, 0.32, 0.28])

    if scene:
        for c in scene["entities"][0]["cubes"]:
            g = c["color"]["r"]
            top.add_patch(Polygon(cube_footprint(c), closed=True, color=(g, g, g), alpha=0.9))
    for seg in links[-200:]:  # the last links, as the 3D panel shows them fading
        top.plot(*zip(*seg), color="tab:orange", lw=0.6, alpha=0.4)
    for name, pts in paths.items():
        top.plot(*zip(*pts), lw=1.2, label=f"{name} (/tf, {len(pts)} steps)")
        top.plot(*pts[-1], "o", ms=4)
    top.set_aspect("equal", adjustable="datalim")
    top.set_title("/scene and /tf, seen from above (m)")
    top.legend(loc="upper right", fontsize=8)
    top.grid(alpha=0.3)

    frames = images.get(drone, [])
    if frames:
        m = frames[len(frames) // 2]
        cam.imshow(m.image(), cmap="gray", vmin=0, vmax=255)
        cam.set_title(f"/{drone}/camera at {m.log_time * 1e-9:.2f} s (frame {len(frames) // 2 + 1} of {len(frames)} kept)")
    else:
        cam.text(0.5, 0.5, "no camera frames", ha="center", va="center")
    cam.axis("off")

    rows = battery.get(drone, [])
    if rows:
        t, v, soc = zip(*rows)
        bat.plot(t, v, color="tab:blue", lw=0.8)
        bat.set_ylabel("voltage (V)", color="tab:blue")
        bat.set_xlabel("world time (s)")
        ax2 = bat.twinx()
        ax2.plot(t, [100 * s for s in soc], color="tab:red", lw=1)
        ax2.set_ylabel("SOC (%)", color="tab:red")
        bat.set_title(f"/{drone}/battery")
    fig.suptitle(f"{Path(a.mcap).name}, drawn from the MCAP file with Python (not a Foxglove screenshot)", fontsize=10)
    fig.savefig(out, dpi=90)
    print(out)


if __name__ == "__main__":
    main()
