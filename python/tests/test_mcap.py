"""run.mcap read back with the PyPI ``mcap`` package (docs/FOXGLOVE.md):
a real ``cosim run`` of a short flight through the thesis's course."""

import subprocess

import numpy as np
import pytest

from crazyflie_cosim.outputs import OutputError, Run, read_mcap
from conftest import ROOT

pytest.importorskip("mcap")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, binaries):
    out = tmp_path_factory.mktemp("mcap") / "run"
    course = ROOT / "scenarios" / "worlds" / "thesis-course.toml"
    subprocess.run(
        [str(binaries["cosim"]), "run", "short-hop", "--quiet", "--no-plots", "--no-trace",
         "--world", str(course), "--set", "mcap_image_every=20", "--set", "mcap_power_every=5", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return out


def test_schemas_transforms_times_and_images(run_dir):
    run = Run(run_dir, tables="rows")
    msgs = list(read_mcap(run.mcap()))
    schemas = {m.topic: m.schema for m in msgs}
    assert schemas["/tf"] == "foxglove.FrameTransform"
    assert schemas["/scene"] == "foxglove.SceneUpdate"
    assert schemas["/cf1/camera"] == "foxglove.RawImage"
    assert schemas["/cf1/battery"] == "cosim.Battery" and schemas["/cf1/power"] == "cosim.Power"
    times = [m.log_time for m in msgs]
    assert times == sorted(times), "log times in file order are monotonic"

    # One transform per world step: trajectory.csv's rows, at their times.
    traj = run.trajectory()
    tf = [m for m in msgs if m.topic == "/tf"]
    assert [m.log_time for m in tf] == [r["time_ms"] * 1_000_000 for r in traj]
    assert all(m.data["child_frame_id"] == "cf1" and m.data["parent_frame_id"] == "world" for m in tf)
    assert tf[-1].data["translation"]["z"] == pytest.approx(traj[-1]["z"])

    images = [m for m in msgs if m.topic == "/cf1/camera"]
    assert images
    for m in images:
        px = m.image()
        assert px.shape == (320, 320) and px.dtype == np.uint8
        assert px.std() > 0  # a rendered view of the course

    # The power channel is power.csv's rows 0, 5, 10, … (mcap_power_every=5)
    # and its last (with the row's own time_s, platform time); the battery
    # channel the same rows at the world's time, its log time.
    power_msgs = [m for m in msgs if m.topic == "/cf1/power"]
    battery = [m for m in msgs if m.topic == "/cf1/battery"]
    power = run.power()
    kept = [r for i, r in enumerate(power) if i % 5 == 0 or i == len(power) - 1]
    assert [m.data["time_s"] for m in power_msgs] == pytest.approx([r["time_s"] for r in kept])
    assert [b.data["time_s"] for b in battery] == pytest.approx([b.log_time * 1e-9 for b in battery])
    assert battery[-1].data["soc"] == pytest.approx(run.summary["battery"]["soc_end"], abs=1e-6)


def test_topics_filter_and_clear_errors(run_dir, tmp_path):
    only = list(read_mcap(Run(run_dir).mcap(), topics=["/scene"]))
    assert [m.topic for m in only] == ["/scene"] and only[0].log_time == 0
    with pytest.raises(ValueError, match="not a foxglove.RawImage"):
        only[0].image()
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file")
    with pytest.raises(OutputError, match="not a readable MCAP"):
        list(read_mcap(bad))
    with pytest.raises(OutputError, match="no such file"):
        list(read_mcap(tmp_path / "missing.mcap"))
