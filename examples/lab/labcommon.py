"""What the three guides' examples share: the command line, the simulator
run (``--launch``), the control loop's clock and the take-off and landing
that the student's code sends (the lab API never sends a set-point).

Every example flies a real Crazyflie too: ``--uri radio://0/80/2M`` and no
``--launch``.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python" / "src"))  # run from a checkout without installing

from crazyflie_cosim.lab.cosim import CosimRun  # noqa: E402


def parser(description: str, scenario: str, drones: int = 1, pace: float = 4.0) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--launch", action=argparse.BooleanOptionalAction, default=True,
                   help=f"start `cosim run {scenario}` for this flight (default); --no-launch: "
                        "fly what --uri points at (a running cosim, or a real Crazyflie)")
    p.add_argument("--scenario", default=scenario, help="the scenario --launch runs")
    p.add_argument("--uri", default="udp://127.0.0.1:19850",
                   help="the (first) drone's link; a swarm's next drones at the next ports")
    p.add_argument("--pace", type=float, default=pace,
                   help="the world's speed over the wall clock (cosim's pace; the control loop follows it)")
    p.add_argument("--out", type=Path, default=ROOT / "out" / "lab", help="outputs (cosim's and this script's)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="more cosim --set keys")
    p.set_defaults(drones=drones)
    return p


@contextlib.contextmanager
def simulator(args):
    """The cosim run serving the example's links (or nothing with --no-launch)."""
    if not args.launch:
        yield None
        return
    port = int(args.uri.rsplit(":", 1)[1])
    # The link closes after 10 s of the drone's time without a packet (a
    # script busy planning on a loaded machine may be silent a while).
    with CosimRun(args.scenario, port=port, pace=args.pace, drones=args.drones, out=args.out / "cosim",
                  idle_s=10.0, extra=tuple(args.set)) as run:
        yield run


def uris(args) -> list[str]:
    base, port = args.uri.rsplit(":", 1)
    if not args.uri.startswith("udp://"):
        return [args.uri]
    return [f"{base}:{int(port) + i}" for i in range(args.drones)]


class Clock:
    """The control loop's clock: ticks every ``period_s`` of the drone's
    time. With ``drone_time`` (a callable giving the drone's time in s, e.g.
    the log's timestamps, or None before the first) it follows the drone,
    so a world that lags its pace (a loaded machine) gets the same number
    of set-points per drone second; otherwise the wall clock, ``pace``
    times slower. ``now`` is the time since the start (s)."""

    def __init__(self, period_s: float = 0.1, pace: float = 1.0, drone_time=None):
        self.period = period_s
        self.pace = pace
        self.drone_time = drone_time
        self.t0 = time.monotonic()
        self.next = self.t0
        self.d0 = None
        self.d_next = None

    def _drone(self):
        t = self.drone_time() if self.drone_time else None
        if t is not None and self.d0 is None:
            self.d0 = t
            self.d_next = t
        return t

    @property
    def now(self) -> float:
        t = self._drone()
        if t is not None:
            return t - self.d0
        return (time.monotonic() - self.t0) * self.pace

    def tick(self) -> None:
        t = self._drone()
        if t is not None:
            self.d_next += self.period
            deadline = time.monotonic() + 10.0
            while (t := self._drone()) < self.d_next - 1e-6:
                if time.monotonic() > deadline:
                    raise ConnectionError("the drone's clock has stopped for 10 s: the link is lost")
                time.sleep(0.002)
            if t > self.d_next + self.period:
                self.d_next = t  # late: do not rush to catch up
            return
        self.next += self.period / self.pace
        wait = self.next - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        else:
            self.next = time.monotonic()

    def seconds(self, s: float) -> range:
        """Ticks in ``s`` seconds of the drone's time."""
        return range(max(1, round(s / self.period)))


def drone_clock(telemetry, pace: float, period_s: float = 0.1) -> Clock:
    """A Clock on the drone's time as a lab Telemetry logs it."""
    return Clock(period_s, pace, lambda: None if telemetry.t_ms is None else telemetry.t_ms / 1000.0)


def take_off(cf, clock: Clock, z: float = 0.3, seconds: float = 4.0) -> None:
    """Hover set-points at ``z`` for ``seconds`` (the motors spin up, the
    drone climbs and settles)."""
    for _ in clock.seconds(seconds):
        cf.commander.send_hover_setpoint(0.0, 0.0, 0.0, z)
        clock.tick()


def land(cf, clock: Clock, z: float = 0.3, seconds: float = 2.5) -> None:
    """Descend to 5 cm in ``seconds``, then stop the motors."""
    n = len(clock.seconds(seconds))
    for i in range(n):
        cf.commander.send_hover_setpoint(0.0, 0.0, 0.0, z + (0.05 - z) * (i + 1) / n)
        clock.tick()
    cf.commander.send_stop_setpoint()
    cf.commander.send_notify_setpoint_stop()
