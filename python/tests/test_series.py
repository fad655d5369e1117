"""The series in both forms (DESIGN.md §6, §19): a run's ``*.csv.zst``
(the default) and its plain ``*.csv`` (``--set output.compress=false``)
read back as the same tables, with pandas and without; a file cut short by
a writer that died reads as its valid prefix, with one warning."""

import shutil
import subprocess

import pytest

from crazyflie_cosim.outputs import Run, TornSeriesWarning, read_csv, series_path

SERIES = ("power", "trajectory", "motors")


def _run(binaries, out, *extra):
    subprocess.run(
        [str(binaries["cosim"]), "run", "short-hop", "--out", str(out), "--no-mcap", "--no-plots", "-q", *extra],
        check=True,
        capture_output=True,
    )
    return Run(out)


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory, binaries):
    base = tmp_path_factory.mktemp("series")
    return _run(binaries, base / "zst"), _run(binaries, base / "plain", "--set", "output.compress=false")


def _tables(run, tables):
    r = Run(run.path, tables)
    return {"power": r.power(), "trajectory": r.trajectory(), "motors": r.motors("stolaroff")}


def test_the_forms_are_where_they_should_be(two_runs):
    zst, plain = two_runs
    for name in ("power.csv", "trajectory.csv", "motor_empirical.csv"):
        assert (zst.path / f"{name}.zst").is_file() and not (zst.path / name).exists()
        assert (plain.path / name).is_file() and not (plain.path / f"{name}.zst").exists()
        assert series_path(zst.path / name) == zst.path / f"{name}.zst"


def test_both_forms_read_the_same_rows(two_runs):
    pd = pytest.importorskip("pandas")
    zst, plain = two_runs
    a, b = _tables(zst, "pandas"), _tables(plain, "pandas")
    for k in SERIES:
        assert len(a[k]) > 100
        pd.testing.assert_frame_equal(a[k], b[k])
    # pandas reads the compressed file by itself too (zstandard installed).
    pd.testing.assert_frame_equal(pd.read_csv(zst.path / "power.csv.zst"), a["power"])
    ra, rb = _tables(zst, "rows"), _tables(plain, "rows")
    for k in SERIES:
        assert ra[k] == rb[k]
        assert ra[k][-1] == {c: v for c, v in b[k].iloc[-1].items()}


def test_a_cut_file_reads_as_its_valid_prefix(two_runs, tmp_path):
    zst, plain = two_runs
    whole = read_csv(plain.path / "trajectory.csv", "rows")
    # Plain: a torn last row (a few of its fields).
    text = (plain.path / "trajectory.csv").read_bytes()
    cut = text[: text.rindex(b"\n", 0, len(text) // 2) + 12]
    (tmp_path / "trajectory.csv").write_bytes(cut)
    with pytest.warns(TornSeriesWarning, match=r"kept \d+ rows, dropped a torn last row \(11 bytes\)"):
        rows = read_csv(tmp_path / "trajectory.csv", "rows")
    assert rows == whole[: len(rows)] and len(rows) == cut.count(b"\n") - 1
    # Compressed: a frame without its end.
    (tmp_path / "trajectory.csv").unlink()
    data = (zst.path / "trajectory.csv.zst").read_bytes()
    (tmp_path / "trajectory.csv.zst").write_bytes(data[: len(data) - 9])
    with pytest.warns(TornSeriesWarning, match="zstd frame is incomplete"):
        rows = read_csv(tmp_path / "trajectory.csv", "rows")
    assert rows == whole[: len(rows)]
    # A run's directory keeps reading too.
    shutil.copy(zst.path / "summary.json", tmp_path / "summary.json")
    with pytest.warns(TornSeriesWarning):
        assert len(Run(tmp_path, "rows").trajectory()) == len(rows)
