#!/usr/bin/env python3
"""How well the world keeps to the wall clock under a cflib flight
(docs/CFLIB.md "Pacing", docs/DESIGN.md §20).

`fly` starts `cosim run cflib-lab` at a pace, flies it with Bitcraze's
cflib the way its MotionCommander example does (take off 0.5 m, a 0.5 m
square, a turn, land; cflib logging the estimate at 10 Hz meanwhile),
waits for the run to end and prints the run's `pacing` figures
(summary.json). With `--busy N` it keeps N CPU-bound processes running
during the flight (what `yes > /dev/null &` does), and ends them after.

`plot` draws, from the runs' `pacing.csv`, the world's time minus F x the
wall time since the first paced step (0: on time; below 0: behind the wall
clock) and each step's lag behind its deadline.

    scripts/pacing-flight.py fly --out OUT/idle [--pace 1] [--busy 2 [--apart]] [--port 19880]
    scripts/pacing-flight.py plot OUT/idle OUT/busy --png pacing.png

Needs cflib (`fly`) and matplotlib (`plot`), and the binaries built
(cargo build -p scenarios -p sim-core -p world-server).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def wait_for_link(port: int, timeout_s: float = 60.0) -> None:
    """Until the drone answers the null packet (cflib's scan probe)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.connect(("127.0.0.1", port))
    s.settimeout(0.3)
    until = time.time() + timeout_s
    while time.time() < until:
        try:
            s.send(b"\xff")
            if s.recv(64) == b"\xff":
                return
        except OSError:
            time.sleep(0.1)
    sys.exit(f"udp://127.0.0.1:{port} never answered")


def fly(args: argparse.Namespace) -> None:
    import cflib.crtp
    from cflib.crazyflie import Crazyflie
    from cflib.crazyflie.log import LogConfig
    from cflib.crazyflie.syncCrazyflie import SyncCrazyflie
    from cflib.positioning.motion_commander import MotionCommander

    target = os.environ.get("CARGO_TARGET_DIR", str(ROOT / "target"))
    cosim = Path(target) / args.profile / "cosim"
    out = Path(args.out)
    run = subprocess.Popen(
        [str(cosim), "run", "cflib-lab", "--out", str(out), "--no-plots", "--no-mcap",
         "--no-build", "--set", f"crtp=udp:127.0.0.1:{args.port}", "--set", f"pace={args.pace}",
         "--set", "crtp_idle_s=2"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    # In the flight's session, `yes` shares its scheduling group with the
    # simulator (Linux's autogroups: one a session, i.e. a terminal);
    # `--apart` gives each its own, as `yes` started in another terminal.
    busy = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL, start_new_session=args.apart)
            for _ in range(args.busy)]
    try:
        cflib.crtp.init_drivers()
        uri = f"udp://127.0.0.1:{args.port}"
        wait_for_link(args.port)
        scf = SyncCrazyflie(uri, cf=Crazyflie(rw_cache=None))
        with scf:
            est = LogConfig("Estimate", 100)
            for v in ("stateEstimate.x", "stateEstimate.y", "stateEstimate.z"):
                est.add_variable(v, "float")
            scf.cf.log.add_config(est)
            est.start()
            t0 = time.time()
            with MotionCommander(scf, default_height=0.5) as mc:
                time.sleep(1.0)
                mc.forward(0.5)
                mc.left(0.5)
                mc.back(0.5)
                mc.right(0.5)
                mc.turn_left(90)
                time.sleep(1.0)
            est.stop()
            print(f"flight: {time.time() - t0:.1f} s wall")
    finally:
        for b in busy:
            b.kill()
            b.wait()
    text, _ = run.communicate(timeout=120)
    if run.returncode != 0:
        sys.exit(text)
    summary = json.loads((out / "summary.json").read_text())
    print(json.dumps(summary.get("pacing"), indent=2))
    for line in text.splitlines():
        if "pacing" in line or "WARNING" in line:
            print(line)


def rows(run: Path) -> tuple[list[float], list[float], list[float]]:
    with open(run / "pacing.csv", newline="") as f:
        r = list(csv.DictReader(f))
    t = [float(x["platform_s"]) for x in r]
    wall = [float(x["wall_s"]) for x in r]
    lag = [float(x["lag_ms"]) for x in r]
    return t, wall, lag


def plot(args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7))
    runs = list(map(Path, args.runs))
    for i, run in enumerate(runs):
        pace = json.loads((run / "summary.json").read_text())["pacing"]
        t, wall, lag = rows(run)
        ahead = [(ti - t[0] - pace["pace"] * w) * 1e3 for ti, w in zip(t, wall)]
        label = (f"{run.name}: {pace['achieved_pace']:.4f}x of {pace['pace']}, "
                 f"worst lag {pace['worst_lag_ms']:.1f} ms")
        # The first run (the quiet one) drawn on top of the others.
        ax1.plot(wall, ahead, lw=0.8, label=label, zorder=len(runs) - i)
        lag.sort()
        share = [(k + 1) / len(lag) for k in range(len(lag))]
        ax2.step([max(x, 1e-3) for x in lag], share, where="post", lw=1.0, label=run.name)
    ax1.axhline(0.0, color="k", lw=0.5)
    ax1.set_ylabel("world - F x wall (ms)")
    ax1.set_xlabel("wall time since the first paced step (s)")
    ax1.set_title("A cflib flight at pace F: the world's time against the wall clock")
    ax1.legend(fontsize=8)
    ax2.set_xscale("log")
    ax2.set_xlabel("step lag behind its deadline (ms)")
    ax2.set_ylabel("share of steps with a lag <= x")
    ax2.axvline(100.0, color="k", lw=0.5, ls="--")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.png, dpi=90)
    print(args.png)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(required=True)
    f = sub.add_parser("fly")
    f.add_argument("--out", required=True)
    f.add_argument("--pace", type=float, default=1.0)
    f.add_argument("--busy", type=int, default=0)
    f.add_argument("--apart", action="store_true",
                   help="the busy processes in sessions of their own")
    f.add_argument("--port", type=int, default=19880)
    f.add_argument("--profile", default="debug")
    f.set_defaults(go=fly)
    q = sub.add_parser("plot")
    q.add_argument("runs", nargs="+")
    q.add_argument("--png", required=True)
    q.set_defaults(go=plot)
    a = p.parse_args()
    a.go(a)


if __name__ == "__main__":
    main()
