"""The readers against a real run: one `cosim sweep` of one short-hop run
(a sweep's table and a run's outputs from one cosim invocation)."""

import json
import subprocess

import pytest

from crazyflie_cosim.outputs import OutputError, Run, Sweep, read_csv


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory, binaries):
    out = tmp_path_factory.mktemp("sweep")
    subprocess.run(
        [str(binaries["cosim"]), "sweep", "short-hop", "--param", "timestep_ms=32", "--jobs", "1", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return out


def test_the_sweep_table_and_its_run(sweep_dir):
    sweep = Sweep(sweep_dir)
    table = sweep.table()
    assert list(table["timestep_ms"]) == [32] and list(table["status"]) == ["ok"]
    rows = Sweep(sweep_dir, tables="rows").table()
    assert rows[0]["timestep_ms"] == 32 and rows[0]["targets_reached"] == 1
    (run,) = sweep.runs()
    assert run.summary["targets_reached"] == rows[0]["targets_reached"]


@pytest.mark.parametrize("tables", ["pandas", "rows"])
def test_a_run_s_outputs(sweep_dir, tables):
    (run,) = Sweep(sweep_dir, tables=tables).runs()
    s = run.summary
    assert s["completed"] and s["targets_total"] == 1 and not run.is_swarm and run.drones == {}
    traj, power = run.trajectory(), run.power()
    motors = {m: run.motors(m) for m in ("empirical", "dandrea", "stolaroff")}
    if tables == "pandas":
        # One row per 32 ms world step up to STOP, but the warm-up's last
        # step, 16 ms to end it at 2.000 s (world-server/README.md).
        steps = traj["time_ms"].diff().dropna()
        assert steps[traj["time_ms"] != 2000].eq(32).all() and traj["time_ms"].iloc[-1] == s["world_time_s"] * 1000
        assert traj["z"].max() > 0.9 and traj["z"].iloc[-1] < 0.05  # took off, landed
        # power.csv: 1 ms rows over the platform's time (DESIGN.md §6).
        assert power["time_s"].iloc[-1] == pytest.approx(s["platform_time_s"], abs=0.002)
        assert len(motors["empirical"]) == len(power)
        assert power["soc"].iloc[-1] == pytest.approx(s["battery"]["soc_end"], abs=1e-6)
    else:
        assert all(b["time_ms"] - a["time_ms"] == (16 if b["time_ms"] == 2000 else 32) for a, b in zip(traj, traj[1:]))
        assert isinstance(traj[0]["y"], float)  # "0" in a float column reads 0.0
        assert power[-1]["soc"] == pytest.approx(s["battery"]["soc_end"], abs=1e-6)
        assert len(motors["dandrea"]) == len(power)
    assert "reached" in run.console()


def test_bad_outputs_are_clear_errors(tmp_path):
    with pytest.raises(OutputError, match="no summary.json"):
        Run(tmp_path)
    with pytest.raises(OutputError, match="no sweep.csv"):
        Sweep(tmp_path)
    (tmp_path / "summary.json").write_text("{")
    with pytest.raises(OutputError, match="invalid JSON"):
        _ = Run(tmp_path).summary
    (tmp_path / "summary.json").write_text(json.dumps({"completed": True}))
    with pytest.raises(OutputError, match="no such file"):
        Run(tmp_path).power()
    (tmp_path / "x.csv").write_text("a,b\n1,2\n3\n")
    with pytest.raises(OutputError, match="x.csv:3: 1 fields"):
        read_csv(tmp_path / "x.csv", "rows")
    with pytest.raises(ValueError, match="motor model"):
        Run(tmp_path).motors("nope")
