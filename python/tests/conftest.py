"""Fixtures: the checkout's binaries (``$COSIM_BIN_DIR``, else the release
build, built once if missing) and small world files.  Every test talks to
real world-server / cosim processes."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RELEASE = ROOT / "target" / "release"
# The test command builds the binaries once, for the Rust and the Python
# tests alike, and names their directory here (the end-to-end tests read it
# too).
BIN_DIR = Path(os.environ["COSIM_BIN_DIR"]) if os.environ.get("COSIM_BIN_DIR") else RELEASE
sys.path.insert(0, str(ROOT / "python" / "src"))  # the tests run from a checkout


def _build(*packages: str) -> None:
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.fail("cargo is needed to build the release binaries the tests run")
    cmd = [cargo, "build", "--release", "--quiet"]
    for p in packages:
        cmd += ["-p", p]
    subprocess.run(cmd, cwd=ROOT, check=True)


@pytest.fixture(scope="session")
def binaries() -> dict[str, Path]:
    """world-server, sim-core and cosim of $COSIM_BIN_DIR, else of
    target/release (built here if they are missing)."""
    names = {"world-server": "world-server", "sim-core": "sim-core", "cosim": "scenarios"}
    missing = [pkg for exe, pkg in names.items() if not (BIN_DIR / exe).is_file()]
    if missing and BIN_DIR != RELEASE:
        pytest.fail(f"$COSIM_BIN_DIR={BIN_DIR} lacks {', '.join(missing)}")
    if missing:
        _build(*missing)
    return {exe: BIN_DIR / exe for exe in names}


@pytest.fixture(autouse=True)
def _world_server_env(binaries, monkeypatch):
    # $COSIM_WORLD_SERVER, when set, picks another build to test.
    if not os.environ.get("COSIM_WORLD_SERVER"):
        monkeypatch.setenv("COSIM_WORLD_SERVER", str(binaries["world-server"]))
    # Likewise $COSIM for the lab's launcher (crazyflie_cosim.lab.cosim).
    if not os.environ.get("COSIM"):
        monkeypatch.setenv("COSIM", str(binaries["cosim"]))
    monkeypatch.chdir(ROOT)


@pytest.fixture
def three_drone_world() -> Path:
    """Three drones 2 m apart with the radio (the example's world)."""
    return ROOT / "examples" / "python" / "three-drones.toml"
