"""The common container for sampled exogenous inputs, and helpers shared by the generators and readers."""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .. import storage
from ..constants import GRAVITY
from ..resources import file_limit
from ..validation import as_generator, check_n_samples, check_scalar  # noqa: F401 (as_generator: shared)

#: Standard acceleration of gravity, m/s^2 (:data:`mrd_env.constants.GRAVITY`, under the name this package has
#: always exported). AT2 files give accelerations in units of g.
STANDARD_GRAVITY = GRAVITY

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3}
TIME_UNITS = {"s": 1.0, "ms": 1e-3}
ACCEL_UNITS = {"g": STANDARD_GRAVITY, "m/s^2": 1.0, "m/s2": 1.0, "cm/s^2": 1e-2, "cm/s2": 1e-2, "gal": 1e-2}


@dataclass(frozen=True, eq=False)
class Record:
    """A sampled exogenous input on a uniform time grid ``t_k = k * dt``, k = 0 .. n_samples - 1.

    ``data`` has shape (n_samples, n_channels); it is stored as a read-only float64 copy so that a
    record handed to several environments cannot be changed behind their backs.
    """

    dt: float
    data: np.ndarray
    channels: tuple[str, ...]
    units: tuple[str, ...]
    name: str = ""

    def __post_init__(self) -> None:
        dt = check_scalar("dt", self.dt, 0.0, lo_open=True, unit="s")
        try:
            data = np.array(self.data, dtype=np.float64)  # a copy: the caller keeps a writable original
        except (TypeError, ValueError):
            raise ValueError("data must be a 2-D array of real numbers (n_samples, n_channels)") from None
        if data.ndim != 2:
            raise ValueError(f"data must be 2-D (n_samples, n_channels), got shape {data.shape}")
        if data.shape[0] < 2 or data.shape[1] < 1:
            raise ValueError(f"data must have >= 2 samples and >= 1 channel, got shape {data.shape}")
        bad = ~np.isfinite(data)
        if bad.any():
            k, j = np.argwhere(bad)[0]
            raise ValueError(f"data must be finite: non-finite value at sample {k} (t = {k * dt:g} s), "
                             f"channel {j}")
        data.setflags(write=False)
        channels = tuple(self.channels) if not isinstance(self.channels, str) else (self.channels,)
        units = tuple(self.units) if not isinstance(self.units, str) else (self.units,)
        n_ch = data.shape[1]
        if len(channels) != n_ch or not all(isinstance(c, str) and c for c in channels):
            raise ValueError(f"channels must be {n_ch} non-empty names (one per data column), got {channels!r}")
        if len(set(channels)) != n_ch:
            raise ValueError(f"channels must be unique, got {channels!r}")
        if len(units) != n_ch or not all(isinstance(u, str) and u for u in units):
            raise ValueError(f"units must be {n_ch} non-empty strings (one per data column), got {units!r}")
        if not isinstance(self.name, str):
            raise ValueError(f"name must be a str, got {self.name!r}")
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "units", units)

    @property
    def n_samples(self) -> int:
        return self.data.shape[0]

    @property
    def t(self) -> np.ndarray:
        """Sample times in s, starting at 0."""
        return np.arange(self.n_samples) * self.dt

    @property
    def duration(self) -> float:
        """Time of the last sample in s, (n_samples - 1) * dt."""
        return (self.n_samples - 1) * self.dt

    def channel(self, name: str) -> np.ndarray:
        """The read-only 1-D samples of channel ``name``."""
        try:
            j = self.channels.index(name)
        except ValueError:
            raise ValueError(f"channel must be one of {self.channels}, got {name!r}") from None
        return self.data[:, j]

    def unit(self, name: str) -> str:
        """The unit of channel ``name``."""
        self.channel(name)  # same error for an unknown channel
        return self.units[self.channels.index(name)]

    def resample(self, dt: float, n_samples: int | None = None) -> "Record":
        """The record on the grid ``k * dt`` up to its duration, by linear interpolation of every channel
        (``n_samples``: only the first that many samples of that grid, the same values).

        No anti-alias filter is applied: resampling to a coarser step keeps the samples' values, so content
        above the new Nyquist frequency 1/(2 dt) aliases. Linear interpolation never exceeds the original
        peak, so a record's PGA can only drop, by at most its change over one original step.
        """
        dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
        if dt > self.duration:
            raise ValueError(f"dt = {dt:g} s must be <= the record's duration {self.duration:g} s")
        if n_samples is None or n_samples > self.duration / dt + 1:
            check_n_samples(self.duration / dt, f"the record's duration / dt = {self.duration:g} s / {dt:g} s")
        n = n_samples_for(self.duration, dt)
        if n_samples is not None:
            n = max(2, min(n, int(n_samples)))
        t_new = np.arange(n) * dt
        t_old = self.t
        data = np.column_stack([np.interp(t_new, t_old, self.data[:, j]) for j in range(self.data.shape[1])])
        return Record(dt, data, self.channels, self.units, self.name)

    def __repr__(self) -> str:
        return (f"Record(name={self.name!r}, dt={self.dt:g} s, n_samples={self.n_samples}, "
                f"duration={self.duration:g} s, channels={self.channels}, units={self.units})")


# ---------------------------------------------------------------------------------------------------------------
# Helpers shared by road.py and ground_motion.py (private to the package).

def n_samples_for(duration: float, dt: float) -> int:
    """Number of samples of the grid k*dt covering [0, duration]; the tolerance keeps e.g. 10 s / 1e-3 s
    from losing its last sample to rounding."""
    return int(math.floor(duration / dt * (1.0 + 1e-12) + 1e-9)) + 1


def check_duration_dt(duration: float, dt: float) -> tuple[float, float]:
    duration = check_scalar("duration", duration, 0.0, lo_open=True, unit="s")
    dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    if dt > duration:
        raise ValueError(f"dt must be <= duration = {duration:g} s, got {dt:g} s")
    check_n_samples(duration / dt, f"duration / dt = {duration:g} s / {dt:g} s")
    return duration, dt


def unit_factor(param: str, unit, table: Mapping[str, float]) -> float:
    """The factor that converts ``unit`` (one of ``table``'s keys, case-insensitive) to SI."""
    if not isinstance(unit, str) or unit.strip().lower() not in table:
        raise ValueError(f"{param} must be one of {sorted(table)}, got {unit!r}")
    return table[unit.strip().lower()]


def parse_float(token: str) -> float:
    """A float from a text token, accepting Fortran 'D' exponents (old strong-motion files use them)."""
    return float(token.replace("D", "E").replace("d", "e"))


def read_text(path, what: str) -> str:
    """The text of a file named by an option, read through :func:`mrd_env.storage.read_limited`: a regular file
    only (never a FIFO or a device such as /dev/zero) of at most :func:`mrd_env.resources.file_limit` bytes, UTF-8
    (a byte-order mark skipped); a ``ValueError`` naming ``what`` and the file otherwise, never quoting it."""
    data = storage.read_limited(path, file_limit(), what=f"{what}: file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise ValueError(f"{what}: {os.fspath(path)!r} line {line} is not UTF-8 text") from None


def read_table(path, what: str) -> tuple[list[str] | None, np.ndarray, np.ndarray]:
    """Read a numeric text table: comma-, semicolon- or whitespace-separated, '#' comment lines and blank lines
    skipped, at most one header row (detected as a first row that is not all numbers).

    Returns (header or None, data of shape (n_rows, n_cols), 1-based line number of each row). Raises
    ``ValueError`` naming the file (and line) if it cannot be read (:func:`read_text`), for ragged rows or
    non-numeric values, never quoting the file; NaN/empty values are kept as NaN so the caller can report them
    against the column they belong to.
    """
    path = os.fspath(path)
    lines = read_text(path, what).splitlines()

    def split(line: str) -> list[str]:
        if "," in line:
            parts = line.split(",")
        elif ";" in line:
            parts = line.split(";")
        else:
            parts = line.split()
        return [p.strip().strip('"').strip("'").strip() for p in parts]

    header: list[str] | None = None
    rows: list[list[float]] = []
    line_no: list[int] = []
    n_cols = None
    for i, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        tokens = split(line)
        if n_cols is None:
            n_cols = len(tokens)
            try:
                [parse_float(tok) for tok in tokens]
            except ValueError:
                header = tokens
                continue
        if len(tokens) != n_cols:
            raise ValueError(f"{what}: {path!r} line {i} has {len(tokens)} fields, expected {n_cols}")
        row = []
        for j, tok in enumerate(tokens):
            if tok == "":
                row.append(math.nan)
                continue
            try:
                row.append(parse_float(tok))
            except ValueError:
                raise ValueError(f"{what}: {path!r} line {i}, column {j + 1} is not a number") from None
        rows.append(row)
        line_no.append(i)
    if len(rows) < 2:
        raise ValueError(f"{what}: {path!r} must have at least 2 data rows, found {len(rows)}")
    return header, np.array(rows, dtype=np.float64), np.array(line_no)


def check_column(values: np.ndarray, lines: np.ndarray, column: str, path, *, increasing: bool) -> None:
    """Raise ``ValueError`` for a NaN in ``values`` or, for an abscissa, a value not above its predecessor."""
    nan = np.flatnonzero(~np.isfinite(values))
    if nan.size:
        raise ValueError(f"column {column!r} of {os.fspath(path)!r} has a missing or non-finite value "
                         f"on line {lines[nan[0]]}")
    if increasing:
        bad = np.flatnonzero(np.diff(values) <= 0)
        if bad.size:
            k = bad[0] + 1
            raise ValueError(f"column {column!r} of {os.fspath(path)!r} must be strictly increasing: "
                             f"{values[k]:g} on line {lines[k]} follows {values[k - 1]:g}")


def split_unit(column: str) -> tuple[str, str | None]:
    """'height [mm]' or 'height (mm)' -> ('height', 'mm'); 'height' -> ('height', None)."""
    m = re.fullmatch(r"\s*(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]\s*", column)
    if m:
        return m.group(1), m.group(2)
    return column.strip(), None
