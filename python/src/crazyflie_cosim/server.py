"""Start and stop a world-server process (DESIGN.md §15).

The binary is ``$COSIM_WORLD_SERVER``, else the checkout's
``target/release/world-server`` (searched upwards from the working directory
and from this package's files), else ``world-server`` on ``PATH``.  Each
server listens on a private UNIX socket in a fresh 0700 directory; stopping
it STOPs nothing by itself (the client does that) but waits for the process,
terminates it if it lingers, and removes the directory.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

from .client import Endpoint

ENV_BINARY = "COSIM_WORLD_SERVER"


class WorldServerError(RuntimeError):
    """world-server could not be found, did not start, or failed."""


def _checkout_roots() -> Iterable[Path]:
    seen = set()
    for start in (Path.cwd(), Path(__file__).resolve().parent):
        for d in (start, *start.parents):
            if d not in seen:
                seen.add(d)
                yield d


def find_checkout() -> Path | None:
    """The crazyflie-cosim checkout around the working directory or this
    package (a directory with ``scenarios/worlds`` and ``world-server``)."""
    for d in _checkout_roots():
        if (d / "scenarios" / "worlds").is_dir() and (d / "world-server").is_dir():
            return d
    return None


def find_world_server() -> Path:
    """The world-server binary to run (see the module's documentation)."""
    env = os.environ.get(ENV_BINARY)
    if env:
        path = Path(env)
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise WorldServerError(f"${ENV_BINARY} = {env} is not an executable file")
        return path
    for d in _checkout_roots():
        path = d / "target" / "release" / "world-server"
        if path.is_file() and os.access(path, os.X_OK):
            return path
    found = shutil.which("world-server")
    if found:
        return Path(found)
    raise WorldServerError(
        f"world-server not found: set ${ENV_BINARY}, build it in the checkout "
        "(cargo build --release -p world-server) or put it on PATH"
    )


def default_world() -> Path:
    """The thesis's 10-gate course (``scenarios/worlds/thesis-course.toml``)."""
    root = find_checkout()
    if root is None:
        raise WorldServerError(
            "the thesis course is in the checkout's scenarios/worlds/, which was not found "
            "from the working directory: pass a world file"
        )
    return root / "scenarios" / "worlds" / "thesis-course.toml"


class WorldServer:
    """One world-server process on a private socket.

    >>> with WorldServer(world="scenarios/worlds/swarm-hover-2.toml") as srv:
    ...     world = World.connect(srv.endpoint, ["d1", "d2"])
    """

    def __init__(
        self,
        world: str | os.PathLike | None = None,
        *,
        timestep_ms: int = 32,
        binary: str | os.PathLike | None = None,
        trace: str | os.PathLike | None = None,
        trajectory: str | os.PathLike | None = None,
        connect_timeout_s: float = 60.0,
        busy_poll_us: int = 0,
        extra_args: Sequence[str] = (),
        start_timeout_s: float = 30.0,
    ):
        self.binary = Path(binary) if binary else find_world_server()
        self.world = Path(world) if world is not None else None
        if self.world is not None and not self.world.is_file():
            raise WorldServerError(f"world file {self.world} does not exist")
        self._dir = Path(tempfile.mkdtemp(prefix="cosim-world-"))  # mode 0700
        self.socket_path = self._dir / "world.sock"
        self.log_path = self._dir / "world-server.log"
        args = [str(self.binary), "--socket", str(self.socket_path), "--timestep", str(int(timestep_ms))]
        args += ["--connect-timeout", str(connect_timeout_s)]
        # A Python client answers slowly: the server's default busy-polling
        # (200 us, docs/COSIM.md "Performance") would only burn a core.
        args += ["--busy-poll-us", str(int(busy_poll_us))]
        if self.world is not None:
            args += ["--world", str(self.world)]
        if trace is not None:
            args += ["--trace", str(trace)]
        if trajectory is not None:
            args += ["--trajectory", str(trajectory)]
        args += list(extra_args)
        self.args = args
        self._log = open(self.log_path, "wb")
        env = dict(os.environ)
        env.setdefault("RUST_LOG", "warn")
        try:
            self.process = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=self._log, stderr=self._log, env=env)
        except OSError as e:
            self._cleanup()
            raise WorldServerError(f"cannot start {self.binary}: {e}") from None
        self._wait_listening(start_timeout_s)

    def _wait_listening(self, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not self.socket_path.exists():
            if self.process.poll() is not None:
                msg = self._failure("exited before listening")
                self._cleanup()
                raise WorldServerError(msg)
            if time.monotonic() > deadline:
                self.stop(timeout_s=1.0)
                raise WorldServerError(f"world-server did not listen within {timeout_s} s")
            time.sleep(0.005)

    def _failure(self, what: str) -> str:
        self._log.flush()
        try:
            lines = self.log_path.read_text(errors="replace").strip().splitlines()
        except OSError:
            lines = []
        # clap ends its errors with a "For more information" line: the
        # error line itself says why.
        errors = [ln for ln in lines if "error" in ln.lower()]
        tail = errors[-1] if errors else lines[-1] if lines else "(no output)"
        return f"world-server {what} (status {self.process.returncode}): {tail}"

    @property
    def endpoint(self) -> Endpoint:
        return Endpoint("unix", path=str(self.socket_path))

    @property
    def log(self) -> str:
        """What the server printed so far."""
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def wait(self, timeout_s: float | None = None) -> int:
        """The exit status once the server exits (after the last STOP)."""
        return self.process.wait(timeout_s)

    def stop(self, timeout_s: float = 5.0) -> int:
        """Wait up to ``timeout_s`` for the process to exit, then SIGTERM it
        (and SIGKILL it after as long again); remove the socket's directory.
        Returns the exit status (negative: the signal that ended it)."""
        if self.process.poll() is None:
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.process.send_signal(signal.SIGTERM)
                try:
                    self.process.wait(timeout_s)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()
        self._cleanup()
        return self.process.returncode

    def kill(self) -> None:
        """End the server at once (an episode abandoned mid-flight)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._cleanup()

    def _cleanup(self) -> None:
        if not self._log.closed:
            self._log.close()
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> WorldServer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def __del__(self):
        proc = getattr(self, "process", None)
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait()
