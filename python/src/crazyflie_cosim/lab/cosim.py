"""Running the simulator for the lab (not part of the seed's API): a
``cosim run SCENARIO`` serving cflib's UDP link, started, waited for (the
drone answers the null packet once the world is up, as cflib's scan
probes) and finished, with its outputs' directory.

    with CosimRun("cflib-lab", port=19850, pace=4.0, out="out/lab") as run:
        with SyncCrazyflie(run.uris[0], cf=Crazyflie(rw_cache=None)) as scf:
            ...
    run.out   # trajectory.csv, summary.json, power.csv, crtp.jsonl ...
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

from ..server import find_checkout


class CosimError(RuntimeError):
    pass


def find_cosim() -> Path:
    """``$COSIM`` or the checkout's target/release/cosim or ``cosim`` on PATH."""
    env = os.environ.get("COSIM")
    if env:
        return Path(env)
    root = find_checkout()
    if root is not None and (root / "target" / "release" / "cosim").is_file():
        return root / "target" / "release" / "cosim"
    found = shutil.which("cosim")
    if found:
        return Path(found)
    raise CosimError("cosim not found: set $COSIM, build it (cargo build --release -p scenarios) or put it on PATH")


def wait_for_link(uri: str, timeout: float = 60.0) -> None:
    """Probe ``udp://HOST:PORT`` with CRTP's null packet until it answers."""
    host, port = uri.removeprefix("udp://").split(":")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(0.2)
        try:
            s.sendto(b"\xff", (host, int(port)))
            s.recv(64)
            return
        except OSError:
            time.sleep(0.2)
        finally:
            s.close()
    raise CosimError(f"{uri} never answered")


class CosimRun:
    """``cosim run scenario --set crtp=udp:HOST:PORT --set pace=PACE`` with
    ``drones`` links at PORT, PORT+1, …"""

    def __init__(self, scenario: str, port: int = 19850, pace: float = 1.0, drones: int = 1,
                 out: str | os.PathLike | None = None, idle_s: float = 2.0, host: str = "127.0.0.1",
                 extra: tuple[str, ...] = (), timeout_s: float = 600.0, quiet: bool = True):
        self.scenario = scenario
        self.uris = [f"udp://{host}:{port + i}" for i in range(drones)]
        root = find_checkout()
        self.out = (Path(out) if out is not None else Path("out") / scenario).resolve()
        cmd = [str(find_cosim()), "run", scenario, "--out", str(self.out), "--no-plots", "--no-build",
               "--timeout", str(int(timeout_s)),
               "--set", f"crtp=udp:{host}:{port}", "--set", f"pace={pace}", "--set", f"crtp_idle_s={idle_s}"]
        if quiet:
            cmd.append("--quiet")
        for e in extra:
            cmd += ["--set", e]
        self.cmd = cmd
        self.cwd = root
        self.proc: subprocess.Popen | None = None
        self.output = ""

    def __enter__(self) -> CosimRun:
        self.proc = subprocess.Popen(self.cmd, cwd=self.cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
        try:
            for uri in self.uris:
                wait_for_link(uri)
        except CosimError:
            self.kill()
            raise CosimError(f"{' '.join(self.cmd)}: no link; its output:\n{self.output}") from None
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is not None:
            self.kill()
            return
        self.finish()

    def finish(self, timeout: float = 120.0) -> Path:
        """Wait for the run to end (its links closed) and check it ended well."""
        assert self.proc is not None
        try:
            self.output, _ = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise CosimError(f"cosim run {self.scenario} did not end within {timeout} s") from None
        if self.proc.returncode != 0:
            raise CosimError(f"cosim run {self.scenario} failed ({self.proc.returncode}):\n{self.output}")
        return self.out

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.output, _ = self.proc.communicate()
