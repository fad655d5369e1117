"""cflib flies the simulated Crazyflie over its UDP link (DESIGN.md §17,
docs/CFLIB.md).  Each test runs `cosim run cflib-lab` (or `cflib-swarm`)
with the STM32 serving CRTP on its own port, flies it with Bitcraze's
cflib from PyPI the way cflib's public examples do (their calls, their
constants; only the URI and a time budget in place of an interactive
loop differ), and checks what cflib printed against the world's
trajectory.

Pacing: cflib's MotionCommander times its moves with `time.sleep`, so its
distances are only right at `pace=1`; logging, the Multi-ranger loop and
the high-level commander (whose durations are the drone's own time) run at
`pace=4`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import socket
import subprocess
import time
from pathlib import Path

import pytest

cflib = pytest.importorskip("cflib")
import cflib.crtp  # noqa: E402
from cflib.crazyflie import Crazyflie  # noqa: E402
from cflib.crazyflie.log import LogConfig  # noqa: E402
from cflib.crazyflie.syncCrazyflie import SyncCrazyflie  # noqa: E402
from cflib.crazyflie.syncLogger import SyncLogger  # noqa: E402
from crazyflie_cosim.lab.cosim import CosimError  # noqa: E402
from crazyflie_cosim.lab.cosim import wait_for_link as probe  # noqa: E402
from crazyflie_cosim.outputs import read_series_bytes  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
# Ports above cflib's scan range (19850-19859), one block per test, so a
# test never talks to another's drone.
BASE_PORT = 19870


def _free(port: int) -> bool:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("127.0.0.1", port))
        return True
    except OSError:
        return False
    finally:
        s.close()


class Lab:
    """A `cosim run` serving CRTP; `finish()` waits for it to end."""

    def __init__(self, binaries, tmp: Path, scenario: str, port: int, pace: float,
                 idle_s: float = 2.0, extra: tuple[str, ...] = ()):
        assert _free(port), f"UDP port {port} is taken"
        self.out = tmp / scenario
        self.uri = f"udp://127.0.0.1:{port}"
        cmd = [str(binaries["cosim"]), "run", scenario, "--out", str(self.out),
               "--no-plots", "--quiet", "--no-build", "--timeout", "120",
               "--set", f"crtp=udp:127.0.0.1:{port}", "--set", f"pace={pace}",
               "--set", f"crtp_idle_s={idle_s}", *[a for e in extra for a in ("--set", e)]]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)

    def finish(self, timeout: float = 60) -> Path:
        out, _ = self.proc.communicate(timeout=timeout)
        assert self.proc.returncode == 0, out
        return self.out

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


def wait_for_link(uri: str, timeout: float = 30.0):
    """The drone answers only once the world is up and EXT_CRTP runs: probe
    with the null packet as cflib's UDP scan does."""
    try:
        probe(uri, timeout)
    except CosimError as e:
        pytest.fail(str(e))


@pytest.fixture
def lab(binaries, tmp_path):
    labs = []

    def start(*args, **kw):
        lab = Lab(binaries, tmp_path, *args, **kw)
        labs.append(lab)
        wait_for_link(lab.uri)
        return lab

    cflib.crtp.init_drivers()
    yield start
    for lab in labs:
        lab.kill()


def trajectory(out: Path, drone: str | None = None) -> list[dict[str, float]]:
    # Either form (trajectory.csv.zst by default).
    rows = list(csv.DictReader(io.StringIO(read_series_bytes(out / "trajectory.csv").decode())))
    if drone is not None:
        rows = [r for r in rows if r["drone"] == drone]
    return [{k: float(v) for k, v in r.items() if k != "drone"} for r in rows]


def at(rows, t_ms: float) -> dict[str, float]:
    """The world's state at (the step ending at or just before) t_ms."""
    return min(rows, key=lambda r: abs(r["time_ms"] - t_ms))


def test_motion_commander_step_by_step_flies_its_distances(lab):
    """cflib's sbs_motion_commander (move_linear_simple): take off to 0.5 m,
    forward 0.5 m, turn 180°, forward 0.5 m, land; at pace 1 the world's
    drone flies those distances."""
    from cflib.positioning.motion_commander import MotionCommander

    lab_run = lab("cflib-lab", BASE_PORT, pace=1.0, idle_s=1.0)
    logged = []
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        assert scf.cf.param.get_value("deck.bcFlow2") == "1"
        logconf = LogConfig(name="Position", period_in_ms=10)
        logconf.add_variable("stateEstimate.x", "float")
        logconf.add_variable("stateEstimate.y", "float")
        scf.cf.log.add_config(logconf)
        logconf.data_received_cb.add_callback(
            lambda ts, data, _: logged.append((ts, data["stateEstimate.x"], data["stateEstimate.y"])))
        logconf.start()
        with MotionCommander(scf, default_height=0.5) as mc:
            time.sleep(1)
            mc.forward(0.5)
            time.sleep(1)
            mc.turn_left(180)
            time.sleep(1)
            mc.forward(0.5)
            time.sleep(1)
        logconf.stop()
    out = lab_run.finish()
    rows = trajectory(out)
    top = max(r["z"] for r in rows)
    assert 0.4 < top < 0.65, top
    far = max(r["x"] for r in rows)
    # From x = 0.5 m, 0.5 m forward, and back after the turn; the wall
    # clock's jitter (the sleeps, the 10 Hz set-points) allows some slack.
    assert 0.85 < far < 1.2, far
    assert abs(rows[-1]["x"] - 0.5) < 0.3, rows[-1]
    assert rows[-1]["z"] < 0.05
    # What cflib printed is the world's drone at the log's timestamp (the
    # platform's ms; the world's time is the platform's in this lab).
    assert len(logged) > 50
    for ts, x, y in logged[::10]:
        r = at(rows, ts)
        assert abs(r["x"] - x) < 0.02 and abs(r["y"] - y) < 0.02, (ts, x, y, r)


def test_motion_commander_takes_off_holds_and_lands_as_a_crazyflie(lab):
    """The firmware's flight stack (`stabilizer.controller = pid`,
    docs/CFLIB.md): over cflib its parameters have the firmware's names and
    the Crazyflie 2.x's defaults; MotionCommander's take-off holds 0.5 m two
    seconds after `take_off()` returns, 0.5 m forward, and the landing
    touches down without a collision, tipping or sliding, motors off."""
    from cflib.positioning.motion_commander import MotionCommander

    lab_run = lab("cflib-lab", BASE_PORT + 9, pace=1.0, idle_s=1.0)
    z = []
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        # platform_defaults_cf2.h
        for name, value in [("posCtlPid.xKp", 2.0), ("posCtlPid.zKp", 2.0),
                            ("posCtlPid.zKi", 0.5), ("posCtlPid.thrustBase", 36000),
                            ("velCtlPid.vxKp", 25.0), ("velCtlPid.vzKp", 25.0),
                            ("velCtlPid.vzKi", 15.0), ("pid_attitude.roll_kp", 6.0),
                            ("pid_attitude.yaw_kd", 0.35), ("pid_rate.roll_kp", 250.0),
                            ("pid_rate.pitch_ki", 500.0), ("pid_rate.yaw_kp", 120.0)]:
            assert float(scf.cf.param.get_value(name)) == pytest.approx(value), name
        logconf = LogConfig(name="Height", period_in_ms=20)
        logconf.add_variable("stateEstimate.z", "float")
        scf.cf.log.add_config(logconf)
        logconf.data_received_cb.add_callback(lambda ts, d, _: z.append(d["stateEstimate.z"]))
        logconf.start()
        with MotionCommander(scf, default_height=0.5) as mc:
            time.sleep(2)
            held = z[-1]
            mc.forward(0.5)
            time.sleep(1)
        logconf.stop()
    out = lab_run.finish()
    assert 0.45 <= held <= 0.55, held
    rows = trajectory(out)
    assert rows[-1]["collisions"] == 0
    airborne = [i for i, r in enumerate(rows) if r["z"] > 0.03]
    landed = rows[airborne[-1] + 1:]
    assert landed, "the drone never came down"
    start, end = landed[0], landed[-1]
    # From x = 0.5 m, 0.5 m forward; then it stays where it came down.
    assert abs(end["x"] - 1.0) < 0.1, end
    assert math.hypot(end["x"] - start["x"], end["y"] - start["y"]) < 0.02, (start, end)
    assert max(max(abs(r["roll"]), abs(r["pitch"])) for r in landed) < 0.1
    assert all(end[f"w{i}"] == 0.0 for i in range(1, 5)), end


def test_logging_step_by_step_matches_the_world(lab):
    """cflib's sbs_connect_log_param: a synchronous log of the stabilizer,
    the asynchronous one, a parameter read and written."""
    lab_run = lab("cflib-lab", BASE_PORT + 1, pace=4.0)
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        lg = LogConfig(name="Stabilizer", period_in_ms=10)
        for v in ("stabilizer.roll", "stabilizer.pitch", "stabilizer.yaw",
                  "stateEstimate.z", "pm.vbat", "pm.batteryLevel"):
            lg.add_variable(v, "float" if not v.endswith("Level") else "uint8_t")
        with SyncLogger(scf, lg) as logger:
            for n, (ts, data, _) in enumerate(logger):
                print(f"[{ts}][{lg.name}]: {data}")
                if n == 20:
                    break
        # The step-by-step's parameter: the attitude loop's kd (0 in the
        # firmware's defaults for the Crazyflie 2.x), written and read back.
        cf = scf.cf
        assert float(cf.param.get_value("pid_attitude.pitch_kd")) == 0.0
        cf.param.set_value("pid_attitude.pitch_kd", 0.15)
        time.sleep(0.5)
        assert float(cf.param.get_value("pid_attitude.pitch_kd")) == pytest.approx(0.15)
        cf.param.set_value("pid_attitude.pitch_kd", 0.0)
        time.sleep(0.2)
    out = lab_run.finish()
    rows = trajectory(out)
    # On the ground: z is the world's, yaw its heading (0), the battery
    # full (the lab's LiPol 250 at 100 %: 4.2 V open circuit).
    assert abs(data["stateEstimate.z"] - at(rows, ts)["z"]) < 1e-4
    assert abs(data["stabilizer.yaw"] - math.degrees(at(rows, ts)["yaw"])) < 0.5
    assert 3.9 < data["pm.vbat"] <= 4.25 and data["pm.batteryLevel"] >= 98
    power = list(csv.DictReader(io.StringIO(read_series_bytes(out / "power.csv").decode())))
    assert power, "power.csv is written"


def test_multiranger_push_moves_away_from_the_wall(lab, tmp_path):
    """cflib's multiranger_push: hover at 0.3 m and move away from whatever
    comes within 0.2 m; the drone starts 0.12 m from the room's y = 0 wall
    (on its right) and is pushed off it by the wall's range alone."""
    from cflib.positioning.motion_commander import MotionCommander
    from cflib.utils.multiranger import Multiranger

    room = (ROOT / "scenarios" / "worlds" / "seed004-room.toml").read_text()
    world = tmp_path / "room-near-wall.toml"
    world.write_text(room.replace("position = [0.5, 0.5, 0.015]", "position = [1.0, 0.15, 0.015]"))
    lab_run = lab("cflib-lab", BASE_PORT + 2, pace=4.0, extra=(f"world={world}",))
    min_distance, velocity = 0.2, 0.5
    seen = []
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        with MotionCommander(scf, default_height=0.3) as mc:
            with Multiranger(scf) as mr:
                end = time.time() + 3.0  # the example loops until a hand is over it
                while time.time() < end:
                    vx = vy = 0.0
                    close = lambda r: r is not None and r < min_distance  # noqa: E731
                    if close(mr.front):
                        vx -= velocity
                    if close(mr.back):
                        vx += velocity
                    if close(mr.left):
                        vy -= velocity
                    if close(mr.right):
                        vy += velocity
                    seen.append(mr.right)
                    mc.start_linear_motion(vx, vy, 0)
                    time.sleep(0.1)
    out = lab_run.finish()
    rows = trajectory(out)
    assert any(r is not None and r < min_distance for r in seen), seen
    flying = [r for r in rows if r["z"] > 0.2]
    assert flying and max(r["y"] for r in flying) > 0.2, max(r["y"] for r in flying)
    # No contact with the wall while the ranges steer it. The landing that
    # MotionCommander's exit makes, wherever the drone then is (within
    # 0.1 m of the wall at times), is not this example's: its motors stop
    # 5 cm up and the touchdown can slide it into the wall.
    assert max(r["collisions"] for r in flying) == 0


def test_swarm_takes_off_and_lands_three_drones(binaries, tmp_path):
    """cflib's Swarm with the high-level commander (its swarm examples'
    take-off and land): three drones take off to 0.5 m in parallel and land.
    The example waits in wall time between the commands, and three paced
    platforms on a busy machine may run slower than 4x the wall clock
    (pacing only holds a step back, it cannot hurry one): pace 1."""
    from cflib.crazyflie.swarm import CachedCfFactory, Swarm

    cflib.crtp.init_drivers()
    port = BASE_PORT + 4
    lab_run = Lab(binaries, tmp_path, "cflib-swarm", port, pace=1.0, idle_s=1.0)
    try:
        uris = [f"udp://127.0.0.1:{port + i}" for i in range(3)]
        for u in uris:
            wait_for_link(u)

        def take_off_land(scf):
            hl = scf.cf.high_level_commander
            hl.takeoff(0.5, 2.0)
            # The world's motors need about 2 s from standstill to hover
            # speed (docs/CFLIB.md): the drone reaches 0.5 m ~2 s after the
            # plan does.
            time.sleep(4.5)
            hl.land(0.0, 2.0)
            time.sleep(2.5)
            hl.stop()

        with Swarm(uris, factory=CachedCfFactory(rw_cache=str(tmp_path / "cache"))) as swarm:
            positions = swarm.get_estimated_positions()
            swarm.parallel_safe(take_off_land)
        out = lab_run.finish()
    finally:
        lab_run.kill()
    for i, name in enumerate(["cf1", "cf2", "cf3"]):
        assert positions[uris[i]].x == pytest.approx(float(i), abs=0.01)
        rows = trajectory(out, name)
        top = max(r["z"] for r in rows)
        assert 0.4 < top < 0.6, (name, top)
        assert rows[-1]["z"] < 0.05 and max(r["collisions"] for r in rows) == 0


def test_replay_of_a_cflib_session_is_byte_identical(lab, binaries, tmp_path):
    """A recorded session (crtp.jsonl) replayed through the same scenario
    gives the same world trajectory and power log, byte for byte."""
    lab_run = lab("cflib-lab", BASE_PORT + 3, pace=4.0)
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        hl = scf.cf.high_level_commander
        hl.takeoff(0.4, 1.0)
        time.sleep(0.5)
        hl.go_to(0.3, 0.2, 0.0, 0.0, 1.0, relative=True)
        time.sleep(0.5)
        hl.land(0.0, 1.0)
        time.sleep(0.4)
    out = lab_run.finish()
    again = tmp_path / "replayed"
    p = subprocess.run(
        [str(binaries["cosim"]), "run", "cflib-lab", "--out", str(again), "--no-plots",
         "--quiet", "--no-build", "--set", f"crtp=replay:{out / 'crtp.jsonl'}",
         "--set", "crtp_idle_s=2"],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stdout + p.stderr
    rows = trajectory(out)
    assert max(r["x"] for r in rows) > 0.7  # the go-to flew
    for name in ("trajectory.csv", "power.csv"):
        assert read_series_bytes(out / name) == read_series_bytes(again / name), name


def test_console_lines_reach_cflib(lab):
    """The firmware's console (console.log) arrives at cflib's
    `console.receivedChar` (port 0), as from a Crazyflie's `consolePrintf`."""
    lab_run = lab("cflib-lab", BASE_PORT + 4, pace=4.0)
    text: list[str] = []
    cf = Crazyflie(rw_cache=None)
    cf.console.receivedChar.add_callback(text.append)
    with SyncCrazyflie(lab_run.uri, cf=cf):
        deadline = time.time() + 5
        while "serving the CRTP link" not in "".join(text) and time.time() < deadline:
            time.sleep(0.05)
    out = lab_run.finish()
    got = "".join(text)
    assert "[crtp] serving the CRTP link\n" in got, got
    assert got in (out / "console.log").read_text()


def _fly_square(uri: str, mocap: bool) -> list[float]:
    """A high-level square of 1 m at 0.5 m. The drone logs its estimate and
    the world's position (`world.x/y/z`: what a motion-capture system
    measures) in one block at 10 Hz; with `mocap` every world position is
    sent back with cflib's `send_extpos`. Returns the estimate's horizontal
    distance from the world's position at each sample above 0.3 m."""
    errors: list[float] = []
    with SyncCrazyflie(uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        conf = LogConfig("Mocap", 100)
        for v in ("world.x", "world.y", "world.z", "stateEstimate.x", "stateEstimate.y"):
            conf.add_variable(v, "float")

        def received(_t, d, _c):
            if mocap:
                cf.extpos.send_extpos(d["world.x"], d["world.y"], d["world.z"])
            if d["world.z"] > 0.3:
                errors.append(math.hypot(d["stateEstimate.x"] - d["world.x"],
                                         d["stateEstimate.y"] - d["world.y"]))

        conf.data_received_cb.add_callback(received)
        cf.log.add_config(conf)
        conf.start()
        hl = cf.high_level_commander
        hl.takeoff(0.5, 2.0)
        time.sleep(4.0 / 4)
        for dx, dy in ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)) * 2:
            hl.go_to(dx, dy, 0.0, 0.0, 2.0, relative=True)
            time.sleep(2.5 / 4)
        conf.stop()
        hl.land(0.0, 2.0)
        time.sleep(2.5 / 4)
    return errors


def test_external_positions_bound_the_flow_estimates_drift(lab):
    """Flow-deck dead reckoning drifts (seed 004's room: the flow is noisy
    and reads 5 % fast); the world's position sent back as external positions (cflib's
    `send_extpos`) is fused and keeps the estimate on the world's position."""
    drift = {}
    for i, mocap in enumerate((False, True)):
        lab_run = lab("cflib-lab", BASE_PORT + 5 + i, pace=4.0, idle_s=6.0,
                      extra=("stm32.position_source=flow",))
        errors = _fly_square(lab_run.uri, mocap)
        out = lab_run.finish()
        assert len(errors) > 100, len(errors)
        drift[mocap] = (max(errors), sum(errors) / len(errors), errors[-1])
        log = (out / "console.log").read_text()
        fused = re.search(r"external positions, (\d+) fused", log)
        assert fused and (int(fused.group(1)) > 100) == mocap, log
    print("estimate - world (max, mean, last; m): without external positions "
          f"{drift[False]}, with {drift[True]}")
    # Without them the estimate strays by centimetres over the 8 m flown
    # (the firmware's stack at 2 ms: 2-3 cm; the thesis's controller at
    # 32 ms strayed more than 0.1 m); with them it stays on the world's
    # position, several times closer.
    assert drift[False][0] > 0.015, drift
    assert drift[True][0] < 0.1, drift
    assert drift[True][2] < drift[False][2] / 4, drift


# The firmware's velocity controller limits the demanded roll and pitch to
# 20° (`PID_VEL_ROLL_MAX`, `position_controller_pid.c`); the CRTP position
# loop does the same (sim-core crtp::TILT_LIMIT).
TILT_LIMIT = math.radians(20.0)


def test_cfclient_buttons_fly_upright(lab):
    """What cfclient's command-based flight buttons send (cfclient's
    `FlightTab._flight_command`: 0.5 m at 0.5 m/s): take off 0.5 m in 1 s,
    forward, back, left, right 0.5 m in 1 s each (`go_to`, relative),
    *Land* at 0.5 m/s. The drone flies every move with |roll|, |pitch|
    within the firmware's 20° (before the fix the first move flipped it),
    reaches each goal, hits nothing, and ends on the floor upright (before
    the landing's touchdown, docs/CFLIB.md "cfclient's Land", its bounce
    tipped it over in most sessions)."""
    pace = 2.0
    lab_run = lab("cflib-lab", BASE_PORT + 7, pace=pace)
    z = [0.0]
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        cf = scf.cf
        conf = LogConfig("Pose", 50)  # cfclient's pose logger
        conf.add_variable("stateEstimate.z", "float")
        conf.data_received_cb.add_callback(lambda _t, d, _c: z.__setitem__(0, d["stateEstimate.z"]))
        cf.log.add_config(conf)
        conf.start()
        cf.param.set_value("commander.enHighLevel", "1")
        hl = cf.high_level_commander
        hl.takeoff(z[0] + 0.5, 1.0)
        time.sleep(3.0 / pace)
        for dx, dy in ((0.5, 0.0), (-0.5, 0.0), (0.0, 0.5), (0.0, -0.5)):
            hl.go_to(dx, dy, 0.0, 0.0, 1.0, relative=True)
            time.sleep(3.0 / pace)
        hl.land(0.0, z[0] / 0.5)
        time.sleep(4.0 / pace)
        conf.stop()
    rows = trajectory(lab_run.finish())
    start = rows[0]
    # The flight: up to the landing's descent through 0.35 m.
    last_high = max(i for i, r in enumerate(rows) if r["z"] > 0.35)
    flight = rows[: last_high + 1]
    tilt = max(max(abs(r["roll"]), abs(r["pitch"])) for r in flight)
    print(f"largest tilt in flight {tilt:.3f} rad; end {rows[-1]}")
    assert tilt < TILT_LIMIT, tilt
    # Each move reached its goal (forward +x, back, left +y, back).
    assert max(r["x"] for r in flight) - start["x"] > 0.4
    assert max(r["y"] for r in flight) - start["y"] > 0.4
    assert max(r["x"] for r in flight) - start["x"] < 0.55
    assert max(r["y"] for r in flight) - start["y"] < 0.55
    end = rows[-1]
    assert max(r["collisions"] for r in rows) == 0
    assert end["z"] < 0.03, end
    # Upright: level on the floor, and never tipped far on the way down.
    after = max(max(abs(r["roll"]), abs(r["pitch"])) for r in rows[last_high:])
    print(f"largest tilt from 0.35 m down {after:.3f} rad")
    assert max(abs(end["roll"]), abs(end["pitch"])) < 0.05, end
    assert after < TILT_LIMIT, after


def test_deck_memories_list_the_drones_decks(lab):
    """cflib reads the decks' 1-wire memories (port 4) at connection: one
    per deck of cflib-lab's drone (the `deck.bc…` parameters at 1: Flow
    deck v2, Multi-ranger and the AI deck of its platform), their
    EEPROMs valid (cflib checks both CRCs) with the firmware drivers' names
    and Bitcraze's vendor and product ids (docs/CFLIB.md, "Deck
    memories")."""
    from cflib.crazyflie.mem import MemoryElement

    lab_run = lab("cflib-lab", BASE_PORT + 8, pace=4.0)
    with SyncCrazyflie(lab_run.uri, cf=Crazyflie(rw_cache=None)) as scf:
        mems = scf.cf.mem.get_mems(MemoryElement.TYPE_1W)
        deadline = time.time() + 5
        while not (all(m.valid for m in mems) and scf.cf.param.is_updated) and time.time() < deadline:
            time.sleep(0.05)
        decks = {m.elements.get("Board name"): (m.vid, m.pid, m.size, m.valid) for m in mems}
        present = {k for k, v in scf.cf.param.values["deck"].items() if int(v) == 1}
        # What cfclient's About box formats before it lists the decks.
        firmware = {k: int(v) for k, v in scf.cf.param.values["firmware"].items()}
    lab_run.finish()
    assert firmware == {"revision0": 0, "revision1": 0, "modified": 1}
    print(decks)
    # The firmware drivers' ids (flowdeck_v1v2.c, multiranger.c, aideck.c).
    ids = {"bcFlow2": 0x0F, "bcMultiranger": 0x0C, "bcAI": 0x12}
    assert {"bcFlow2", "bcMultiranger"} <= present
    assert decks == {name: (0xBC, ids[name], 112, True) for name in present}
