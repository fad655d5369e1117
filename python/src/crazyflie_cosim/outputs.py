"""Readers of a run's and a sweep's outputs (DESIGN.md §6, docs/COSIM.md).

``Run(DIR)`` reads what ``cosim run --out DIR`` wrote: ``summary.json``,
``power.csv``, ``trajectory.csv``, the three motor models' CSVs
(``motor_empirical.csv``, ``motor_dandrea.csv``, ``motor_stolaroff.csv``),
``console.log``, and for a swarm run the world's ``radio.csv`` and one
``Run`` per drone (``run.drones``, the ``out/<scenario>/<drone>/``
directories), and ``run.mcap`` (``read_mcap``, with the PyPI package
``mcap``: ``pip install ./python[mcap]``).  ``Sweep(DIR)`` reads ``cosim sweep``'s ``sweep.csv`` and
opens its runs.

Tables are pandas DataFrames when pandas is installed (``tables="pandas"``,
the default ``"auto"``) and lists of dicts otherwise (``tables="rows"``):
numbers become ``int``/``float``, empty cells ``None``, other text stays
``str``.

The series (``power.csv``, the motor CSVs, ``trajectory.csv``) are stored
zstd-compressed by default (``power.csv.zst``; run key ``output.compress``):
every reader here takes a series by its CSV name and finds either form
(:func:`series_path`). A file whose writer died mid-run (a torn last row, a
cut zstd frame) is read up to its last whole row, with one warning
(:class:`TornSeriesWarning`) saying what was dropped.
"""

from __future__ import annotations

import csv
import io
import json
import os
import warnings
from pathlib import Path
from typing import Any

MOTOR_MODELS = ("empirical", "dandrea", "stolaroff")


class OutputError(ValueError):
    """A missing or malformed output file."""


class TornSeriesWarning(UserWarning):
    """A series file whose writer stopped mid-file: its valid prefix was read."""


def series_path(path: str | os.PathLike) -> Path:
    """The file that holds the series ``path`` names in either form:
    ``out/power.csv`` finds ``out/power.csv.zst``."""
    path = Path(path)
    if path.exists():
        return path
    other = path.with_suffix("") if path.suffix == ".zst" else path.with_name(path.name + ".zst")
    return other if other.is_file() else path


def read_series_bytes(path: str | os.PathLike) -> bytes:
    """The whole lines of a series file in either form (plain or ``.zst``).
    Of a file whose writer died, the valid prefix, with one
    :class:`TornSeriesWarning`."""
    path = series_path(path)
    if not path.is_file():
        raise OutputError(f"{path}: no such file")
    data = path.read_bytes()
    frame_note = ""
    if path.suffix == ".zst":
        try:
            import zstandard
        except ImportError:
            raise OutputError(f"{path}: reading .zst series needs the `zstandard` package (pip install zstandard)") from None
        # A decompressobj, unlike a whole-frame decompress, gives what it can
        # of a frame that breaks off and says so (eof stays False).
        d = zstandard.ZstdDecompressor().decompressobj()
        try:
            data = d.decompress(data)
        except zstandard.ZstdError as e:
            raise OutputError(f"{path}: not a readable zstd file ({e})") from None
        if not d.eof:
            frame_note = ", and the rows the writer had not yet compressed to the file (the zstd frame is incomplete)"
    cut = data.rfind(b"\n") + 1
    partial = len(data) - cut
    if partial or frame_note:
        data = data[:cut]
        rows = max(data.count(b"\n") - 1, 0)
        note = f"{path}: its writer stopped mid-file: kept {rows} rows"
        if partial:
            note += f", dropped a torn last row ({partial} bytes)"
        warnings.warn(note + frame_note, TornSeriesWarning, stacklevel=2)
    return data


def _have_pandas() -> bool:
    try:
        import pandas  # noqa: F401
    except ImportError:
        return False
    return True


def _cell(text: str) -> Any:
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_csv(path: str | os.PathLike, tables: str = "auto"):
    """One of our CSV files (a header line, then rows) as a DataFrame or
    a list of dicts (see the module's documentation); a series in either
    form (:func:`read_series_bytes`)."""
    use_pandas = tables == "pandas" or (tables == "auto" and _have_pandas())
    if tables not in ("auto", "pandas", "rows"):
        raise ValueError(f'tables must be "auto", "pandas" or "rows", not {tables!r}')
    path = series_path(path)
    data = read_series_bytes(path)
    if use_pandas:
        import pandas as pd

        try:
            return pd.read_csv(io.BytesIO(data))
        except pd.errors.EmptyDataError:
            raise OutputError(f"{path}: empty file (no header)") from None
    with io.TextIOWrapper(io.BytesIO(data), newline="") as f:
        reader = csv.reader(f)
        try:
            header = next(reader)
        except StopIteration:
            raise OutputError(f"{path}: empty file (no header)") from None
        rows = []
        for lineno, row in enumerate(reader, start=2):
            if len(row) != len(header):
                raise OutputError(f"{path}:{lineno}: {len(row)} fields, the header has {len(header)}")
            rows.append({k: _cell(v) for k, v in zip(header, row)})
    # A column with any fractional number is a float column ("0" in a
    # column of positions is 0.0), as pandas would type it.
    for k in header:
        if any(isinstance(r[k], float) for r in rows):
            for r in rows:
                if isinstance(r[k], int):
                    r[k] = float(r[k])
    return rows


class Run:
    """The outputs of one ``cosim run`` (or one drone of a swarm run)."""

    def __init__(self, path: str | os.PathLike, tables: str = "auto"):
        self.path = Path(path)
        self.tables = tables
        if not (self.path / "summary.json").is_file():
            raise OutputError(f"{self.path}: not a run's directory (no summary.json)")

    def file(self, name: str) -> Path:
        return self.path / name

    @property
    def summary(self) -> dict[str, Any]:
        """``summary.json`` (DESIGN.md §6; with a ``drones`` map for a swarm)."""
        try:
            return json.loads(self.file("summary.json").read_text())
        except json.JSONDecodeError as e:
            raise OutputError(f"{self.file('summary.json')}: invalid JSON ({e})") from None

    @property
    def is_swarm(self) -> bool:
        return "drones" in self.summary

    @property
    def drones(self) -> dict[str, Run]:
        """A swarm run's drones, each with its own outputs (empty for a
        single-drone run)."""
        names = self.summary.get("drones") or {}
        return {n: Run(self.path / n, self.tables) for n in names if (self.path / n / "summary.json").is_file()}

    def _csv(self, name: str):
        return read_csv(self.file(name), self.tables)

    def power(self):
        """``power.csv`` (or ``power.csv.zst``): 1 ms rows of bus currents, battery current, voltage
        and SOC."""
        return self._csv("power.csv")

    def trajectory(self):
        """``trajectory.csv``: one row per world step (and drone, with a
        ``drone`` column, in a swarm run's top directory)."""
        return self._csv("trajectory.csv")

    def motors(self, model: str = "empirical"):
        """``motor_<model>.csv`` of one of the thesis's three motor models."""
        if model not in MOTOR_MODELS:
            raise ValueError(f"motor model must be one of {MOTOR_MODELS}, not {model!r}")
        return self._csv(f"motor_{model}.csv")

    def radio(self):
        """A swarm run's ``radio.csv`` (one row per frame and receiver)."""
        return self._csv("radio.csv")

    def mcap(self) -> Path:
        """The run's ``run.mcap`` (docs/FOXGLOVE.md); read it with
        :func:`read_mcap`."""
        path = self.file("run.mcap")
        if not path.is_file():
            raise OutputError(f"{path}: no such file (the run was made with --no-mcap?)")
        return path

    def console(self) -> str:
        """What the firmware printed (``console.log``)."""
        path = self.file("console.log")
        if not path.is_file():
            raise OutputError(f"{path}: no such file")
        return path.read_text(errors="replace")

    def __repr__(self) -> str:
        return f"Run({str(self.path)!r})"


class Sweep:
    """The outputs of one ``cosim sweep``: ``sweep.csv`` and its runs."""

    def __init__(self, path: str | os.PathLike, tables: str = "auto"):
        self.path = Path(path)
        self.tables = tables
        if not (self.path / "sweep.csv").is_file():
            raise OutputError(f"{self.path}: not a sweep's directory (no sweep.csv)")

    def table(self):
        """``sweep.csv``: one row per run, its parameters and results."""
        return read_csv(self.path / "sweep.csv", self.tables)

    def runs(self) -> list[Run]:
        """The runs that wrote their outputs, in the table's order."""
        rows = read_csv(self.path / "sweep.csv", "rows")
        out = []
        for row in rows:
            d = Path(str(row.get("dir") or ""))
            if not d.is_absolute():
                d = self.path / d
            if (d / "summary.json").is_file():
                out.append(Run(d, self.tables))
        return out

    def __repr__(self) -> str:
        return f"Sweep({str(self.path)!r})"


class McapMessage:
    """One message of a run's ``run.mcap``: its ``topic``, ``schema`` name,
    ``log_time`` (world time, ns) and ``data`` (the decoded JSON object)."""

    __slots__ = ("topic", "schema", "log_time", "data")

    def __init__(self, topic: str, schema: str, log_time: int, data: dict[str, Any]):
        self.topic, self.schema, self.log_time, self.data = topic, schema, log_time, data

    def image(self):
        """A ``foxglove.RawImage`` message's pixels as a ``height × width``
        NumPy ``uint8`` array (mono8)."""
        import base64

        import numpy as np

        if self.schema != "foxglove.RawImage":
            raise ValueError(f"{self.topic}: a {self.schema}, not a foxglove.RawImage")
        d = self.data
        if d.get("encoding") != "mono8":
            raise ValueError(f"{self.topic}: encoding {d.get('encoding')!r}, not mono8")
        px = np.frombuffer(base64.b64decode(d["data"]), dtype=np.uint8)
        return px.reshape(d["height"], d["width"])

    def __repr__(self) -> str:
        return f"McapMessage({self.topic!r}, {self.schema!r}, {self.log_time})"


def read_mcap(path: str | os.PathLike, topics: list[str] | None = None):
    """Yields the messages of a ``run.mcap`` (or a world's ``--mcap`` file)
    in file order — log-time order for cosim's files — as
    :class:`McapMessage`, optionally only those of ``topics``.  Needs the
    PyPI package ``mcap``."""
    try:
        from mcap.reader import make_reader
    except ImportError:
        raise OutputError("reading MCAP files needs the `mcap` package (pip install mcap)") from None
    path = Path(path)
    if not path.is_file():
        raise OutputError(f"{path}: no such file")
    with open(path, "rb") as f:
        try:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages(topics=topics, log_time_order=False):
                if channel.message_encoding != "json":
                    raise OutputError(f"{path}: {channel.topic} is {channel.message_encoding}, not json")
                yield McapMessage(
                    channel.topic,
                    schema.name if schema is not None else "",
                    message.log_time,
                    json.loads(message.data),
                )
        except OutputError:
            raise
        except Exception as e:  # the mcap package's own errors: a broken file
            raise OutputError(f"{path}: not a readable MCAP file ({e})") from None
