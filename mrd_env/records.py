"""One damper's time series: the validated SI container :class:`DamperRecord` and a CSV loader with declared units.

A :class:`DamperRecord` holds one test — time, stroke, command, force, optionally the velocity, the effective
command after the coil lag and sensor-saturation flags — whatever produced it: a measured file
(:func:`load_record_csv`), the virtual rig (:mod:`mrd_env.rig`) or the rig's sensors
(:func:`mrd_env.identification.apply_sensors`). Every column of a file needs a declared unit (nothing is guessed)
and is converted to SI exactly once, on loading.
"""
from __future__ import annotations

import csv
import dataclasses
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from . import storage
from .resources import file_limit
from .validation import check_signal, check_time, shown

__all__ = ["DamperRecord", "load_record_csv", "read_columns", "own_columns", "UNITS"]

# Accepted input units per role, as factors to SI. Commands keep V or A (the damper models' command units).
UNITS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "ms": 1e-3},
    "x": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "v": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3},
    "force": {"N": 1.0, "kN": 1e3},
    "command": {"V": 1.0, "mV": 1e-3, "A": 1.0, "mA": 1e-3},
}
_COMMAND_SI = {"V": "V", "mV": "V", "A": "A", "mA": "A"}
_REQUIRED = ("t", "x", "command", "force")
_OPTIONAL = ("v",)
# Header of files written by DamperRecord.to_csv; read back by DamperRecord.read_csv.
_OWN_HEADER = {"t": "t_s", "x": "x_m", "v": "v_m_per_s", "force": "force_N"}
# The record's columns: the required four, the optional real ones, the optional boolean flags.
_SIGNALS = ("x", "command", "force")
_OPTIONAL_SIGNALS = ("v", "u")
_FLAGS = ("saturated_x", "saturated_force")


def lowpass_zero_phase(signal: np.ndarray, cutoff_Hz: float, fs_Hz: float) -> np.ndarray:
    """4th-order Butterworth low-pass run forward and backward (zero phase, -6 dB at ``cutoff_Hz``).

    The ends are padded by odd reflection over about six periods of the cut-off, long enough for the filter's
    start-up transient to die out before the real samples; shorter records are padded as far as they go.
    """
    from scipy.signal import butter, sosfiltfilt
    sos = butter(4, cutoff_Hz, fs=fs_Hz, output="sos")
    pad = min(int(math.ceil(6.0 * fs_Hz / cutoff_Hz)), signal.shape[0] - 1)
    return sosfiltfilt(sos, signal, padlen=pad)


def hold_previous(t: np.ndarray, values: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Zero-order hold: the value of the last sample at or before each new time."""
    # a tolerance of 1e-9 interval keeps a new time that rounds just below a sample time on that sample
    tol = 1e-9 * (t[-1] - t[0]) / (t.shape[0] - 1)
    idx = np.searchsorted(t, t_new + tol, side="right") - 1
    return values[np.clip(idx, 0, t.shape[0] - 1)]


def _frozen(a: np.ndarray) -> np.ndarray:
    # a frozen record must not be changeable through its arrays either
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


def _check_flags(label: str, value, n: int) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype != np.bool_ or a.shape != (n,):
        raise ValueError(f"{label} must be a 1-D boolean mask of {n} samples (the length of the other columns), "
                         f"got {a.dtype} of shape {a.shape}")
    return a


@dataclass(frozen=True, eq=False)
class DamperRecord:
    """One damper's time series in SI units: ``t`` (s), ``x`` stroke (m, extension positive), ``command`` (V or
    A, held over each interval), ``force`` (N, positive when resisting extension).

    Optional columns: ``v`` measured velocity (m/s; :meth:`velocity` falls back to dx/dt), ``u`` effective command
    after the driver/coil lag (V or A; the rig knows it), ``saturated_x`` / ``saturated_force`` (boolean: the
    sensor saturated at that sample; the rig's sensors know it). ``model`` names the damper model that produced
    the record (the rig), empty for a measured one. All columns have the same length (>= 3) and are finite,
    ``t`` is strictly increasing; the arrays are read-only copies.
    """

    t: np.ndarray
    x: np.ndarray
    command: np.ndarray
    force: np.ndarray
    v: np.ndarray | None = None
    command_unit: str = "V"
    label: str = field(default="", compare=False)
    u: np.ndarray | None = None
    saturated_x: np.ndarray | None = None
    saturated_force: np.ndarray | None = None
    model: str = ""

    def __post_init__(self):
        t = check_time("column 't'", self.t, item="row")
        n = t.shape[0]
        cols = {"t": t}
        for name in _SIGNALS + tuple(k for k in _OPTIONAL_SIGNALS if getattr(self, k) is not None):
            cols[name] = check_signal(f"column '{name}'", getattr(self, name), n=n, item="row")
        for name in (k for k in _FLAGS if getattr(self, k) is not None):
            cols[name] = _check_flags(f"column '{name}'", getattr(self, name), n)
        if not isinstance(self.command_unit, str) or self.command_unit not in ("V", "A"):
            raise ValueError(f"command_unit = {shown(self.command_unit)} is invalid: must be 'V' or 'A'")
        for name, a in cols.items():
            object.__setattr__(self, name, _frozen(a))

    # --- derived quantities ---------------------------------------------------------------------------------

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> float:
        """Mean sampling interval (s)."""
        return self.duration / (self.n - 1)

    def columns(self) -> tuple[str, ...]:
        """Names of the columns this record holds (the required four and the optional ones present)."""
        return ("t",) + _SIGNALS + tuple(k for k in _OPTIONAL_SIGNALS + _FLAGS if getattr(self, k) is not None)

    def velocity(self) -> np.ndarray:
        """Measured velocity if present, else dx/dt by second-order differences on ``t`` (m/s)."""
        if self.v is not None:
            return self.v
        return np.gradient(self.x, self.t, edge_order=2)

    def steady_cycles(self, frequency: float, n_cycles: int = 1) -> slice:
        """Index slice of the last ``n_cycles`` periods of a test at ``frequency`` (Hz), for loops and energy."""
        n = int(round(n_cycles / (frequency * self.dt)))
        return slice(self.n - n - 1, self.n)

    def dissipated_energy(self, sl: slice | None = None) -> float:
        """∮ F dx over the samples in ``sl`` (J), trapezoidal in time: ∫ F ẋ dt."""
        sl = sl or slice(None)
        return float(np.trapezoid(self.force[sl] * self.velocity()[sl], self.t[sl]))

    def _replace(self, idx, label: str | None = None) -> DamperRecord:
        """The samples ``idx`` (a slice or index array) of every column."""
        return dataclasses.replace(self, label=self.label if label is None else label,
                                   **{k: getattr(self, k)[idx] for k in self.columns()})

    # --- selections -------------------------------------------------------------------------------------------

    def slice(self, t0: float, t1: float) -> DamperRecord:
        """Samples with t0 <= t <= t1 (s); times are kept, not shifted to zero."""
        t0, t1 = float(t0), float(t1)
        if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
            raise ValueError(f"the time window [{t0:g}, {t1:g}] s is invalid: its start must be finite and before its "
                             "finite end")
        idx = np.flatnonzero((self.t >= t0) & (self.t <= t1))
        if idx.size < 3:
            raise ValueError(f"the time window [{t0:g}, {t1:g}] s holds {idx.size} samples (need >= 3); the record "
                             f"{self.label!r} spans [{self.t[0]:g}, {self.t[-1]:g}] s")
        return self._replace(slice(int(idx[0]), int(idx[-1]) + 1))

    def split(self, fraction: float) -> tuple[DamperRecord, DamperRecord]:
        """(fit, validation): the first ``fraction`` of the samples and the rest, without overlap."""
        f = float(fraction)
        if not (0.0 < f < 1.0):
            raise ValueError(f"fraction = {shown(fraction)} is invalid: must be in (0, 1)")
        k = int(round(f * self.n))
        if k < 3 or self.n - k < 3:
            raise ValueError(f"fraction = {f:g} of {self.n} samples leaves a part with fewer than 3 samples")
        return (self._replace(slice(0, k), self.label and f"{self.label} (fit)"),
                self._replace(slice(k, None), self.label and f"{self.label} (validation)"))

    def resample(self, dt: float, *, antialias: bool = True) -> DamperRecord:
        """Record on the uniform grid t0 + k·dt (s), k = 0.. while <= t_end.

        x, v, u and force are interpolated linearly; the command, a switched signal, and the saturation flags are
        held from the last sample at or before each new time (zero-order hold) so steps stay steps. When
        downsampling (dt larger than the mean interval) with ``antialias``, x, v, u and force first pass a
        zero-phase 4th-order Butterworth low-pass at 0.8 × the new Nyquist frequency — the original grid must then
        be uniform up to rounding of the time stamps (within half an interval of t0 + k·dt).
        """
        dt = float(dt)
        if not (math.isfinite(dt) and 0.0 < dt <= self.duration / 2):
            raise ValueError(f"dt = {shown(dt)} is invalid: must be > 0 and <= half the duration "
                             f"({self.duration / 2:g} s)")
        n_new = int(math.floor(self.duration / dt * (1 + 1e-12))) + 1
        t_new = self.t[0] + dt * np.arange(n_new)
        signals = {k: getattr(self, k) for k in ("x", "force") + _OPTIONAL_SIGNALS if getattr(self, k) is not None}
        if antialias and dt > self.dt * (1 + 1e-9):
            # time stamps rounded in the file are fine: only a real gap or rate change breaks the filter
            drift = np.abs(self.t - (self.t[0] + self.dt * np.arange(self.n))).max()
            if drift > 0.5 * self.dt:
                raise ValueError("resample with antialias=True needs a uniformly sampled record (t deviates "
                                 f"by {drift:g} s from a uniform grid of {self.dt:g} s); pass antialias=False")
            signals = {k: lowpass_zero_phase(s, 0.8 * (0.5 / dt), 1.0 / self.dt) for k, s in signals.items()}
        cols = {k: np.interp(t_new, self.t, s) for k, s in signals.items()}
        held = {k: hold_previous(self.t, getattr(self, k), t_new) for k in ("command",) + _FLAGS
                if getattr(self, k) is not None}
        return dataclasses.replace(self, t=t_new, **cols, **held)

    # --- files ------------------------------------------------------------------------------------------------

    def to_csv(self, path: str | Path) -> Path:
        """Write SI columns ``t_s, x_m[, v_m_per_s], command_<unit>[, u_<unit>], force_N``, round-trip exact
        (:meth:`read_csv` reads them back but for ``u``; the saturation flags are not written)."""
        path = Path(path)
        names = [k for k in ("t", "x", "v", "command", "u", "force") if getattr(self, k) is not None]
        header = [_OWN_HEADER.get(k, f"{k}_{self.command_unit}") for k in names]
        buf = io.StringIO(newline="")
        w = csv.writer(buf)
        w.writerow(header)
        # repr gives the shortest string that parses back to the same float
        w.writerows([repr(float(val)) for val in row] for row in zip(*(getattr(self, k) for k in names)))
        return storage.write_text(path, buf.getvalue())

    @classmethod
    def read_csv(cls, path: str | Path, label: str = "") -> DamperRecord:
        """Read a file written by :meth:`to_csv` or by the virtual rig (its header declares the SI units)."""
        columns, units = own_columns(path)
        return load_record_csv(path, columns, units, label=label)


def own_columns(path: str | Path, required: tuple[str, ...] = _REQUIRED) -> tuple[dict[str, str], dict[str, str]]:
    """(columns, units) of a file written by mrd-env — :meth:`DamperRecord.to_csv`, ``mrd-env rig`` — whose header
    names the SI unit of each column (``t_s``, ``x_m``, ``v_m_per_s``, ``command_V`` or ``command_A``, ``force_N``);
    ``ValueError`` if the file lacks a ``required`` role."""
    header, _, _ = _read_table(_as_path(path), True, max_rows=0)
    unit = next((h[len("command_"):] for h in header if h in ("command_V", "command_A")), None)
    columns = {k: v for k, v in _OWN_HEADER.items() if v in header}
    if unit is not None:
        columns["command"] = f"command_{unit}"
    missing = [r for r in required if r not in columns]
    if missing:
        wanted = [(_OWN_HEADER.get(r) or "command_V or command_A") for r in missing]
        raise ValueError(f"{path}: not a file written by mrd-env (no column {' / '.join(wanted)}); name your "
                         "columns and their units (columns=..., units=...; on the command line --columns and "
                         "--units)")
    si = {"t": "s", "x": "m", "v": "m/s", "force": "N", "command": unit}
    return columns, {k: si[k] for k in columns}


def read_columns(path: str | Path, columns: dict[str, str], units: dict[str, str], *,
                 required: tuple[str, ...] = _REQUIRED, skip_trailing_empty: bool = True) -> dict[str, np.ndarray]:
    """The chosen columns of a CSV file with a header line, converted to SI once: {role: array}.

    The loader behind :func:`load_record_csv` and the rig's record replay: ``columns`` maps roles (among "t",
    "x", "v", "command", "force"; ``required`` ones must be present) to header names, ``units`` gives each
    chosen column's unit (:data:`UNITS`; no defaults). Commas, semicolons or tabs separate the cells (detected
    from the header line). Raises ``ValueError`` naming the file, column and row for a missing file, a file that
    is not text, missing columns, missing or unknown units, empty/non-numeric/non-finite cells and a
    non-increasing time column.
    """
    path = _as_path(path)
    roles = tuple(dict.fromkeys(_REQUIRED + _OPTIONAL))
    for name, given in (("columns", columns), ("units", units)):
        if not isinstance(given, Mapping):
            raise ValueError(f"{name} must be a dict role -> {'header name' if name == 'columns' else 'unit'} "
                             f"(roles {list(roles)}), got {type(given).__name__}")
    unknown = sorted(set(columns) - set(roles), key=repr)
    if unknown:
        raise ValueError(f"columns has unknown roles {unknown}; valid roles are {list(roles)}")
    missing_roles = [r for r in required if r not in columns]
    if missing_roles:
        raise ValueError(f"columns must name the file columns for roles {missing_roles} "
                         f"(required roles: {list(required)}, optional: {[r for r in roles if r not in required]})")
    factors = {}
    for role, col in columns.items():
        accepted = list(UNITS[role])
        if not isinstance(col, str):
            raise ValueError(f"columns['{role}'] must be a header name (text), got {col!r}")
        if role not in units:
            raise ValueError(f"units['{role}'] is not given for column '{col}': declare its unit, one of "
                             f"{accepted}")
        if not isinstance(units[role], str) or units[role] not in UNITS[role]:
            raise ValueError(f"units['{role}'] = {units[role]!r} for column '{col}' is not accepted; use one of "
                             f"{accepted}")
        factors[role] = UNITS[role][units[role]]
    extra = sorted(set(units) - set(columns), key=repr)
    if extra:
        raise ValueError(f"units given for roles {extra} that have no column in columns")

    header, rows, lines = _read_table(path, skip_trailing_empty)
    index = {}
    for role, col in columns.items():
        hits = [i for i, h in enumerate(header) if h == col]
        if not hits:
            raise ValueError(f"{path}: column '{col}' (for '{role}') not found; available columns: "
                             f"{[h for h in header if h]}")
        if len(hits) > 1:
            raise ValueError(f"{path}: column '{col}' appears {len(hits)} times in the header")
        index[role] = hits[0]
    if len(rows) < 3:
        raise ValueError(f"{path}: has {len(rows)} data row(s), need at least 3")

    data = {role: _parse_column(path, rows, lines, index[role], f"column '{columns[role]}' ({role})")
            * factors[role] for role in columns}
    for role in columns:
        what = f"{path}: column '{columns[role]}' ({role})"
        if role == "t":
            check_time(what, data[role], item="data row")
        else:
            check_signal(what, data[role], item="data row")
    return data


def load_record_csv(path: str | Path, columns: dict[str, str], units: dict[str, str], *,
                    skip_trailing_empty: bool = True, label: str = "") -> DamperRecord:
    """Load a damper test from a CSV file with a header line, converting the chosen columns to SI once.

    ``columns`` maps the roles "t", "x", "command", "force" (and optionally "v") to header names; header names
    may be quoted. ``units`` gives each chosen column's unit (accepted units: :data:`UNITS`); there are no
    defaults. With ``skip_trailing_empty`` the empty cells left by a trailing comma at the end of each line and
    blank lines are ignored, as in files exported with a comma after the last column. Columns not chosen are
    never parsed (they may be partly empty). Errors: see :func:`read_columns`.
    """
    data = read_columns(path, columns, units, skip_trailing_empty=skip_trailing_empty)
    return DamperRecord(data["t"], data["x"], data["command"], data["force"], data.get("v"),
                        _COMMAND_SI[units["command"]], label or Path(path).stem)


def _as_path(path) -> Path:
    try:
        return Path(path)
    except TypeError:
        raise ValueError(f"path must be a file path (str or os.PathLike), got {path!r}") from None


def _read_table(path: Path, skip_trailing_empty: bool,
                max_rows: int | None = None) -> tuple[list[str], list[list[str]], list[int]]:
    """Header cells, data rows and their file line numbers (cells separated by ',', ';' or tabs)."""
    def trim(cells: list[str]) -> list[str]:
        if skip_trailing_empty:
            while cells and cells[-1].strip() == "":
                cells = cells[:-1]
        return cells

    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a CSV file")
    # a regular file of a bounded size only (never a FIFO or /dev/zero: mrd_env.storage.read_limited)
    data = storage.read_limited(path, file_limit(), what="CSV file")
    try:
        with io.StringIO(data.decode("utf-8-sig"), newline="") as fh:
            first = ""
            for first in fh:
                if first.strip():
                    break
            # the separator of the header line: the most frequent of comma, semicolon, tab
            delimiter = max((",", ";", "\t"), key=first.count) if first.strip() else ","
            fh.seek(0)
            reader = csv.reader(fh, delimiter=delimiter, skipinitialspace=True)
            header = None
            rows, lines = [], []
            for cells in reader:
                if not any(c.strip() for c in cells):
                    if skip_trailing_empty or header is None:
                        continue
                    raise ValueError(f"{path}: line {reader.line_num} is empty")
                if header is None:
                    header = [c.strip() for c in trim(cells)]
                    if max_rows == 0:
                        break
                    continue
                rows.append(cells if not skip_trailing_empty else trim(cells))
                lines.append(reader.line_num)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text CSV file (byte {exc.start} is not UTF-8 text)") from None
    except csv.Error:
        raise ValueError(f"{path}: not a readable CSV file") from None
    if header is None:
        raise ValueError(f"{path}: the file is empty (expected a header line)")
    width = len(header)
    if width == 1 and rows:
        raise ValueError(f"{path}: the header line has a single column; expected column names "
                         "separated by commas, semicolons or tabs")
    for cells, line in zip(rows, lines):
        # rows may be shorter only when trailing empty cells were trimmed
        if len(cells) > width or (not skip_trailing_empty and len(cells) != width):
            raise ValueError(f"{path}: line {line} has {len(cells)} cells but the header has {width}")
    return header, rows, lines


def _parse_column(path: Path, rows: list[list[str]], lines: list[int], j: int, what: str) -> np.ndarray:
    cells = [r[j] if j < len(r) else "" for r in rows]
    try:
        return np.array(cells, dtype=np.float64)
    except ValueError:
        pass
    # slow path only to say where the bad cell is
    for i, (c, line) in enumerate(zip(cells, lines)):
        try:
            float(c)
        except ValueError:
            shown = "an empty cell" if c.strip() == "" else "a value that is not a number"
            raise ValueError(f"{path}: {what} has {shown} at data row {i} (file line {line})") from None
    raise AssertionError("unreachable")  # numpy rejected a cell that float() accepts
