"""The options of a fit, in two groups: how the optimiser searches (:class:`SearchOptions`) and how the records are
prepared and scored (:class:`DataOptions`).

Each function that takes them accepts ``None`` (the defaults), an instance, or a dict of field overrides
(:func:`as_options`), so ``fit_model(..., search={"maxiter": 20})`` works as well.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..validation import shown
from .prepare import FAULT_MODES

METHODS = ("least_squares", "differential_evolution", "pso", "adam")
DEFAULT_MAXITER = {"least_squares": 200, "differential_evolution": 60, "pso": 60, "adam": 150}


def _check_count(name: str, value) -> None:
    if value is None:
        return
    try:
        ok = not isinstance(value, bool) and int(value) == value and value >= 1
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise ValueError(f"{name} = {shown(value)} is invalid: must be an int >= 1 (or None for the default)")


@dataclass(frozen=True)
class SearchOptions:
    """How the optimiser searches (see :mod:`mrd_env.identification.fit`).

    ``method``: "least_squares", "differential_evolution" or "pso" (parametric models); "adam" (the neural
    model, :mod:`.neural`; the only method it takes). ``seed``: of every random choice; results are
    bit-reproducible. ``maxiter``: least squares — residual evaluations (200); DE/PSO — generations (60);
    adam — epochs (150). ``popsize``: DE population multiplier (10) / PSO swarm size (10 × free parameters, at
    least 20). ``tol``: least squares ftol = xtol (1e-8), DE tol (0.01), PSO ftol (1e-6). ``diff_step`` and
    ``jacobian`` ("central"/"forward"): the least-squares finite differences in the [0, 1] scale of the bounds.
    ``bound_factor``: f of the default bounds. ``progress``: tqdm progress bars.
    """

    method: str = "least_squares"
    seed: int = 0
    maxiter: int | None = None
    popsize: int | None = None
    tol: float | None = None
    diff_step: float = 1e-3
    jacobian: str = "central"
    bound_factor: float = 10.0
    progress: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise ValueError(f"method = {shown(self.method)} is invalid: must be one of {list(METHODS)}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed = {shown(self.seed)} is invalid: must be a non-negative int")
        _check_count("maxiter", self.maxiter)
        _check_count("popsize", self.popsize)
        if self.jacobian not in ("central", "forward"):
            raise ValueError(f"jacobian = {shown(self.jacobian)} is invalid: must be 'central' or 'forward'")
        if not (isinstance(self.diff_step, (int, float)) and 0 < self.diff_step < 0.25):
            raise ValueError(f"diff_step = {shown(self.diff_step)} is invalid: must be in (0, 0.25)")
        f = self.bound_factor
        if not (isinstance(f, (int, float)) and math.isfinite(f) and f > 1):
            raise ValueError(f"bound_factor = {shown(f)} is invalid: must be > 1")

    @property
    def iterations(self) -> int:
        return DEFAULT_MAXITER[self.method] if self.maxiter is None else int(self.maxiter)


@dataclass(frozen=True)
class DataOptions:
    """How records are prepared and scored (:func:`~mrd_env.identification.prepare.prepare_record`).

    ``dt``: the simulation step (s) records are put on (None: each record's mean interval). ``warmup`` (s): left
    out of the objective at the start of each record. ``command_range``: commands outside the channel's range —
    "clip", "raise" or "widen" (the fitted damper's range covers the records). ``faults``: "exclude" (default),
    "keep" or "raise" (:mod:`.faults`). ``align``: estimate and correct a constant sample offset between the
    force and the motion channels (:mod:`.align`); ``offset``: impose one (samples, force lagging; overrides
    ``align``). ``normalize``: divide each record's J2 by the standard deviation of its measured force.
    ``weighting``: "record" — Σ_r w_r J2_r, every record counts the same; "sample" — all samples pooled (the
    maximum-likelihood choice for white force noise of one level).
    """

    dt: float | None = None
    warmup: float = 0.0
    command_range: str = "clip"
    faults: str = "exclude"
    align: bool = False
    offset: int | None = None
    normalize: bool = False
    weighting: str = "record"

    def __post_init__(self) -> None:
        if self.dt is not None and not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt = {shown(self.dt)} is invalid: must be > 0 s (or None)")
        try:
            w = float(self.warmup)
        except (TypeError, ValueError, OverflowError):
            w = math.nan
        if not (math.isfinite(w) and w >= 0):
            raise ValueError(f"warmup = {shown(self.warmup)} is invalid: must be >= 0 s")
        if not isinstance(self.command_range, str) or self.command_range not in ("clip", "raise", "widen"):
            raise ValueError(f"command_range = {shown(self.command_range)} is invalid: must be 'clip', 'raise' or "
                             "'widen'")
        if self.faults not in FAULT_MODES:
            raise ValueError(f"faults = {shown(self.faults)} is invalid: must be one of {list(FAULT_MODES)}")
        if self.offset is not None and (isinstance(self.offset, bool)
                                        or not isinstance(self.offset, (int, np.integer))):
            raise ValueError(f"offset = {shown(self.offset)} is invalid: must be an int number of samples (or None)")
        if self.weighting not in ("record", "sample"):
            raise ValueError(f"weighting = {shown(self.weighting)} is invalid: must be 'record' or 'sample'")

    def prepare_kwargs(self) -> dict:
        """The keyword arguments of ``prepare_record`` (without the offset)."""
        return {"dt": self.dt, "command_range": self.command_range, "warmup": self.warmup, "faults": self.faults}


def as_options(cls, value, name: str):
    """``value`` as a ``cls`` instance: None → defaults, an instance, or a dict of field overrides."""
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        valid = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(value) - set(valid), key=repr)
        if unknown:
            raise ValueError(f"{name} has unknown key(s) {unknown}; valid keys: {valid}")
        return cls(**value)
    raise ValueError(f"{name} must be a {cls.__name__} or a dict of its fields, got {type(value).__name__}")
