"""`pip install ./python` into a fresh venv works, and the installed package
(the client is standard library only; the readers' one dependency is
zstandard) flies a drone."""

import os
import subprocess
import venv

from conftest import ROOT

SCRIPT = """
from crazyflie_cosim import World, WorldServer
with WorldServer() as srv, World.connect(srv.endpoint) as w:
    d = w["cf1"]
    d.set_velocity(1.0, 1.0, 1.0, 1.0)
    print(d.state().time_s, w.stop()["cf1"].time_s > 2.032)
"""


def test_pip_install_into_a_fresh_venv(tmp_path, binaries):
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    # What a user types (pip fetches setuptools into its build environment).
    r = subprocess.run(
        [str(py), "-m", "pip", "install", "--quiet", str(ROOT / "python")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, f"pip install ./python failed (it needs PyPI for setuptools):\n{r.stderr}"
    env = dict(os.environ, COSIM_WORLD_SERVER=str(binaries["world-server"]))
    env.pop("PYTHONPATH", None)
    out = subprocess.run([str(py), "-c", SCRIPT], check=True, capture_output=True, text=True, cwd=ROOT, env=env)
    assert out.stdout.split() == ["2.032", "True"]
    # The installed copy, not the checkout's.
    where = subprocess.run(
        [str(py), "-c", "import crazyflie_cosim; print(crazyflie_cosim.__file__)"],
        check=True, capture_output=True, text=True, cwd=tmp_path,
    ).stdout  # fmt: skip
    assert str(env_dir) in where
