"""The outcome of a fit and the error measures of a model on prepared records."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..dampers import CommandSpec, DamperModel
from .measures import error_measures, scored_intervals
from .parameters import COMMAND_PARAMS, initial_values
from .prepare import PreparedRecord

# a fitted value sits on a bound when it is within this fraction of the bounds' span of it (the optimisers work on
# the bounds scaled to [0, 1]: 1e-3 there is below any step that still improves the fit) ...
BOUND_RTOL = 1e-3
# ... and, for a bound other than 0, within this fraction of the bound itself (so that 301 is not "at" a bound of
# 1 in a span of 1e200, while k0 = 469.6 N/m against a bound of 469 N/m is)
BOUND_REL = 1e-2


class ParameterAtBound(UserWarning):
    """A parameter was fitted onto one of its bounds: the best fit may lie beyond it."""


class FitInterrupted(KeyboardInterrupt):
    """A fit stopped by Ctrl-C or SIGTERM: ``result`` is the :class:`FitResult` of the best parameters found so far
    (not converged), for the caller to save; ``__cause__`` is the interruption itself."""

    def __init__(self, result: "FitResult"):
        super().__init__(f"fit of {result.model} interrupted after {result.n_evaluations} evaluations")
        self.result = result


@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of :func:`fit_model` (SI units throughout).

    ``per_record``: one dict per record with its label, samples and the measures E_t, E_x, E_v (ratios), J1
    (N²), J2 (N) of the fitted model; ``overall``: J1 summed, J2 pooled over all samples, E_* as the
    duration-weighted RMS of the per-record values. ``objective`` / ``initial_objective``: Σ_r w_r J2_r at the
    fitted parameters and at the initial guess. ``n_evaluations`` counts candidate parameter vectors simulated
    (every Jacobian column and population member counts one); ``history`` the best objective after each
    iteration (generation). For the neural model (``model == "neural"``, ``damper`` a
    :class:`~.neural.NeuralForwardModel`) ``params``/``free`` are empty, the objectives are the training loss
    (mean squared standardised force error) per epoch, and ``n_evaluations`` counts sample presentations.
    ``settings["offsets"]``: the force offset (samples) used on each record.
    """

    model: str
    damper: DamperModel
    params: dict[str, float]
    initial: dict[str, float]
    free: tuple[str, ...]
    bounds: dict[str, tuple[float, float]]
    fixed: dict[str, str]
    method: str
    seed: int
    objective: float
    initial_objective: float
    per_record: list[dict]
    overall: dict[str, float]
    wall_time: float
    n_evaluations: int
    n_iterations: int
    converged: bool
    message: str
    history: tuple[float, ...] = ()
    n_infeasible: int = 0
    n_diverged: int = 0
    records: tuple[dict, ...] = ()
    settings: dict = field(default_factory=dict)

    @property
    def n_free(self) -> int:
        """Free parameters of a parametric model; weights of a network."""
        return int(self.settings.get("n_weights", len(self.free)))

    @property
    def command(self) -> CommandSpec:
        return self.damper.command

    def free_values(self) -> dict[str, float]:
        d = initial_values(self.damper.params, self.damper.command) if self.params else {}
        return {k: d[k] for k in self.free}

    def bound_status(self) -> dict[str, str]:
        """{free parameter: "at lower bound" or "at upper bound"} for those fitted onto a bound (within
        :data:`BOUND_RTOL` of the bounds' span, and :data:`BOUND_REL` of the bound itself unless it is 0); the
        others are not listed."""
        out = {}
        for k, v in self.free_values().items():
            lo, hi = self.bounds[k]
            for where, b in (("at lower bound", lo), ("at upper bound", hi)):
                if abs(v - b) <= BOUND_RTOL * (hi - lo) and (b == 0 or abs(v - b) <= BOUND_REL * abs(b)):
                    out[k] = where
        return out

    def bound_messages(self) -> list[str]:
        """One sentence per parameter fitted onto a bound (see :meth:`bound_status`)."""
        units = self.damper.Params.units() if self.free else {}
        out = []
        for k, where in self.bound_status().items():
            unit = units.get(k) or COMMAND_PARAMS[k][1]
            unit = "" if unit in ("", "-") else f" {unit}"
            bound = self.bounds[k][0 if where == "at lower bound" else 1]
            out.append(f"{self.model}: {k} = {self.free_values()[k]:.6g}{unit} is {where} ({bound:.6g}{unit}): "
                       "the best fit may lie beyond it (widen its bounds)")
        return out

    def summary(self) -> str:
        o = self.overall
        lines = [f"{self.model} fitted by {self.method} (seed {self.seed}) on {len(self.per_record)} record(s): "
                 f"E_t = {100 * o['E_t']:.2f} %, E_x = {100 * o['E_x']:.2f} %, E_v = {100 * o['E_v']:.2f} %, "
                 f"J2 = {o['J2']:.4g} N; objective {self.initial_objective:.4g} → {self.objective:.4g}; "
                 f"{self.n_evaluations} evaluations, {self.wall_time:.1f} s; {self.message}"]
        units = self.damper.Params.units() if self.free else {}
        status = self.bound_status()
        for k in self.free:
            v = self.free_values()[k]
            unit = units.get(k) or COMMAND_PARAMS[k][1]
            flag = f"  {status[k]}" if k in status else ""
            lines.append(f"  {k:10s} = {v:.6g} {unit}  (initial {self._initial_of(k):.6g}){flag}")
        return "\n".join(lines)

    def _initial_of(self, k):
        return self.initial.get(k, float("nan"))


def record_measures(prep: PreparedRecord, F_model: np.ndarray, sl=None) -> dict:
    """The measures of one record on its scored samples (``sl``, default the prepared mask): the integrals run over
    the steps between two scored samples, so that an excluded span (a fault, the warm-up, the fit part) is not
    bridged; ``duration_s`` is the time they cover."""
    m = prep.mask if sl is None else sl
    t = prep.series.t
    em = error_measures(prep.series.force, F_model, t, v=prep.series.v, mask=m)
    return {"record": prep.series.label, "n": int(np.count_nonzero(m)),
            "duration_s": float(scored_intervals(t, m).sum()), **em}


def pooled_measures(rows: Sequence[dict]) -> dict[str, float]:
    """Overall measures of several records' rows (see :class:`FitResult`)."""
    T = np.array([r["duration_s"] for r in rows])
    n = np.array([r["n"] for r in rows])
    out = {}
    for k in ("E_t", "E_x", "E_v"):
        e = np.array([r[k] for r in rows])
        out[k] = float(np.sqrt(np.sum(T * e ** 2) / np.sum(T))) if T.sum() > 0 else float(e.mean())
    out["J1"] = float(sum(r["J1"] for r in rows))
    out["J2"] = float(math.sqrt(out["J1"] / n.sum()))
    return out


def record_info(preps: list[PreparedRecord]) -> tuple[dict, ...]:
    """What a fit result keeps about each record: label, size, grid, clipped commands, faults and offset."""
    return tuple({"label": p.series.label, "n": p.series.n, "dt_s": p.dt, "t0_s": float(p.series.t[0]),
                  "duration_s": p.series.duration, "commands_clipped": p.n_clipped, "offset_samples": p.offset,
                  "faults": [str(f) for f in p.faults], "samples_scored": int(p.mask.sum())} for p in preps)
