"""Fixtures: the checkout's release binaries (built once if missing) and
small world files.  Every test talks to real world-server / cosim processes."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RELEASE = ROOT / "target" / "release"
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
    """world-server, sim-core and cosim of target/release (the test command
    builds them first; built here if they are missing)."""
    names = {"world-server": "world-server", "sim-core": "sim-core", "cosim": "scenarios"}
    missing = [pkg for exe, pkg in names.items() if not (RELEASE / exe).is_file()]
    if missing:
        _build(*missing)
    return {exe: RELEASE / exe for exe in names}


@pytest.fixture(autouse=True)
def _world_server_env(binaries, monkeypatch):
    # $COSIM_WORLD_SERVER, when set, picks another build to test.
    if not os.environ.get("COSIM_WORLD_SERVER"):
        monkeypatch.setenv("COSIM_WORLD_SERVER", str(binaries["world-server"]))
    monkeypatch.chdir(ROOT)


@pytest.fixture
def three_drone_world() -> Path:
    """Three drones 2 m apart with the radio (the example's world)."""
    return ROOT / "examples" / "python" / "three-drones.toml"
