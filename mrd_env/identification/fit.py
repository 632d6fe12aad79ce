"""Parameter identification: fit any registered damper model to measured records (review section 4).

The model is driven, on each record's own uniform time grid, by the record's measured stroke x, velocity
(measured if present, else dx/dt) and command, exactly as the virtual rig would drive it, and its force is
compared with the measured one. The objective is the review's J2 (eq. 26, RMS force error in N) summed over
the records, each optionally divided by the standard deviation of its measured force (``normalize=True``,
which makes every record's term an E_t-like ratio)::

    objective = Σ_r w_r J2_r,     J2_r = sqrt(mean_k (F_model − F_measured)²)

(``weighting="sample"`` pools the samples instead: sqrt(Σ_r w_r² Σ_k e² / Σ_r N_r), every sample counting
the same — the maximum-likelihood choice for white force noise of one level.)

Three optimisers, all deterministic for a given ``seed`` (bit for bit: the stepping routine is), all inside
the parameter bounds, all with a tqdm progress bar:

* ``"least_squares"`` — bounded nonlinear least squares, ``scipy.optimize.least_squares`` (trust-region
  reflective) on the residual vector (w_r (F_model − F_measured)/sqrt(N_r)); it minimises Σ_r (w_r J2_r)²,
  the same minimiser as the objective for one record (with ``weighting="sample"``: exactly the square of the
  pooled objective). Parameters are scaled to [0, 1] by their bounds; the Jacobian is a central difference
  in that scale (one-sided at a bound), its columns simulated as one batch.
* ``"differential_evolution"`` — ``scipy.optimize.differential_evolution`` with ``vectorized=True``: each
  generation is one batched simulation of the whole population (``integrator.run``'s per-system P).
* ``"pso"`` — particle swarm from pymoo (``pymoo.algorithms.soo.nonconvex.pso.PSO``, an optional
  dependency), one batched simulation per swarm generation.

Constraints: every bound lies inside the parameter's declared valid range, and a candidate that the
parameter dataclass rejects (its ``check()`` cross-field constraints, e.g. β + γ > 0) or whose simulation
diverges (:class:`~mrd_env.errors.SimulationDivergedError`) is infeasible: it gets the penalty objective
``PENALTY`` × Σ_r w_r RMS(F_r) instead of a crash.

Free parameters: by default all parameters except the ones fixed by :func:`fixed_by_default` — the Bouc–Wen
exponent n (a shape choice), the Bouc–Wen A when α, β, γ are present ((α, A, β, γ) → (α/s, s A, β/sⁿ, γ/sⁿ)
leaves the force unchanged, so one of the four must be fixed), smoothing scales of sign functions (e.g. v_s;
a regularisation, not physics), internal filter time constants, conditions of the test (excitation amplitude
or frequency), and parameters that are exactly zero in the preset (structurally absent). A model class may
set ``fit_fixed = {"name": "reason", ...}`` to declare its own. The command lag rate η of the
command channel can be fitted too, under the name ``"command_eta"``.

Default bounds: (p0/f, p0·f) around the initial value p0 > 0 (f = ``bound_factor``, 10), (p0·f, p0/f) for
p0 < 0, and p0 ± f|p0| for a parameter whose valid range has no lower limit (so it may change sign, e.g. x0),
always intersected with the declared valid range.

Presets: :func:`save_preset` / :func:`load_preset` write and read JSON (model, SI parameters with units,
command channel, provenance); floats are written with ``repr`` and come back exactly equal.
"""
from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..dampers import CommandSpec, DamperModel, damper_class
from ..errors import SimulationDivergedError
from ..integrator import Stepper, SystemMatrices
from .data import DamperRecord
from .measures import error_measures

__all__ = ["FitResult", "fit_model", "fixed_by_default", "default_bounds", "uniform_record", "prepare_record",
           "predict", "sensitivity", "pooled_measures", "save_preset", "load_preset", "read_preset", "METHODS",
           "PENALTY", "COMMAND_ETA"]

METHODS = ("least_squares", "differential_evolution", "pso")
PENALTY = 1.0e3          # infeasible/diverged candidates: objective = PENALTY × Σ_r w_r RMS(F_measured,r)
COMMAND_ETA = "command_eta"  # pseudo-parameter: the command channel's lag rate η (1/s)
_CHUNK = 32              # candidates per compiled call (bounds the memory of long records)
_DEFAULT_MAXITER = {"least_squares": 200, "differential_evolution": 60, "pso": 60}
PRESET_FORMAT = "mrd-env-preset"


# --- records on a uniform grid ---------------------------------------------------------------------------------

def _as_record(rec: Any, i: int) -> DamperRecord:
    """A DamperRecord from a DamperRecord or any object with t, x, command, force (and v) arrays (a RigResult,
    a SensorReadout...); constructing the DamperRecord validates it (NaN, lengths, increasing time)."""
    if isinstance(rec, DamperRecord):
        return rec
    try:
        return DamperRecord(rec.t, rec.x, rec.command, rec.force, getattr(rec, "v", None),
                            getattr(rec, "command_unit", "V"), getattr(rec, "label", "") or f"record {i}")
    except AttributeError:
        raise ValueError(f"records[{i}] must be a DamperRecord (or have t, x, command, force arrays), got "
                         f"{type(rec).__name__}") from None


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
        raise ValueError(f"dt = {dt!r} is invalid: must be > 0 s")
    grid = record.t[0] + dt * np.arange(record.n)
    if np.abs(record.t - grid).max() <= 0.5 * dt:
        if np.array_equal(grid, record.t):
            return record
        return DamperRecord(grid, record.x, record.command, record.force, record.v, record.command_unit,
                            record.label)
    try:
        return record.resample(dt)
    except ValueError:
        if dt > 0.5 * record.duration:
            raise
        # a non-uniform record cannot be low-pass filtered on its own grid: interpolate only
        return record.resample(dt, antialias=False)


@dataclass(frozen=True, eq=False)
class PreparedRecord:
    """A record ready to drive a model: uniform grid, velocity, acceleration, command in the admissible range,
    and the mask of samples that enter the objective (after ``warmup``)."""

    record: DamperRecord
    dt: float
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    command: np.ndarray
    force: np.ndarray
    mask: np.ndarray
    n_clipped: int = 0

    @property
    def label(self) -> str:
        return self.record.label

    @property
    def n(self) -> int:
        return self.record.n


def prepare_record(record: DamperRecord, command: CommandSpec, *, dt: float | None = None,
                   command_range: str = "clip", warmup: float = 0.0) -> PreparedRecord:
    """Put ``record`` on a uniform grid (:func:`uniform_record`) and check its command against ``command``.

    ``command_range``: "clip" — commands outside [v_min, v_max] are clipped to the range (the count is kept
    in ``n_clipped``); "raise" — ``ValueError``; "widen" — keep them (the caller widens the channel's range,
    see :func:`fit_model`). ``warmup`` (s): the first samples, where the model's states (started at rest) have
    not yet forgotten their initial values, are simulated but left out of the objective and of the measures.
    """
    if command_range not in ("clip", "raise", "widen"):
        raise ValueError(f"command_range = {command_range!r} is invalid: must be 'clip', 'raise' or 'widen'")
    if record.command_unit != command.unit:
        raise ValueError(f"record {record.label!r} has commands in {record.command_unit} but the damper's "
                         f"command channel is in {command.unit}")
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
        raise ValueError(f"warmup = {warmup!r} is invalid: must be >= 0 s")
    mask = (r.t - r.t[0]) >= warmup - 1e-12 * dt_r
    if np.count_nonzero(mask) < 3:
        raise ValueError(f"warmup = {warmup:g} s leaves fewer than 3 samples of record {record.label!r} "
                         f"({r.duration:g} s long)")
    return PreparedRecord(r, dt_r, np.array(r.x), v, a, cmd, np.array(r.force), mask,
                          n_out if command_range == "clip" else 0)


# --- batched simulation -----------------------------------------------------------------------------------------

_RIG = SystemMatrices.displacement_driven()


def _simulate_batch(cls, command: CommandSpec, prep: PreparedRecord, P: np.ndarray, eta: np.ndarray,
                    Y0: np.ndarray, integrator_options: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """Forces (S, n) of S parameter vectors P (S, n_params) on one record, and a mask of the runs that did not
    diverge (their rows are NaN). One compiled call per chunk of candidates; a diverging candidate stops alone,
    the others of its chunk run on."""
    S = P.shape[0]
    n = prep.n
    F = np.full((S, n), np.nan)
    ok = np.ones(S, dtype=bool)
    if S == 0:
        return F, ok
    W1 = np.stack([prep.x, prep.v, prep.a], axis=1)
    V1 = prep.command[:-1, None]
    damper = _template(cls, command)
    for c0 in range(0, S, _CHUNK):
        sl = slice(c0, min(S, c0 + _CHUNK))
        m = sl.stop - c0
        lag = np.broadcast_to(command.lag_vector(), (m, 1, 3)).copy()
        lag[:, 0, 0] = eta[sl]
        st = Stepper(damper, _RIG, m, n - 1, prep.dt, P=P[sl, None, :], lag=lag, **integrator_options)
        st.Y = np.array(Y0[sl], dtype=np.float64)
        st.U = np.full((m, 1), prep.command[0])
        Fc, _, good = st.advance(np.broadcast_to(V1, (m,) + V1.shape), np.broadcast_to(W1, (m,) + W1.shape))
        F[sl, 1:] = np.where(good[:, None], Fc[:, :, 0], np.nan)
        ok[sl] = good
    # force at t0 from the initial state switched to the initial motion (as the rig does), then the
    # end-of-step forces
    for i in range(S):
        if ok[i]:
            s0 = np.array(Y0[i], dtype=np.float64)
            cls.project(P[i], s0, prep.x[0], prep.v[0], prep.command[0])
            F[i, 0] = cls.force_law(P[i], s0, prep.x[0], prep.v[0], prep.a[0], prep.command[0])
    ok &= np.all(np.isfinite(F), axis=1)
    return F, ok


_TEMPLATES: dict = {}


def _template(cls, command: CommandSpec) -> DamperModel:
    """A damper instance of ``cls`` for the Stepper's bookkeeping (name, states, η); P overrides its params."""
    key = (cls, command)
    d = _TEMPLATES.get(key)
    if d is None:
        d = _TEMPLATES[key] = cls(None, command)
    return d


def predict(damper: DamperModel, record: DamperRecord | PreparedRecord, *, dt: float | None = None,
            command_range: str = "clip", **integrator_options) -> tuple[PreparedRecord, np.ndarray]:
    """(prepared record, model force in N) for ``damper`` driven by ``record`` on its uniform grid.

    Raises :class:`~mrd_env.errors.SimulationDivergedError` if the simulation diverges.
    """
    prep = record if isinstance(record, PreparedRecord) else prepare_record(
        _as_record(record, 0), damper.command, dt=dt, command_range=command_range)
    cls = type(damper)
    P = damper.params.as_array()[None, :]
    F, ok = _simulate_batch(cls, damper.command, prep, P, np.array([damper.command.eta]),
                            damper.initial_state()[None, :], integrator_options)
    if not ok[0]:
        raise SimulationDivergedError(f"damper model {damper.name!r} diverged on record {prep.label!r}",
                                      model=damper.name)
    return prep, F[0]


# --- free parameters and bounds ---------------------------------------------------------------------------------

_GENERIC_FIXED = {
    "n": "Bouc–Wen exponent: a shape choice, kept fixed (n = 2 in the presets)",
}
# parameters recognised by their documentation (DamperParams field metadata "doc")
_DOC_RULES = (
    ("smoothed", "smoothing scale of a sign function: a numerical regularisation, not a damper property"),
    ("velocity filter", "time constant of an internal velocity filter: an estimator setting, not a damper "
                        "property"),
    ("known a priori", "a condition of the test (set it to the record's value), not a damper property"),
    ("of the excitation", "a condition of the test (set it to the record's value), not a damper property"),
)
_A_REASON = ("Bouc–Wen scaling redundancy: (α, A, β, γ) → (α/s, s·A, β/sⁿ, γ/sⁿ) gives the same force, so one of "
             "them is fixed")


def fixed_by_default(model: str | type | DamperModel, params=None) -> dict[str, str]:
    """Parameters that :func:`fit_model` keeps fixed unless named in ``free``, with the reason for each.

    Generic rules: the Bouc–Wen exponent ``n``; ``A`` when the model also has ``beta`` and ``gamma``; and
    parameters whose declared doc says they are a smoothing scale ("smoothed"), an internal velocity filter
    ("velocity filter") or a condition of the test ("known a priori", "of the excitation"). A model class may
    declare ``fit_fixed`` (dict name → reason, or a sequence of names) to replace the generic rules.
    Parameters equal to zero in ``params`` (the preset) are added.
    """
    cls = _model_class(model)
    names = cls.Params.names()
    declared = getattr(cls, "fit_fixed", None)
    if declared is not None:
        fixed = dict(declared) if isinstance(declared, Mapping) else {k: "declared by the model" for k in declared}
    else:
        fixed = {k: v for k, v in _GENERIC_FIXED.items() if k in names}
        if {"A", "beta", "gamma"} <= set(names):
            fixed["A"] = _A_REASON
        for f in dataclasses.fields(cls.Params):
            doc = f.metadata.get("doc", "")
            for key, reason in _DOC_RULES:
                if key in doc and f.name not in fixed:
                    fixed[f.name] = reason
    if params is not None:
        for k, v in params.to_dict().items():
            if v == 0.0 and k not in fixed:
                fixed[k] = "zero in the preset (structurally absent): name it in free and give bounds to fit it"
    return fixed


def default_bounds(model: str | type | DamperModel, name: str, value: float,
                   bound_factor: float = 10.0) -> tuple[float, float]:
    """Default bounds of parameter ``name`` around its initial ``value`` (see the module docstring)."""
    cls = _model_class(model)
    f = float(bound_factor)
    if not (math.isfinite(f) and f > 1):
        raise ValueError(f"bound_factor = {bound_factor!r} is invalid: must be > 1")
    lo_valid, hi_valid, _ = _valid_range(cls, name)
    v = float(value)
    if v == 0.0:
        raise ValueError(f"parameter {name!r} is 0 in the initial guess: give its bounds explicitly")
    if math.isinf(lo_valid):
        lo, hi = v - f * abs(v), v + f * abs(v)
    elif v > 0:
        lo, hi = v / f, v * f
    else:
        lo, hi = v * f, v / f
    return max(lo, lo_valid), min(hi, hi_valid)


def _valid_range(cls, name: str) -> tuple[float, float, bool]:
    if name == COMMAND_ETA:
        return 0.0, math.inf, True
    f = {fl.name: fl for fl in dataclasses.fields(cls.Params)}[name]
    return f.metadata["lo"], f.metadata["hi"], f.metadata["lo_open"]


def _make_params(cls, p: np.ndarray):
    """The model's parameter dataclass from a vector in declaration order (fields may be keyword-only)."""
    return cls.Params(**{k: float(v) for k, v in zip(cls.Params.names(), p)})


def _model_class(model) -> type:
    if isinstance(model, str):
        return damper_class(model)
    if isinstance(model, DamperModel):
        return type(model)
    if isinstance(model, type) and issubclass(model, DamperModel):
        return model
    raise ValueError(f"model must be a registered model name or a DamperModel, got {model!r}")


# --- the fitting problem ----------------------------------------------------------------------------------------

class _Problem:
    """Free parameters scaled to [0, 1] by their bounds → objective / residuals on all records."""

    def __init__(self, cls, base_params, command: CommandSpec, free: Sequence[str], lo, hi,
                 preps: Sequence[PreparedRecord], normalize: bool, integrator_options: Mapping,
                 weighting: str = "record"):
        self.cls = cls
        self.command = command
        self.names = cls.Params.names()
        self.base = base_params.as_array()
        self.free = tuple(free)
        self.idx = [self.names.index(k) if k != COMMAND_ETA else -1 for k in self.free]
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        self.preps = list(preps)
        self.integrator_options = dict(integrator_options)
        self.meas = [p.force[p.mask] for p in self.preps]
        self.n_obj = [m.size for m in self.meas]
        rms = [float(np.sqrt(np.mean(m ** 2))) for m in self.meas]
        if normalize:
            std = [float(np.std(m)) for m in self.meas]
            for p, s in zip(self.preps, std):
                if not s > 0:
                    raise ValueError(f"normalize=True needs a varying measured force; record {p.label!r} has a "
                                     "constant force")
            self.w = [1.0 / s for s in std]
        else:
            self.w = [1.0] * len(self.preps)
        self.rms = rms
        self.pooled = weighting == "sample"
        self.penalty = PENALTY * sum(w * (r + 1e-300) for w, r in zip(self.w, rms))
        self.n_evaluations = 0
        self.n_infeasible = 0
        self.n_diverged = 0
        self.best = math.inf
        self.best_theta = None

    # scaling
    def decode(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = np.clip(np.atleast_2d(np.asarray(theta, dtype=np.float64)), 0.0, 1.0)
        vals = self.lo + theta * (self.hi - self.lo)
        P = np.tile(self.base, (theta.shape[0], 1))
        eta = np.full(theta.shape[0], self.command.eta)
        for j, i in enumerate(self.idx):
            if i < 0:
                eta[:] = vals[:, j]
            else:
                P[:, i] = vals[:, j]
        return P, eta

    def encode(self, values: Sequence[float]) -> np.ndarray:
        return (np.asarray(values, dtype=np.float64) - self.lo) / (self.hi - self.lo)

    def _feasible(self, p: np.ndarray, eta: float):
        try:
            params = _make_params(self.cls, p)
            if not (math.isfinite(eta) and eta > 0):
                raise ValueError("eta must be > 0")
            return self.cls(params, self.command)
        except ValueError:
            return None

    def simulate(self, theta: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """Per record: model forces (S, n_masked); and the mask of feasible, non-diverged candidates."""
        P, eta = self.decode(theta)
        S = P.shape[0]
        self.n_evaluations += S
        dampers = [self._feasible(P[i], eta[i]) for i in range(S)]
        feas = np.array([d is not None for d in dampers], dtype=bool)
        self.n_infeasible += int(S - feas.sum())
        good = feas.copy()
        out = []
        sel = np.flatnonzero(feas)
        ns = len(self.cls.state_names)
        Y0 = np.zeros((S, ns))
        for i in sel:
            Y0[i] = dampers[i].initial_state()
        for prep in self.preps:
            Fr = np.full((S, int(prep.mask.sum())), np.nan)
            if sel.size:
                F, ok = _simulate_batch(self.cls, self.command, prep, P[sel], eta[sel], Y0[sel],
                                        self.integrator_options)
                Fr[sel] = F[:, prep.mask]
                good[sel[~ok]] = False
            out.append(Fr)
        self.n_diverged += int(feas.sum() - good.sum())
        return out, good

    def _J(self, forces, good) -> np.ndarray:
        if self.pooled:  # J2 of all samples pooled: sqrt(Σ_r w_r² Σ_k e² / Σ_r N_r)
            sse = sum(w * w * np.sum((Fr - m) ** 2, axis=1) for Fr, m, w in zip(forces, self.meas, self.w))
            J = np.sqrt(sse / sum(self.n_obj))
        else:  # Σ_r w_r J2_r
            J = sum(w * np.sqrt(np.mean((Fr - m) ** 2, axis=1)) for Fr, m, w in zip(forces, self.meas, self.w))
        J = np.array(J, dtype=np.float64)
        J[~good] = self.penalty
        return J

    def objective(self, theta: np.ndarray) -> np.ndarray:
        """The objective for each row of theta (S, k); the penalty for infeasible or diverged candidates."""
        theta = np.atleast_2d(theta)
        forces, good = self.simulate(theta)
        J = self._J(forces, good)
        self._track(theta, J)
        return J

    def residuals(self, theta: np.ndarray, return_good: bool = False):
        """Residual vectors (S, Σ N_r): w_r (F_model − F_measured)/sqrt(N_r), constant penalty if infeasible
        (and the mask of feasible, non-diverged candidates if ``return_good``)."""
        theta = np.atleast_2d(theta)
        forces, good = self.simulate(theta)
        parts = []
        total = sum(self.n_obj)
        for Fr, m, w, n, rms in zip(forces, self.meas, self.w, self.n_obj, self.rms):
            scale = math.sqrt(total if self.pooled else n)
            R = w * (Fr - m) / scale
            R[~good] = w * PENALTY * (rms + 1e-300) / scale
            parts.append(R)
        R = np.concatenate(parts, axis=1)
        J = self._J(forces, good)
        self._track(theta, J)
        return (R, good) if return_good else R

    def _track(self, theta, J):
        i = int(np.argmin(J))
        if J[i] < self.best:
            self.best = float(J[i])
            self.best_theta = np.array(theta[i], dtype=np.float64)


# --- result -----------------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of :func:`fit_model` (SI units throughout).

    ``per_record``: one dict per record with its label, samples and the measures E_t, E_x, E_v (ratios), J1
    (N²), J2 (N) of the fitted model; ``overall``: J1 summed, J2 pooled over all samples, E_* as the
    duration-weighted RMS of the per-record values. ``objective`` / ``initial_objective``: Σ_r w_r J2_r at the
    fitted parameters and at the initial guess. ``n_evaluations`` counts candidate parameter vectors simulated
    (every Jacobian column and population member counts one); ``history`` the best objective after each
    iteration (generation).
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
    def command(self) -> CommandSpec:
        return self.damper.command

    def free_values(self) -> dict[str, float]:
        d = dict(self.params)
        d[COMMAND_ETA] = self.damper.command.eta
        return {k: d[k] for k in self.free}

    def summary(self) -> str:
        o = self.overall
        lines = [f"{self.model} fitted by {self.method} (seed {self.seed}) on {len(self.per_record)} record(s): "
                 f"E_t = {100 * o['E_t']:.2f} %, E_x = {100 * o['E_x']:.2f} %, E_v = {100 * o['E_v']:.2f} %, "
                 f"J2 = {o['J2']:.4g} N; objective {self.initial_objective:.4g} → {self.objective:.4g}; "
                 f"{self.n_evaluations} evaluations, {self.wall_time:.1f} s; {self.message}"]
        units = self.damper.Params.units()
        for k in self.free:
            v = self.free_values()[k]
            lines.append(f"  {k:10s} = {v:.6g} {units.get(k, '1/s')}  (initial {self._initial_of(k):.6g})")
        return "\n".join(lines)

    def _initial_of(self, k):
        return self.settings.get("initial_eta", float("nan")) if k == COMMAND_ETA else self.initial[k]


def _measures(prep: PreparedRecord, F_model: np.ndarray, sl=None) -> dict:
    m = prep.mask if sl is None else sl
    t = prep.record.t[m]
    em = error_measures(prep.force[m], F_model[m], t, v=prep.v[m])
    return {"record": prep.label, "n": int(t.size), "duration_s": float(t[-1] - t[0]), **em}


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


# --- the public fitting function --------------------------------------------------------------------------------

def check_fit_options(method: str = "least_squares", seed: int = 0, *, maxiter: int | None = None,
                      popsize: int | None = None, warmup: float = 0.0, command_range: str = "clip") -> None:
    """``ValueError`` for a bad option of :func:`fit_model` that does not depend on the model: checked before
    any simulation, and once up front by :func:`~mrd_env.identification.compare.compare_models` (where a
    per-model failure would only mark every model's row failed)."""
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method = {method!r} is invalid: must be one of {list(METHODS)}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed = {seed!r} is invalid: must be a non-negative int")
    for name, value in (("maxiter", maxiter), ("popsize", popsize)):
        if value is None:
            continue
        try:
            ok = not isinstance(value, bool) and int(value) == value and value >= 1
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise ValueError(f"{name} = {value!r} is invalid: must be an int >= 1 (or None for the default)")
    try:
        w = float(warmup)
    except (TypeError, ValueError, OverflowError):
        w = math.nan
    if not (math.isfinite(w) and w >= 0):
        raise ValueError(f"warmup = {warmup!r} is invalid: must be >= 0 s")
    if not isinstance(command_range, str) or command_range not in ("clip", "raise", "widen"):
        raise ValueError(f"command_range = {command_range!r} is invalid: must be 'clip', 'raise' or 'widen'")


def fit_model(model_name: str | DamperModel, records, *, preset: str | None = None,
              free: Iterable[str] | None = None, bounds: Mapping[str, tuple[float, float]] | None = None,
              method: str = "least_squares", seed: int = 0, maxiter: int | None = None, progress: bool = True,
              dt: float | None = None, initial: Mapping[str, float] | None = None, normalize: bool = False,
              warmup: float = 0.0, command_range: str = "clip", bound_factor: float = 10.0,
              popsize: int | None = None, tol: float | None = None, diff_step: float = 1e-3,
              jacobian: str = "central", weighting: str = "record",
              integrator_options: Mapping | None = None) -> FitResult:
    """Fit the parameters of a damper model to measured records; see the module docstring.

    Parameters
    ----------
    model_name : a registered model name (``available_dampers()``) or a configured ``DamperModel`` whose
        parameters and command channel are the initial guess (then ``preset`` must be None).
    records : a :class:`DamperRecord` or a sequence of them (or objects with t, x, command, force[, v]).
    preset : the preset that supplies the initial guess and the command channel (default: the model's).
    free : names of the parameters to fit (default: all but :func:`fixed_by_default`); ``"command_eta"``
        adds the command lag rate η.
    bounds : {name: (lo, hi)} in SI units, overriding :func:`default_bounds` for free parameters; must
        contain the initial value and lie inside the parameter's valid range.
    method : "least_squares", "differential_evolution" or "pso".
    seed : seed of the stochastic optimisers (least squares is deterministic); results are bit-reproducible.
    maxiter : least squares: maximum residual evaluations (excluding Jacobian columns; default 200);
        differential evolution / PSO: generations (default 60).
    dt : simulation step (s) = the grid records are put on (default: each record's mean interval, see
        :func:`uniform_record`).
    initial : {name: value} overrides of the initial guess.
    normalize : divide each record's J2 by the standard deviation of its measured force.
    weighting : "record" (default) — the objective is Σ_r w_r J2_r, every record counts the same whatever its
        length; "sample" — the J2 of all samples pooled, sqrt(Σ_r w_r² Σ_k e² / Σ_r N_r), every sample counts
        the same (the maximum-likelihood choice for white force noise of one level across records).
    warmup : seconds at the start of each record left out of the objective (states start at rest).
    command_range : commands outside the channel's [v_min, v_max]: "clip" (default), "raise", or "widen"
        (the fitted damper's command range is widened to cover the records).
    bound_factor : f of the default bounds.
    popsize : population of differential evolution (a multiplier of the free-parameter count, scipy's
        convention; default 10) or swarm size of PSO (default 10 × free parameters, at least 20).
    tol : least squares ftol = xtol (default 1e-8); differential evolution tol (default 0.01); PSO ftol of
        pymoo's default termination (default 1e-6).
    diff_step : finite-difference step of the least-squares Jacobian in the [0, 1] scale of the bounds.
    jacobian : "central" (default; 2 simulations per free parameter and iteration) or "forward" differences.
    integrator_options : passed to the stepping routine (max_substeps, rtol, atol).
    """
    t_start = time.perf_counter()
    check_fit_options(method, seed, maxiter=maxiter, popsize=popsize, warmup=warmup, command_range=command_range)
    if weighting not in ("record", "sample"):
        raise ValueError(f"weighting = {weighting!r} is invalid: must be 'record' or 'sample'")
    if jacobian not in ("central", "forward"):
        raise ValueError(f"jacobian = {jacobian!r} is invalid: must be 'central' or 'forward'")
    seed = int(seed)
    if isinstance(model_name, DamperModel):
        if preset is not None:
            raise ValueError("give either a DamperModel or a preset name, not both")
        cls = type(model_name)
        params0, command = model_name.params, model_name.command
        preset_name = None
    else:
        cls = damper_class(model_name)
        base = cls.preset(preset)
        params0, command = base.params, base.command
        preset_name = preset or cls.default_preset
    names = cls.Params.names()
    valid_names = list(names) + [COMMAND_ETA]
    if initial:
        eta_init = initial.get(COMMAND_ETA)
        ovr = {k: v for k, v in initial.items() if k != COMMAND_ETA}
        params0 = params0.replace(**ovr)
        if eta_init is not None:
            command = dataclasses.replace(command, eta=float(eta_init))
    try:
        cls(params0, command)  # model-level checks (e.g. constraints over the command range)
    except ValueError as exc:
        raise ValueError(f"the initial guess of {cls.name!r} is invalid: {exc}") from None
    fixed = fixed_by_default(cls, params0)
    if free is None:
        free_t = tuple(k for k in names if k not in fixed)
    else:
        if isinstance(free, str):
            free = [free]
        free_t = tuple(dict.fromkeys(free))
        unknown = [k for k in free_t if k not in valid_names]
        if unknown:
            raise ValueError(f"unknown parameter name(s) {unknown} in free for model {cls.name!r}; valid: "
                             f"{valid_names}")
    if not free_t:
        raise ValueError("no free parameters to fit")
    bounds = dict(bounds or {})
    unknown = [k for k in bounds if k not in valid_names]
    if unknown:
        raise ValueError(f"unknown parameter name(s) {unknown} in bounds for model {cls.name!r}; valid: "
                         f"{valid_names}")
    not_free = [k for k in bounds if k not in free_t]
    if not_free:
        raise ValueError(f"bounds given for {not_free}, which are not free (free: {list(free_t)}); add them to "
                         f"free to fit them")
    init_vals = {**params0.to_dict(), COMMAND_ETA: command.eta}
    lo, hi, bnd = [], [], {}
    for k in free_t:
        v0 = init_vals[k]
        if k in bounds:
            try:
                b_lo, b_hi = (float(b) for b in bounds[k])
            except (TypeError, ValueError):
                raise ValueError(f"bounds[{k!r}] must be a pair (lo, hi) of numbers, got {bounds[k]!r}") from None
            if not (math.isfinite(b_lo) and math.isfinite(b_hi) and b_lo < b_hi):
                raise ValueError(f"bounds[{k!r}] = ({b_lo!r}, {b_hi!r}) is invalid: need finite lo < hi")
            vlo, vhi, _ = _valid_range(cls, k)
            if b_lo < vlo or b_hi > vhi:
                raise ValueError(f"bounds[{k!r}] = ({b_lo:g}, {b_hi:g}) leave the valid range [{vlo:g}, {vhi:g}] "
                                 f"of parameter {k!r}")
        else:
            b_lo, b_hi = default_bounds(cls, k, v0, bound_factor)
        if not (b_lo <= v0 <= b_hi):
            raise ValueError(f"bounds of parameter {k!r} = ({b_lo:g}, {b_hi:g}) exclude its initial value "
                             f"{v0:g}")
        lo.append(b_lo)
        hi.append(b_hi)
        bnd[k] = (b_lo, b_hi)

    if isinstance(records, (DamperRecord,)) or not isinstance(records, (list, tuple)):
        records = [records]
    if not records:
        raise ValueError("records must not be empty")
    recs = [_as_record(r, i) for i, r in enumerate(records)]
    preps = [prepare_record(r, command, dt=dt, command_range=command_range, warmup=warmup) for r in recs]
    if command_range == "widen":
        cmin = min(command.v_min, *(float(p.command.min()) for p in preps))
        cmax = max(command.v_max, *(float(p.command.max()) for p in preps))
        command = dataclasses.replace(command, v_min=cmin, v_max=cmax)
    opts = dict(integrator_options or {})
    prob = _Problem(cls, params0, command, free_t, lo, hi, preps, normalize, opts, weighting)
    x0 = prob.encode([init_vals[k] for k in free_t])
    maxiter = _DEFAULT_MAXITER[method] if maxiter is None else int(maxiter)
    J0 = float(prob.objective(x0[None, :])[0])
    if J0 >= prob.penalty:
        raise ValueError(f"the initial guess of {cls.name!r} diverges or is infeasible on the records")

    history: list[float] = []
    desc = f"fit {cls.name} ({method})"
    if method == "least_squares":
        theta, nit, converged, message = _run_least_squares(prob, x0, maxiter, tol, diff_step, progress, desc,
                                                             history, central=(jacobian == "central"))
    elif method == "differential_evolution":
        theta, nit, converged, message = _run_de(prob, x0, maxiter, popsize, tol, seed, progress, desc, history)
    else:
        theta, nit, converged, message = _run_pso(prob, x0, maxiter, popsize, tol, seed, progress, desc, history)
    # the best candidate seen is the answer (it is the optimiser's result, or better)
    if prob.best_theta is not None and prob.best < float(prob.objective(theta[None, :])[0]):
        theta = prob.best_theta
    P, eta = prob.decode(theta[None, :])
    fitted_params = _make_params(cls, P[0])
    fitted_cmd = dataclasses.replace(command, eta=float(eta[0]))
    damper = cls(fitted_params, fitted_cmd)
    J = float(prob.objective(theta[None, :])[0])
    per = []
    for prep in preps:
        _, F = predict(damper, prep, **opts)
        per.append(_measures(prep, F))
    wall = time.perf_counter() - t_start
    settings = {"preset": preset_name, "dt": dt, "normalize": bool(normalize), "warmup": float(warmup),
                "command_range": command_range, "bound_factor": float(bound_factor), "maxiter": maxiter,
                "popsize": popsize, "tol": tol, "diff_step": diff_step, "jacobian": jacobian, "weighting": weighting,
                "initial_eta": init_vals[COMMAND_ETA],
                "integrator_options": opts}
    rec_info = tuple({"label": p.label, "n": p.n, "dt_s": p.dt, "t0_s": float(p.record.t[0]),
                      "duration_s": p.record.duration, "commands_clipped": p.n_clipped} for p in preps)
    return FitResult(cls.name, damper, fitted_params.to_dict(), params0.to_dict(), free_t, bnd,
                     {k: v for k, v in fixed.items() if k not in free_t}, method, seed, J, J0, per,
                     pooled_measures(per), wall, prob.n_evaluations, nit, bool(converged), str(message),
                     tuple(history), prob.n_infeasible, prob.n_diverged, rec_info, settings)


def _run_least_squares(prob: _Problem, x0, maxiter, tol, diff_step, progress, desc, history, central=True):
    from scipy.optimize import least_squares
    from tqdm import tqdm

    h = float(diff_step)
    if not (0 < h < 0.25):
        raise ValueError(f"diff_step = {diff_step!r} is invalid: must be in (0, 0.25)")
    tol = 1e-8 if tol is None else float(tol)
    k = x0.size
    bar = tqdm(total=maxiter, desc=desc, unit="eval", disable=not progress, leave=False)
    last: dict = {}

    def fun(x):
        r = prob.residuals(x[None, :])[0]
        last["x"], last["r"] = x.copy(), r
        bar.update(1)
        bar.set_postfix(objective=f"{prob.best:.5g}")
        return r

    def jac(x, *args):
        """Finite differences in the [0, 1] scale, all columns simulated as one batch: central where both
        sides lie inside the bounds (and are feasible), one-sided otherwise."""
        f0 = last["r"] if "x" in last and np.array_equal(last["x"], x) else prob.residuals(x[None, :])[0]
        up = np.minimum(x + h, 1.0) - x
        dn = x - np.maximum(x - h, 0.0)
        X = np.vstack([np.tile(x, (k, 1)), np.tile(x, (k, 1))]) if central else np.tile(x, (k, 1))
        X[np.arange(k), np.arange(k)] += up
        if central:
            X[k + np.arange(k), np.arange(k)] -= dn
        R, good = prob.residuals(X, return_good=True)
        Jm = np.zeros((f0.size, k))
        for j in range(k):
            gu = good[j] and up[j] > 0
            gd = central and good[k + j] and dn[j] > 0
            if gu and gd:
                Jm[:, j] = (R[j] - R[k + j]) / (up[j] + dn[j])
            elif gu:
                Jm[:, j] = (R[j] - f0) / up[j]
            elif gd:
                Jm[:, j] = (f0 - R[k + j]) / dn[j]
            elif not central and dn[j] > 0:  # forward point infeasible or at the bound: try the other side
                xb = x.copy()
                xb[j] -= dn[j]
                rb, gb = prob.residuals(xb[None, :], return_good=True)
                if gb[0]:
                    Jm[:, j] = (f0 - rb[0]) / dn[j]
        history.append(prob.best)
        return Jm

    try:
        res = least_squares(fun, x0, jac=jac, bounds=(np.zeros(k), np.ones(k)), method="trf", x_scale=1.0,
                            max_nfev=maxiter, ftol=tol, xtol=tol, gtol=tol)
    finally:
        bar.close()
    return np.clip(res.x, 0.0, 1.0), int(res.njev or 0), res.status > 0, res.message


def _run_de(prob: _Problem, x0, maxiter, popsize, tol, seed, progress, desc, history):
    from scipy.optimize import differential_evolution
    from tqdm import tqdm

    k = x0.size
    popsize = 10 if popsize is None else int(popsize)
    bar = tqdm(total=maxiter, desc=desc, unit="gen", disable=not progress, leave=False)

    def func(X):  # X has shape (k, S): one batched simulation per generation
        return prob.objective(np.asarray(X).T)

    def callback(intermediate_result):
        history.append(float(intermediate_result.fun))
        bar.update(1)
        bar.set_postfix(objective=f"{intermediate_result.fun:.5g}")

    try:
        res = differential_evolution(func, [(0.0, 1.0)] * k, maxiter=maxiter, popsize=popsize,
                                     tol=0.01 if tol is None else float(tol), rng=np.random.default_rng(seed),
                                     callback=callback, polish=False, init="latinhypercube", updating="deferred",
                                     vectorized=True, x0=x0)
    finally:
        bar.close()
    return np.clip(res.x, 0.0, 1.0), int(res.nit), bool(res.success), res.message


def _pymoo():
    try:
        from pymoo.algorithms.soo.nonconvex.pso import PSO
        from pymoo.core.problem import Problem
        from pymoo.optimize import minimize
        from pymoo.termination.default import DefaultSingleObjectiveTermination
    except ImportError:
        raise ImportError("method='pso' needs the optional dependency pymoo (pip install 'pymoo>=0.6.1')") from None
    return PSO, Problem, minimize, DefaultSingleObjectiveTermination


def _run_pso(prob: _Problem, x0, maxiter, popsize, tol, seed, progress, desc, history):
    PSO, Problem, minimize, Termination = _pymoo()
    from scipy.stats import qmc
    from tqdm import tqdm

    k = x0.size
    pop = max(20, 10 * k) if popsize is None else int(popsize)
    if pop < 2:
        raise ValueError(f"popsize = {popsize!r} is invalid: PSO needs at least 2 particles")
    # the initial swarm: the initial guess plus a Latin hypercube, from our own seeded generator
    X0 = np.vstack([x0[None, :], qmc.LatinHypercube(d=k, rng=np.random.default_rng(seed)).random(pop - 1)])

    class _P(Problem):
        def __init__(self):
            super().__init__(n_var=k, n_obj=1, xl=np.zeros(k), xu=np.ones(k))

        def _evaluate(self, X, out, *args, **kwargs):
            out["F"] = prob.objective(X)[:, None]

    bar = tqdm(total=maxiter, desc=desc, unit="gen", disable=not progress, leave=False)

    def callback(algorithm):
        f = float(algorithm.opt.get("F").min())
        history.append(f)
        bar.update(1)
        bar.set_postfix(objective=f"{f:.5g}")

    term = Termination(ftol=1e-6 if tol is None else float(tol), n_max_gen=maxiter)
    try:
        res = minimize(_P(), PSO(pop_size=pop, sampling=X0), termination=term, seed=seed, callback=callback,
                       verbose=False)
    finally:
        bar.close()
    n_gen = int(res.algorithm.n_gen)
    converged = n_gen < maxiter
    msg = ("swarm converged (pymoo's single-objective termination)" if converged
           else f"maximum number of generations ({maxiter}) reached")
    return np.clip(np.asarray(res.X, dtype=np.float64).ravel(), 0.0, 1.0), n_gen, converged, msg


# --- sensitivity / identifiability ------------------------------------------------------------------------------

def sensitivity(damper: DamperModel, records, *, free: Iterable[str] | None = None, noise: float | None = None,
                rel_step: float = 1e-4, dt: float | None = None, command_range: str = "clip",
                warmup: float = 0.0, rcond: float = 1e-8, **integrator_options) -> dict:
    """Local identifiability of ``damper``'s parameters on ``records``: the Jacobian S = ∂F/∂ln p of the
    simulated force samples (central differences), its singular values, and the Cramér–Rao bound on each
    parameter's relative standard deviation for white force noise of standard deviation ``noise`` (N):
    cov(ln p) ≈ noise² (SᵀS)⁻¹.

    Returns {"names", "rel_std" (dict; with noise=None: per newton of noise), "singular_values",
    "condition" (of S with unit-norm columns), "weakest" (the right singular vector of the smallest singular
    value, as {name: component}), "correlation" (2-D array)}. Singular values below ``rcond`` × the largest
    mark exactly unidentifiable combinations (e.g. c1 + c2 x_a + c3 x_a² with x_a fixed): the parameters in them
    get ``rel_std`` = inf. A parameter whose ``rel_std`` is far below the accuracy wanted is well identifiable
    from these records at that noise level.
    """
    cls = type(damper)
    fixed = fixed_by_default(cls, damper.params)
    names = tuple(free) if free is not None else tuple(k for k in cls.Params.names() if k not in fixed)
    bad = [k for k in names if k not in cls.Params.names()]
    if bad:
        raise ValueError(f"unknown parameter name(s) {bad} for model {cls.name!r}")
    if isinstance(records, DamperRecord) or not isinstance(records, (list, tuple)):
        records = [records]
    preps = [prepare_record(_as_record(r, i), damper.command, dt=dt, command_range=command_range, warmup=warmup)
             for i, r in enumerate(records)]
    p0 = damper.params.as_array()
    idx = [cls.Params.names().index(k) for k in names]
    k = len(idx)
    P = np.tile(p0, (2 * k, 1))
    dp = np.empty(k)
    for j, i in enumerate(idx):
        dp[j] = rel_step * (abs(p0[i]) if p0[i] != 0 else 1.0)
        P[2 * j, i] += dp[j]
        P[2 * j + 1, i] -= dp[j]
    scale = np.array([abs(p0[i]) if p0[i] != 0 else 1.0 for i in idx])
    cols = []
    Y0 = np.tile(damper.initial_state(), (2 * k, 1))
    for prep in preps:
        F, ok = _simulate_batch(cls, damper.command, prep, P, np.full(2 * k, damper.command.eta), Y0,
                                integrator_options)
        if not ok.all():
            raise SimulationDivergedError(f"a perturbed {cls.name!r} diverged in the sensitivity analysis",
                                          model=cls.name)
        F = F[:, prep.mask]
        cols.append(((F[0::2] - F[1::2]) / (2 * dp[:, None]) * scale[:, None]).T)
    S = np.vstack(cols)
    sigma = 1.0 if noise is None else float(noise)
    # covariance from the SVD of S with unit-norm columns; a (numerically) zero singular value means an exactly
    # unidentifiable combination: every parameter taking part in it gets an infinite bound
    norms = np.linalg.norm(S, axis=0)
    Sn = S / np.where(norms > 0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(Sn, full_matrices=False)
    null = sv <= rcond * sv[0]
    inv2 = np.where(null, 0.0, 1.0 / np.where(null, 1.0, sv) ** 2)
    cov_n = (Vt.T * inv2) @ Vt
    with np.errstate(divide="ignore", invalid="ignore"):
        rel_std = sigma * np.sqrt(np.clip(np.diag(cov_n), 0, None)) / norms
    in_null = np.any(np.abs(Vt[null]) > 1e-6, axis=0) if null.any() else np.zeros(k, dtype=bool)
    rel_std = np.where(in_null | (norms == 0), math.inf, rel_std)
    d = np.sqrt(np.clip(np.diag(cov_n), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov_n / np.outer(np.where(d > 0, d, 1), np.where(d > 0, d, 1))
    return {"names": names, "rel_std": dict(zip(names, rel_std.tolist())), "singular_values": sv,
            "condition": float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf,
            "weakest": dict(zip(names, Vt[-1].tolist())), "correlation": corr}


# --- presets ----------------------------------------------------------------------------------------------------

def save_preset(result: FitResult | DamperModel, path: str | Path, *, source: str = "") -> Path:
    """Write a fitted damper (or any damper) as a JSON preset: model name, parameters (SI, with units), command
    channel, and the provenance of a fit (records, method, seed, error measures). Floats are stored with repr,
    so :func:`load_preset` gives back exactly equal parameters."""
    if isinstance(result, FitResult):
        damper = result.damper
        prov = {
            "method": result.method, "seed": result.seed, "free": list(result.free),
            "bounds": {k: list(v) for k, v in result.bounds.items()},
            "initial": result.initial, "records": list(result.records),
            "errors": {"per_record": result.per_record, "overall": result.overall},
            "objective": result.objective, "initial_objective": result.initial_objective,
            "n_evaluations": result.n_evaluations, "wall_time_s": result.wall_time,
            "converged": result.converged, "message": result.message,
            "settings": {k: v for k, v in result.settings.items() if _jsonable(v)},
        }
    elif isinstance(result, DamperModel):
        damper, prov = result, {}
    else:
        raise ValueError(f"save_preset needs a FitResult or a DamperModel, got {type(result).__name__}")
    from .. import __version__
    units = damper.Params.units()
    c = damper.command
    doc = {
        "format": PRESET_FORMAT, "version": 1, "mrd_env_version": __version__,
        "model": damper.name,
        "source": source or (f"fitted with mrd_env.identification.fit_model ({prov['method']})" if prov else ""),
        "parameters": {k: {"value": float(v), "unit": units[k]} for k, v in damper.params.to_dict().items()},
        "command": {"unit": c.unit, "v_min": float(c.v_min), "v_max": float(c.v_max), "eta": float(c.eta),
                    "eta_unit": "1/s"},
        "provenance": prov,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2, ensure_ascii=False, allow_nan=True) + "\n", encoding="utf-8")
    return path


def _jsonable(v) -> bool:
    try:
        json.dumps(v)
        return True
    except (TypeError, ValueError):
        return False


def read_preset(path: str | Path) -> dict:
    """The JSON document of a preset file (checked for the format marker)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a JSON preset ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != PRESET_FORMAT:
        raise ValueError(f"{path}: not an mrd-env preset file (missing \"format\": \"{PRESET_FORMAT}\")")
    return doc


def load_preset(path: str | Path) -> DamperModel:
    """The damper of a preset written by :func:`save_preset` (parameters exactly as saved).

    Raises ``ValueError`` for an unknown model, missing or extra parameters, or a unit that differs from the
    model's declared SI unit.
    """
    path = Path(path)
    doc = read_preset(path)
    cls = damper_class(doc.get("model", ""))
    units = cls.Params.units()
    pars = doc.get("parameters", {})
    missing = [k for k in units if k not in pars]
    extra = [k for k in pars if k not in units]
    if missing or extra:
        raise ValueError(f"{path}: parameters of {cls.name!r} do not match (missing {missing}, unknown {extra})")
    values = {}
    for k, entry in pars.items():
        if entry.get("unit") != units[k]:
            raise ValueError(f"{path}: parameter {k!r} is in {entry.get('unit')!r}, expected {units[k]!r} (SI)")
        values[k] = float(entry["value"])
    c = doc.get("command", {})
    try:
        command = CommandSpec(c["unit"], float(c["v_min"]), float(c["v_max"]), float(c["eta"]))
    except KeyError as exc:
        raise ValueError(f"{path}: command channel lacks {exc}") from None
    return cls(cls.Params(**values), command)
