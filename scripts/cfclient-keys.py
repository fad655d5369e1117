#!/usr/bin/env python3
"""Fly Bitcraze's cfclient with the keyboard: the keys typed in this
terminal pushed to cfclient's ZMQ input (docs/CFLIB.md, "cfclient flown
with the keyboard"; the key map in crazyflie_cosim/cfclient_keys.py).

    cosim run cflib-lab &                       # the simulated Crazyflie
    cfclient                                    # with "enable_zmq_input": true, connect to udp://127.0.0.1:19850
    scripts/cfclient-keys.py                    # t take off, arrows/wasd move, q/e turn, r/f up/down, l land, esc quit

    scripts/cfclient-keys.py --script "t@0, up@5:1.5, left@8:1, l@11"
                                                # scripted keys: KEY@START[:HOLD] (wall seconds; hold 0.35 s)

Runs with any Python that has pyzmq, else with cfclient's own venv
(target/cfclient-venv, made by scripts/test-all.sh), and imports the
checkout's python/src.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# This checkout's package first (an installed one may be another checkout's).
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python" / "src"))

from crazyflie_cosim.cfclient_keys import ZMQ_INPUT, CfclientKeys, Speeds, push  # noqa: E402
from crazyflie_cosim.lab.keys import Hold, ScriptedKeys, TerminalKeys  # noqa: E402

TAP_S = 0.35  # a scripted key without a hold: one terminal key press


def parse_script(text: str) -> list[Hold]:
    """``KEY@START[:HOLD]`` items separated by commas."""
    holds = []
    for item in filter(None, (i.strip() for i in text.split(","))):
        try:
            key, when = item.split("@")
            start, _, hold = when.partition(":")
            holds.append(Hold(float(start), key.strip().lower(), float(hold) if hold else TAP_S))
        except ValueError:
            raise ValueError(f"bad scripted key {item!r}: expected KEY@START[:HOLD], e.g. up@5:1.5") from None
    return holds


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--address", default=ZMQ_INPUT, help=f"cfclient's ZMQ input (default {ZMQ_INPUT})")
    ap.add_argument("--rate", type=float, default=50.0, help="messages per second (default 50)")
    ap.add_argument("--speed", type=float, default=0.3, help="horizontal speed, m/s (default 0.3)")
    ap.add_argument("--script", help="scripted keys instead of the terminal: KEY@START[:HOLD],...")
    ap.add_argument("--after", type=float, default=3.0,
                    help="with --script: seconds to go on pushing after its last key (default 3)")
    a = ap.parse_args()
    if not a.rate > 0 or not a.speed > 0:
        ap.error("--rate and --speed must be positive")
    speeds = Speeds(horizontal=a.speed)
    holds = None
    if a.script is not None:
        try:
            holds = parse_script(a.script)
        except ValueError as e:
            ap.error(str(e))
        if not holds:
            ap.error("--script has no keys")
    try:
        import zmq  # noqa: F401
    except ImportError:
        # cfclient's own venv has pyzmq: use it when this Python has none.
        venv_python = Path(__file__).resolve().parents[1] / "target" / "cfclient-venv" / "bin" / "python"
        if venv_python.is_file() and Path(sys.executable).resolve() != venv_python.resolve():
            os.execv(venv_python, [str(venv_python), __file__, *sys.argv[1:]])
        sys.exit("cfclient-keys: needs pyzmq: make cfclient's venv (python3 -m venv target/cfclient-venv && "
                 "target/cfclient-venv/bin/pip install cfclient==2026.8.1) or pip install pyzmq")
    if holds is not None:
        end = max(h.start_s + h.duration_s for h in holds) + a.after
        keys = ScriptedKeys(holds)
        pilot = CfclientKeys(keys, speeds)
        t0 = []

        def done() -> bool:
            import time

            if not t0:
                t0.append(time.monotonic())
            return keys.finished and not pilot.landing and time.monotonic() - t0[0] >= end

        def log(msg: dict) -> None:
            c = msg["ctrl"]
            state = "landing" if pilot.landing else ("flying" if pilot.flying else "motors off")
            print(f"{state:10} roll {c['roll']:+.2f} pitch {c['pitch']:+.2f} yaw {c['yaw']:+.0f} "
                  f"thrust {c['thrust']:.0f} target {pilot.target_height:.2f} m", flush=True)

        with pilot:
            push(pilot, a.address, a.rate, until=done, on_message=_every(log, int(a.rate)))
        return 0
    if not sys.stdin.isatty():
        sys.exit("cfclient-keys: reads the keys of an interactive terminal (or give --script)")
    print("t take off | arrows/wasd move | q/e turn | r/f up/down | space stop | l land | esc quit", flush=True)

    def status(msg: dict) -> None:
        state = "landing" if pilot.landing else ("flying" if pilot.flying else "motors off")
        print(f"\r{state:10} target height {pilot.target_height:.2f} m ", end="", flush=True)

    pilot = CfclientKeys(TerminalKeys(), speeds)
    try:
        with pilot:
            push(pilot, a.address, a.rate, on_message=_every(status, 5))
    except KeyboardInterrupt:
        pass
    print()
    return 0


def _every(f, n: int):
    """``f`` called on every ``n``-th message."""
    count = [0]

    def call(msg):
        if count[0] % max(1, n) == 0:
            f(msg)
        count[0] += 1

    return call


if __name__ == "__main__":
    sys.exit(main())
