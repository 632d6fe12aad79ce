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
  generation is one batched simulation of the whole population (``mrd_env.stepping.run``'s per-system P).
* ``"pso"`` — particle swarm from pymoo (``pymoo.algorithms.soo.nonconvex.pso.PSO``, an optional
  dependency), one batched simulation per swarm generation.

Constraints: every bound lies inside the parameter's declared valid range, and a candidate that the
parameter dataclass rejects (its ``check()`` cross-field constraints, e.g. β + γ > 0) or whose simulation
diverges (:class:`~mrd_env.errors.SimulationDivergedError`) is infeasible: it gets the penalty objective
``PENALTY`` × Σ_r w_r RMS(F_r) instead of a crash.

Free parameters, their default bounds and the command-dynamics pseudo-parameters (``command_eta``,
``command_eta_fall``, ``command_delay``): :mod:`.parameters`. Records are prepared by :mod:`.prepare` — faults
(:mod:`.faults`) excluded by default, the force optionally aligned with the motion (:mod:`.align`). Options are
grouped in :class:`~.options.SearchOptions` (the optimiser) and :class:`~.options.DataOptions` (the records).
``fit_model("neural", ...)`` fits the non-parametric forward model of :mod:`.neural` through the same call
and returns the same :class:`~.result.FitResult`. Presets: :mod:`.presets`.
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings
from typing import Iterable, Mapping

from ..dampers import DamperModel, damper_class
from ..errors import SimulationDivergedError
from .align import best_offset
from .neural import NeuralOptions, fit_neural
from .optimisers import run_search
from .options import DataOptions, SearchOptions, as_options
from .parameters import (COMMAND_PARAMS, make_params, valid_range, command_with, default_bounds,
                         fixed_by_default, initial_values)
from .prepare import as_records, prepare_record
from .problem import Problem
from .result import FitInterrupted, FitResult, ParameterAtBound, record_measures, pooled_measures, record_info
from .simulate import predict

__all__ = ["fit_model", "reference_offset", "SearchOptions", "DataOptions"]

ALIGN_ROUNDS = 3  # refits at most when the fitted model prefers another force offset
#: The model whose fit (command dynamics free, align=True) gives the neural model its force offset: the offset a
#: model finds depends on what it can explain (on the NEES record Bingham prefers +2 samples, the hyperbolic
#: tangent +1, Spencer–Dyke with its fitted lag −1), so the best-fitting one is asked.
OFFSET_REFERENCE = "spencer_dyke"


def fit_model(model: str | DamperModel, records, *, preset: str | None = None, free: Iterable[str] | None = None,
              bounds: Mapping[str, tuple[float, float]] | None = None, initial: Mapping[str, float] | None = None,
              search: SearchOptions | Mapping | None = None, data: DataOptions | Mapping | None = None,
              integrator_options: Mapping | None = None) -> FitResult:
    """Fit a damper model to measured records; see the module docstring.

    Parameters
    ----------
    model : a registered model name (``available_dampers()``), a configured ``DamperModel`` whose parameters
        and command channel are the initial guess (then ``preset`` must be None), or ``"neural"`` (or a
        :class:`~.neural.NeuralOptions`) for the non-parametric forward model.
    records : a :class:`DamperRecord` or a sequence of them (or objects with t, x, command, force[, v]).
    preset : the preset that supplies the initial guess and the command channel (default: the model's).
    free : names of the parameters to fit (default: all but :func:`fixed_by_default`); the command dynamics
        under the names of :data:`~.parameters.COMMAND_PARAMS`.
    bounds : {name: (lo, hi)} in SI units, overriding :func:`default_bounds` for free parameters; must
        contain the initial value and lie inside the parameter's valid range.
    initial : {name: value} overrides of the initial guess (command pseudo-parameters too).
    search : :class:`~.options.SearchOptions` (or a dict of them): method, seed, maxiter, ...
    data : :class:`~.options.DataOptions` (or a dict of them): dt, warmup, command_range, faults, align, ...
    integrator_options : passed to the stepping routine (max_substeps, rtol, atol).
    """
    search = as_options(SearchOptions, search, "search")
    data = as_options(DataOptions, data, "data")
    recs = as_records(records)
    if isinstance(model, NeuralOptions) or (isinstance(model, str) and model == "neural"):
        if preset is not None or free is not None or bounds is not None or initial is not None:
            raise ValueError("the neural model takes no preset, free, bounds or initial (use NeuralOptions)")
        if search.method == "least_squares":  # the default: the network's optimiser is Adam
            search = dataclasses.replace(search, method="adam")
        return fit_neural(recs, model if isinstance(model, NeuralOptions) else NeuralOptions(), search, data)
    if search.method == "adam":
        raise ValueError("method = 'adam' trains the neural model only; parametric models take 'least_squares', "
                         "'differential_evolution' or 'pso'")
    t_start = time.perf_counter()
    cls, params0, command, preset_name = _initial_guess(model, preset, initial)
    free_t = _free_names(cls, params0, free)
    init_vals = initial_values(params0, command)
    lo, hi, bnd = _bounds(cls, free_t, init_vals, bounds, search.bound_factor)
    opts = dict(integrator_options or {})

    align = data.align and data.offset is None
    offsets = [data.offset or 0] * len(recs)
    preps = [prepare_record(r, command, offset=o, **data.prepare_kwargs()) for r, o in zip(recs, offsets)]
    if data.command_range == "widen":
        cmin = min(command.v_min, *(float(p.series.command.min()) for p in preps))
        cmax = max(command.v_max, *(float(p.series.command.max()) for p in preps))
        command = dataclasses.replace(command, v_min=cmin, v_max=cmax)

    def solve(preps, x0):
        prob = Problem(cls, params0, command, free_t, lo, hi, preps, data.normalize, opts, data.weighting)
        J0 = float(prob.objective(x0[None, :])[0])
        if J0 >= prob.penalty:
            raise ValueError(f"the initial guess of {cls.name!r} diverges or is infeasible on the records")
        return prob, J0, run_search(prob, x0, search, f"fit {cls.name} ({search.method})")

    def realigned(damper):
        """The records with the force offsets ``damper`` prefers, or None if they are the ones in use (or the
        damper diverges: the fit reports that)."""
        try:
            better = [best_offset(predict(damper, p, **opts)[1], p) for p in preps]
        except SimulationDivergedError:
            return None
        if better == offsets:
            return None
        return better, [prepare_record(r, command, offset=o, **data.prepare_kwargs()) for r, o in zip(recs, better)]

    x0 = Problem.scale(init_vals, free_t, lo, hi)
    if align and (moved := realigned(cls(params0, command))) is not None:  # the offset of the initial guess
        offsets, preps = moved
    prob, J0, (theta, nit, converged, message, history) = solve(preps, x0)
    damper = _fitted(cls, prob, theta, command, free_t)
    n_evaluations = prob.n_evaluations
    stopped = prob.interrupted
    for _ in range(0 if stopped or not align else ALIGN_ROUNDS):  # the offset the fitted model prefers; fit again
        moved = realigned(damper)                                # if it differs
        if moved is None:
            break
        offsets, preps = moved
        # from the fit so far and from the initial guess (the first may sit in the previous offset's optimum)
        runs = []
        for start in (theta.copy(), x0):
            runs.append(solve(preps, start))
            if runs[-1][0].interrupted is not None:
                stopped = runs[-1][0].interrupted
                break
        n_evaluations += sum(r[0].n_evaluations for r in runs)
        prob, _, (theta, nit, converged, message, history) = min(runs, key=lambda r: r[0].best)
        damper = _fitted(cls, prob, theta, command, free_t)
        if stopped is not None:
            converged, message = False, "interrupted: the best parameters found so far"
            break
    J = float(prob.objective(theta[None, :])[0])
    per = [record_measures(p, predict(damper, p, **opts)[1]) for p in preps]
    settings = {"preset": preset_name, **dataclasses.asdict(search), **dataclasses.asdict(data),
                "maxiter": search.iterations, "offsets": offsets, "integrator_options": opts}
    fr = FitResult(cls.name, damper, damper.params.to_dict(), init_vals, free_t, bnd,
                   {k: v for k, v in fixed_by_default(cls, params0).items() if k not in free_t}, search.method,
                   int(search.seed), J, J0, per, pooled_measures(per), time.perf_counter() - t_start,
                   n_evaluations, nit, bool(converged), str(message), tuple(history), prob.n_infeasible,
                   prob.n_diverged, record_info(preps), settings)
    if stopped is not None:  # the caller saves the best so far, then the interruption goes on
        raise FitInterrupted(fr) from stopped
    for msg in fr.bound_messages():  # a parameter held by its bound is not a fitted value: never silently
        warnings.warn(msg, ParameterAtBound, stacklevel=2)
    return fr


def reference_offset(records, *, model: str = OFFSET_REFERENCE, search: SearchOptions | Mapping | None = None,
                     data: DataOptions | Mapping | None = None) -> tuple[int, FitResult]:
    """(force offset in samples, the fit that found it): ``model`` fitted by least squares with its command
    dynamics free and ``align=True`` on ``records`` — the offset to give the neural model, which cannot find it
    (:mod:`.align`). ``search``: its seed and progress are used; ``data``: the records' preparation."""
    search = as_options(SearchOptions, search, "search")
    data = as_options(DataOptions, data, "data")
    cls = damper_class(model)
    base = cls.preset(None)
    free = [k for k in cls.Params.names() if k not in fixed_by_default(cls, base.params)] + list(COMMAND_PARAMS)
    with warnings.catch_warnings():  # its parameters are not reported: only its offset is used
        warnings.simplefilter("ignore", ParameterAtBound)
        fr = fit_model(model, records, free=free,
                       search=SearchOptions(seed=search.seed, progress=search.progress),
                       data=dataclasses.replace(data, align=True, offset=None))
    offsets = sorted(set(fr.settings["offsets"]))
    if len(offsets) != 1:
        raise ValueError(f"the records' force offsets differ ({fr.settings['offsets']} samples, found by a "
                         f"{model} fit): the neural model takes one offset; fit the records one at a time")
    return int(offsets[0]), fr


def _initial_guess(model, preset, initial):
    """(class, parameters, command channel, preset name) of the initial guess."""
    if isinstance(model, DamperModel):
        if preset is not None:
            raise ValueError("give either a DamperModel or a preset name, not both")
        cls, params0, command, preset_name = type(model), model.params, model.command, None
    else:
        cls = damper_class(model)
        base = cls.preset(preset)
        params0, command, preset_name = base.params, base.command, preset or cls.default_preset
    if initial:
        valid = list(cls.Params.names()) + list(COMMAND_PARAMS)
        unknown = [k for k in initial if k not in valid]
        if unknown:
            raise ValueError(f"unknown parameter name(s) {unknown} in initial for model {cls.name!r}; valid: {valid}")
        params0 = params0.replace(**{k: v for k, v in initial.items() if k not in COMMAND_PARAMS})
        cmd = {COMMAND_PARAMS[k][0]: float(v) for k, v in initial.items() if k in COMMAND_PARAMS}
        command = dataclasses.replace(command, **cmd)
    try:
        cls(params0, command)  # model-level checks (e.g. constraints over the command range)
    except ValueError as exc:
        raise ValueError(f"the initial guess of {cls.name!r} is invalid: {exc}") from None
    return cls, params0, command, preset_name


def _free_names(cls, params0, free) -> tuple[str, ...]:
    valid = list(cls.Params.names()) + list(COMMAND_PARAMS)
    if free is None:
        fixed = fixed_by_default(cls, params0)
        free_t = tuple(k for k in cls.Params.names() if k not in fixed)
    else:
        free_t = tuple(dict.fromkeys([free] if isinstance(free, str) else free))
        unknown = [k for k in free_t if k not in valid]
        if unknown:
            raise ValueError(f"unknown parameter name(s) {unknown} in free for model {cls.name!r}; valid: {valid}")
    if not free_t:
        raise ValueError("no free parameters to fit")
    return free_t


def _bounds(cls, free_t, init_vals, bounds, bound_factor):
    """(lower, upper, {name: (lo, hi)}) of the free parameters: given or default, checked."""
    bounds = dict(bounds or {})
    valid = list(cls.Params.names()) + list(COMMAND_PARAMS)
    unknown = [k for k in bounds if k not in valid]
    if unknown:
        raise ValueError(f"unknown parameter name(s) {unknown} in bounds for model {cls.name!r}; valid: {valid}")
    not_free = [k for k in bounds if k not in free_t]
    if not_free:
        raise ValueError(f"bounds given for {not_free}, which are not free (free: {list(free_t)}); add them to "
                         f"free to fit them")
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
            vlo, vhi, _ = valid_range(cls, k)
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
    return lo, hi, bnd


def _fitted(cls, prob: Problem, theta, command, free_t) -> DamperModel:
    """The damper at θ (the best candidate the search saw, if better than θ)."""
    if prob.best_theta is not None and prob.best < float(prob.objective(theta[None, :])[0]):
        theta[:] = prob.best_theta
    P, lag = prob.decode(theta[None, :])
    return cls(make_params(cls, P[0]), command_with(command, lag[0], free_t))
