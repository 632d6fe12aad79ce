"""Records made ready to drive a model: a uniform grid, the velocity and acceleration, the command in the admissible
range, and the mask of samples that enter the objective and the error measures (warm-up, faults left out).
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..dampers import CommandSpec
from ..validation import shown
from ..records import DamperRecord
from .faults import Fault, FaultsExcluded, describe_faults, find_faults, repair_spikes


def as_record(rec: Any, i: int) -> DamperRecord:
    """``rec`` as a :class:`DamperRecord` labelled (``record i`` if it had no label): a DamperRecord (measured, from
    the rig or from its sensors) is used as it is; any other object with t, x, command, force (and v) arrays is
    converted, which validates it (NaN, lengths, increasing time)."""
    if isinstance(rec, DamperRecord):
        return rec if rec.label else dataclasses.replace(rec, label=f"record {i}")
    try:
        return DamperRecord(rec.t, rec.x, rec.command, rec.force, getattr(rec, "v", None),
                            getattr(rec, "command_unit", "V"), getattr(rec, "label", "") or f"record {i}")
    except AttributeError:
        raise ValueError(f"records[{i}] must be a DamperRecord (or have t, x, command, force arrays), got "
                         f"{type(rec).__name__}") from None


def as_records(records) -> list[DamperRecord]:
    """One record or a sequence of them as a non-empty list of DamperRecords (see :func:`as_record`)."""
    if isinstance(records, DamperRecord) or not isinstance(records, (list, tuple)):
        records = [records]
    if not records:
        raise ValueError("records must not be empty")
    return [as_record(r, i) for i, r in enumerate(records)]


def uniform_record(record: DamperRecord, dt: float | None = None) -> DamperRecord:
    """``record`` on a uniform grid t0 + k·dt (s).

    ``dt=None`` uses the mean sampling interval. If every time stamp lies within dt/2 of t0 + k·dt (a uniform
    record whose time column was rounded in the file), the stamps are simply rebuilt as t0 + k·dt and the
    samples are kept as they are; otherwise the record is resampled (:meth:`DamperRecord.resample`: linear
    interpolation, zero-order hold for the command, zero-phase anti-alias filter when downsampling).
    """
    if dt is None:
        dt = record.dt
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {shown(dt)} is invalid: must be > 0 s")
    grid = record.t[0] + dt * np.arange(record.n)
    if np.abs(record.t - grid).max() <= 0.5 * dt:
        if np.array_equal(grid, record.t):
            return record
        return dataclasses.replace(record, t=grid)
    try:
        return record.resample(dt)
    except ValueError:
        if dt > 0.5 * record.duration:
            raise
        # a non-uniform record cannot be low-pass filtered on its own grid: interpolate only
        return record.resample(dt, antialias=False)


@dataclass(frozen=True, eq=False)
class PreparedRecord:
    """A record ready to drive a model (:func:`prepare_record`): ``series`` is the record on a uniform grid of step
    ``dt`` (s) with its velocity, its command in the admissible range (``n_clipped`` samples clipped) and its force
    aligned with the motion (``offset`` samples, :mod:`.align`); beside it the acceleration ``a`` (m/s²) and the
    ``mask`` of samples that enter the objective and the error measures (after the warm-up, outside the
    ``faults``)."""

    series: DamperRecord
    dt: float
    a: np.ndarray
    mask: np.ndarray
    n_clipped: int = 0
    faults: tuple[Fault, ...] = ()
    offset: int = 0


FAULT_MODES = ("exclude", "keep", "raise")
FAULT_MARGIN = 0.005  # s excluded on both sides of a fault span (a load cell's filter, a kicked model state)


def prepare_record(record: DamperRecord, command: CommandSpec, *, dt: float | None = None,
                   command_range: str = "clip", warmup: float = 0.0, faults: str = "exclude",
                   offset: int = 0) -> PreparedRecord:
    """Put ``record`` on a uniform grid (:func:`uniform_record`) and check its command against ``command``.

    ``command_range``: "clip" — commands outside [v_min, v_max] are clipped to the range (the count is kept
    in ``n_clipped``); "raise" — ``ValueError``; "widen" — keep them (the caller widens the channel's range,
    see :func:`fit_model`). ``warmup`` (s): the first samples, where the model's states (started at rest) have
    not yet forgotten their initial values, are simulated but left out of the objective and of the measures.
    ``faults``: "exclude" (default) — the faults of :func:`~.faults.find_faults` leave the mask (with
    :data:`FAULT_MARGIN` on both sides), spikes of x and v are repaired, and a :class:`~.faults.FaultsExcluded`
    warning says so; "keep" — use the record as it is; "raise" — ``ValueError`` if there is a fault.
    ``offset`` (samples): the force channel lags the motion channels by this many samples; the force is shifted
    back (``force[k] = measured[k + offset]``) and the samples left without a partner leave the mask.
    """
    if command_range not in ("clip", "raise", "widen"):
        raise ValueError(f"command_range = {shown(command_range)} is invalid: must be 'clip', 'raise' or 'widen'")
    if faults not in FAULT_MODES:
        raise ValueError(f"faults = {shown(faults)} is invalid: must be one of {list(FAULT_MODES)}")
    if record.command_unit != command.unit:
        raise ValueError(f"record {record.label!r} has commands in {record.command_unit} but the damper's "
                         f"command channel is in {command.unit}")
    found = tuple(find_faults(record)) if faults != "keep" else ()
    if found and faults == "raise":
        raise ValueError(f"record {record.label!r} has faults: " + "; ".join(str(f) for f in found))
    if found:
        record = dataclasses.replace(record, x=repair_spikes(record.x, found, "x"),
                                     v=None if record.v is None else repair_spikes(record.v, found, "v"))
    r = uniform_record(record, dt)
    dt_r = r.dt if dt is None else float(dt)
    cmd = np.array(r.command, dtype=np.float64)
    n_out = int(np.count_nonzero((cmd < command.v_min) | (cmd > command.v_max)))
    if command_range == "clip":
        cmd = np.clip(cmd, command.v_min, command.v_max)
    elif command_range == "raise":
        command.check_command(cmd, f"command of record {record.label!r}")
    v = np.array(r.velocity(), dtype=np.float64)
    a = np.gradient(v, dt_r, edge_order=2)
    warmup = float(warmup)
    if not (math.isfinite(warmup) and warmup >= 0):
        raise ValueError(f"warmup = {shown(warmup)} is invalid: must be >= 0 s")
    mask = (r.t - r.t[0]) >= warmup - 1e-12 * dt_r
    force, partner = shift_channel(np.array(r.force), offset)
    mask &= partner
    if found:
        bad = excluded(r.t, found)
        mask &= ~bad
        warnings.warn(describe_faults(record.label, found, int(bad.sum()), r.n), FaultsExcluded, stacklevel=3)
    if np.count_nonzero(mask) < 3:
        causes = [c for c, on in ((f"a warm-up of {warmup:g} s", warmup > 0),
                                  (f"a force offset of {offset} samples", offset != 0), ("its faults", bool(found)))
                  if on]
        raise ValueError(f"fewer than 3 samples of record {record.label!r} ({r.duration:g} s long) are left to score "
                         f"after {' and '.join(causes) or 'preparation'}")
    series = DamperRecord(r.t, r.x, cmd, force, v, r.command_unit, r.label)
    return PreparedRecord(series, dt_r, a, mask, n_out if command_range == "clip" else 0, found, int(offset))


def excluded(t: np.ndarray, found) -> np.ndarray:
    """The samples at times ``t`` that the faults ``found`` leave out of a fit and its measures (by time, with
    :data:`FAULT_MARGIN` on both sides: the uniform grid may differ from the file's)."""
    bad = np.zeros(t.size, dtype=bool)
    for f in found:
        bad |= (t >= f.start - FAULT_MARGIN) & (t <= f.end + FAULT_MARGIN)
    return bad


def shift_channel(a: np.ndarray, offset: int) -> tuple[np.ndarray, np.ndarray]:
    """(a[k + offset] for every k, the mask of the k that have such a sample); ends padded with the edge value."""
    offset = int(offset)
    n = a.size
    if abs(offset) >= n - 2:
        raise ValueError(f"offset = {offset} is invalid: must be shorter than the record ({n} samples)")
    idx = np.arange(n) + offset
    ok = (idx >= 0) & (idx < n)
    return a[np.clip(idx, 0, n - 1)], ok
