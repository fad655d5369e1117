"""cfclient flown with the keyboard (docs/CFLIB.md, "cfclient flown with
the keyboard"): the key map against cfclient's own input code, and the
whole chain — scripted keys pushed over ZMQ to a real cfclient under Xvfb,
connected to `cosim run cflib-lab` — flying the drone up, along and down,
upright at the end."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from crazyflie_cosim.cfclient_keys import (
    HOVER_FLOOR_M, HOVER_START_M, THRUST_MID, ZMQ_DEVICE, CfclientKeys, Speeds)
from crazyflie_cosim.lab.keys import Hold, ScriptedKeys
from crazyflie_cosim.outputs import read_series_bytes

ROOT = Path(__file__).resolve().parents[2]
# cfclient's own venv, as scripts/test-all.sh makes it.
CFCLIENT = Path(os.environ.get("CFCLIENT", ROOT / "target" / "cfclient-venv" / "bin" / "cfclient"))


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_keys_become_cfclients_hover_mode_input():
    """Take off, forward + left, climb, turn, land: the ctrl values are
    what cfclient's `JoystickReader.read_input` turns into the hover
    set-point asked (vx = pitch, vy = -roll, yaw rate = -yaw, vz =
    (thrust - 32767) / 32767) and the landing ends with the motors off."""
    clock = Clock()
    keys = ScriptedKeys([Hold(0.0, "t", 0.1), Hold(1.0, "up", 1.0), Hold(1.0, "a", 1.0),
                         Hold(3.0, "r", 1.0), Hold(5.0, "q", 0.5), Hold(6.0, "l", 0.1)], clock=clock)
    pilot = CfclientKeys(keys, Speeds(horizontal=0.3, yaw=45.0, climb=0.3, land=0.3), clock=clock)
    seen = {}
    with pilot:
        while clock.t < 12.0:
            seen[round(clock.t, 2)] = (pilot.ctrl(), pilot.target_height, pilot.landing)
            clock.t += 0.01
    off = {"roll": 0.0, "pitch": 0.0, "yaw": 0.0, "thrust": 0.0, "assistedControl": False}
    assert seen[0.0][0]["assistedControl"] is True  # t: cfclient's Hover mode, from 0.4 m
    assert seen[0.0][1] == pytest.approx(HOVER_START_M)
    c = seen[1.5][0]
    vx, vy, vz = c["pitch"], -c["roll"], (c["thrust"] - THRUST_MID) / THRUST_MID
    assert (vx, vy, vz) == pytest.approx((0.3, 0.3, 0.0))  # forward and left
    c = seen[3.5][0]
    assert (c["thrust"] - THRUST_MID) / THRUST_MID == pytest.approx(0.3)  # r: climbing
    assert seen[4.5][1] == pytest.approx(HOVER_START_M + 0.3, abs=0.02)  # 1 s at 0.3 m/s
    assert -seen[5.2][0]["yaw"] == pytest.approx(45.0)  # q: turn left
    # l: down at 0.3 m/s to cfclient's floor, then (as long again, at least
    # 1 s) the motors off.
    assert seen[6.5][2] and (seen[6.5][0]["thrust"] - THRUST_MID) / THRUST_MID == pytest.approx(-0.3)
    assert seen[8.0][1] == pytest.approx(HOVER_FLOOR_M)
    assert seen[11.99][0] == off and not seen[11.99][2]
    assert pilot.message()["ctrl"] == off


def test_cfclient_script_rejects_a_bad_script():
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "cfclient-keys.py"), "--script", "up5"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode != 0 and "KEY@START" in p.stderr


def _need_cfclient():
    if not CFCLIENT.is_file():
        pytest.skip(f"cfclient not installed at {CFCLIENT} (docs/CFLIB.md, 'cfclient')")
    for tool in ("Xvfb", "xdotool"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not installed (docs/CFLIB.md, 'cfclient')")


def test_cfclient_flown_by_keys_takes_off_moves_and_lands_upright(binaries, tmp_path):
    """Real processes end to end: `cosim run cflib-lab`, cfclient under Xvfb
    with its ZMQ input device selected and the simulator's URI, connected
    (xdotool clicks *Connect*), and scripts/cfclient-keys.py pushing
    scripted keys: take off, forward 1.5 s, left 1 s, land. The world's
    trajectory shows the take-off to cfclient's 0.4 m, the moves, and the
    drone back on the floor, upright."""
    _need_cfclient()
    port = 19858  # in cfclient's scan range (19850-19859), not the other tests'
    out = tmp_path / "run"
    home = tmp_path / "home"
    (home / ".config" / "cfclient").mkdir(parents=True)
    (home / ".config" / "cfclient" / "config.json").write_text(json.dumps({
        "link_uri": f"udp://127.0.0.1:{port}", "open_tabs": "Flight Control",
        "window_size": [1600, 1000], "enable_zmq_input": True, "input_device": ZMQ_DEVICE,
        "assistedControl": 3}))
    procs = []
    # A display nobody uses (X servers hold /tmp/.X<n>-lock).
    display = next(f":{n}" for n in range(78, 178) if not Path(f"/tmp/.X{n}-lock").exists())
    try:
        procs.append(subprocess.Popen(["Xvfb", display, "-screen", "0", "1600x1000x24"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        lab = subprocess.Popen(
            [str(binaries["cosim"]), "run", "cflib-lab", "--out", str(out), "--no-plots", "--quiet",
             "--no-build", "--timeout", "120", "--set", f"crtp=udp:127.0.0.1:{port}",
             "--set", "crtp_idle_s=3"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(lab)
        env = dict(os.environ, HOME=str(home), DISPLAY=display, QT_QPA_PLATFORM="xcb")
        with open(tmp_path / "cfclient.log", "w") as log:
            procs.append(subprocess.Popen([str(CFCLIENT), "--debug", "info"], env=env, stdout=log,
                                          stderr=subprocess.STDOUT))
        deadline = time.time() + 40
        text = ""
        while "Adding device ZMQ@" not in text:
            if time.time() > deadline:
                pytest.fail("cfclient did not start its ZMQ input:\n" + text[-3000:])
            time.sleep(0.5)
            text = (tmp_path / "cfclient.log").read_text()
        time.sleep(3)
        subprocess.run(["xdotool", "mousemove", "304", "47", "click", "1"], env=env, check=True)  # Connect
        deadline = time.time() + 20
        while "Callback->Connected to" not in (tmp_path / "cfclient.log").read_text():
            if time.time() > deadline:
                pytest.fail("cfclient did not connect:\n" + (tmp_path / "cfclient.log").read_text()[-3000:])
            time.sleep(0.5)
        time.sleep(2)
        keys = subprocess.run(
            [str(CFCLIENT.parent / "python"), str(ROOT / "scripts" / "cfclient-keys.py"),
             "--script", "t@0, up@5:1.5, left@8:1, l@11", "--after", "2"],
            capture_output=True, text=True, timeout=60)
        assert keys.returncode == 0, keys.stdout + keys.stderr
        # cfclient disconnects when it is closed: the link goes idle, the run ends.
        procs[-1].terminate()
        procs[-1].wait(timeout=20)
        stdout, _ = lab.communicate(timeout=60)
        assert lab.returncode == 0, stdout
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.kill()
                p.wait()
    # Either form (trajectory.csv.zst by default).
    text = read_series_bytes(out / "trajectory.csv").decode()
    rows = [{k: float(v) for k, v in r.items() if k != "drone"} for r in csv.DictReader(io.StringIO(text))]
    start, end = rows[0], rows[-1]
    top = max(r["z"] for r in rows)
    dx = max(r["x"] for r in rows) - start["x"]
    dy = max(r["y"] for r in rows) - start["y"]
    tilt = max(max(abs(r["roll"]), abs(r["pitch"])) for r in rows if r["z"] > 0.25)
    print(f"top {top:.2f} m, forward {dx:.2f} m, left {dy:.2f} m, tilt in flight {tilt:.3f} rad, end {end}")
    assert 0.3 < top < 0.5, top  # cfclient's Hover mode: 0.4 m
    assert 0.25 < dx < 0.7, dx  # 1.5 s at 0.3 m/s forward
    assert 0.15 < dy < 0.5, dy  # 1 s at 0.3 m/s left
    assert tilt < math.radians(20), tilt
    assert end["z"] < 0.03 and max(abs(end["roll"]), abs(end["pitch"])) < 0.05, end
    assert max(r["collisions"] for r in rows) == 0
