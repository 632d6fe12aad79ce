"""Compare damper models on the same measured records: fit on the first part, validate on the held-back rest.

For every model, :func:`~mrd_env.identification.fit.fit_model` fits the parameters on the first
``fit_fraction`` of each record; the fitted model is then simulated over the *whole* record (its states carry
over from the fitted part, so no start-up transient lands in the validation part — and no measured force of
the held-back part is used) and E_t, E_x, E_v (review eq. 3) and J2 (eq. 26) are evaluated on the held-back
samples only. Output: a Markdown + CSV table (``mrd_env.report.write_table``), one JSON preset per fitted
model, and PNG figures: measured vs fitted force over a window of the held-back part, and force–velocity
loops of the held-back part (PNG, :mod:`mrd_env.report`).
"""
from __future__ import annotations

import dataclasses
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..dampers import DamperModel, available_dampers, damper_class
from ..errors import SimulationDivergedError
from ..executor import Task, TaskFailed, resolve_backend, run_tasks
from ..validation import check_scalar
from ..validation import shown
from ..records import DamperRecord
from .fit import fit_model
from .neural import NAME as NEURAL
from .options import DataOptions, SearchOptions, as_options
from .faults import find_faults
from .prepare import PreparedRecord, as_records, excluded, uniform_record
from .presets import save_preset
from .result import FitResult, record_measures, pooled_measures
from .simulate import predict

__all__ = ["ModelComparison", "ComparisonResult", "compare_models", "split_records", "validate", "plot_fit",
           "COLUMNS"]

COLUMNS = ("model", "free params", "offset samples", "fit E_t %", "E_t %", "E_x %", "E_v %", "J2 N", "fit J2 N",
           "wall time s", "evaluations", "converged")


@dataclass(frozen=True, eq=False)
class ModelComparison:
    """One model's fit and its validation on the held-back parts (``validation``: one dict of measures per
    record, ``validation_overall``: pooled as in :class:`FitResult`). ``error`` is set when the fit failed."""

    model: str
    fit: FitResult | None
    validation: list[dict] = field(default_factory=list)
    validation_overall: dict = field(default_factory=dict)
    forces: list[np.ndarray] = field(default_factory=list)
    error: str = ""

    def row(self) -> dict:
        nan = float("nan")
        if self.fit is None:
            return {"model": self.model, "free params": 0, "offset samples": nan, "fit E_t %": nan, "E_t %": nan,
                    "E_x %": nan,
                    "E_v %": nan, "J2 N": nan, "fit J2 N": nan, "wall time s": nan, "evaluations": 0,
                    "converged": f"failed: {self.error}"}
        v, f = self.validation_overall, self.fit.overall
        return {"model": self.model, "free params": self.fit.n_free,
                "offset samples": _offsets_label(self.fit.settings.get("offsets", [0])), "fit E_t %": 100 * f["E_t"],
                "E_t %": 100 * v["E_t"], "E_x %": 100 * v["E_x"], "E_v %": 100 * v["E_v"], "J2 N": v["J2"],
                "fit J2 N": f["J2"], "wall time s": self.fit.wall_time, "evaluations": self.fit.n_evaluations,
                "converged": "yes" if self.fit.converged else "no"}


@dataclass(frozen=True, eq=False)
class ComparisonResult:
    """All models' results; ``rows`` is the table (one row per model, :data:`COLUMNS`), ``files`` the outputs."""

    models: list[ModelComparison]
    records: list[DamperRecord]          # the uniform records (whole)
    split_index: list[int]               # first held-back sample of each record
    method: str
    fit_fraction: float
    files: dict[str, Path] = field(default_factory=dict)
    cross_record: bool = False       # validated on other records (the whole of each)

    @property
    def rows(self) -> list[dict]:
        return [m.row() for m in self.models]

    def by_model(self, name: str) -> ModelComparison:
        for m in self.models:
            if m.model == name:
                return m
        raise KeyError(name)


#: Fewest held-back samples an error measure is computed on.
MIN_HELD_BACK = 3


def split_records(records, fit_fraction: float, dt: float | None = None, faults: str = "keep"
                  ) -> tuple[list[DamperRecord], list[DamperRecord], list[int]]:
    """(uniform whole records, their fit parts, index of the first held-back sample of each). With ``faults``
    "exclude", a held-back part left with too few samples once its faults are excluded is refused here, before
    any fit, naming the fit fraction."""
    whole = [uniform_record(r, dt) for r in as_records(records)]
    f = float(fit_fraction)
    if not (0.0 < f < 1.0):
        raise ValueError(f"fit_fraction = {shown(fit_fraction)} is invalid: must be in (0, 1)")
    fits, idx = [], []
    for r in whole:
        part, _ = r.split(f)
        fits.append(part)
        idx.append(part.n)
        kept = r.n - part.n
        if faults == "exclude":
            kept -= int(excluded(r.t, find_faults(r))[part.n:].sum())
        if kept < MIN_HELD_BACK:
            raise ValueError(f"fit_fraction = {shown(fit_fraction)} leaves {kept} sample(s) of {r.label!r} to "
                             f"validate on{' once its faults are excluded' if faults == 'exclude' else ''} (at "
                             f"least {MIN_HELD_BACK} are needed): lower it, or validate on other records")
    return whole, fits, idx


def validate(damper, whole: Sequence[DamperRecord], split_index: Sequence[int], *, data: DataOptions | None = None,
             offset: int | Sequence[int] = 0, **integrator_options
             ) -> tuple[list[dict], dict, list[np.ndarray], list[PreparedRecord]]:
    """Measures of ``damper`` on the held-back part of each record (simulated over the whole record; samples
    with faults, or without a partner after the force ``offset`` — one for all records, or one per record —
    left out)."""
    data = as_options(DataOptions, data, "data")
    offsets = [int(offset)] * len(whole) if np.ndim(offset) == 0 else [int(o) for o in offset]
    if len(offsets) != len(whole):
        raise ValueError(f"offset must be one number or one per record ({len(whole)}), got {list(offset)}")
    rows, forces, preps = [], [], []
    for r, k, o in zip(whole, split_index, offsets):
        prep, F = predict(damper, r, dt=data.dt, command_range=data.command_range, faults=data.faults, offset=o,
                          **integrator_options)
        sl = prep.mask.copy()
        sl[:k] = False
        rows.append(record_measures(prep, F, sl))
        forces.append(F)
        preps.append(prep)
    return rows, pooled_measures(rows), forces, preps


def compare_models(records, models: Sequence[str | DamperModel] | None = None, *,
                   search: SearchOptions | Mapping | None = None, data: DataOptions | Mapping | None = None,
                   fit_fraction: float = 0.6, validation_records=None, out: str | Path | None = None,
                   presets: Mapping[str, str] | None = None, title: str = "", plot_window: float = 1.0,
                   model_options: Mapping[str, Mapping] | None = None,
                   stop_on_error: bool = False, backend: str = "serial", jobs: int | None = None,
                   address: str | None = None, progress: bool = False) -> ComparisonResult:
    """Fit each model (default: all registered) on the first ``fit_fraction`` of ``records`` and validate it on
    the rest; see the module docstring. ``models`` holds model names (initial guess: their preset; ``"neural"``
    for the forward network) or configured ``DamperModel`` instances (initial guess and command channel: theirs).

    ``validation_records``: other records (e.g. another test of the same damper): the models are fitted on the
    whole of ``records`` and scored on these (cross-record validation); ``fit_fraction`` is then not used.
    ``search``/``data``: the options of every fit (:mod:`.options`); ``model_options``: {model: {keyword:
    value}} of :func:`fit_model` for one model (free, bounds, initial, search, ...). ``presets``: {model: preset
    name} for the initial guesses. ``out``: folder for the table (``comparison.md``/``.csv``), the presets
    (``<model>_fitted.json``) and the figures; None writes nothing. A model whose fit fails (bad input for that
    model, a diverging initial guess) gets a row marked failed unless ``stop_on_error``.

    The models are fitted as independent tasks of :func:`mrd_env.executor.run_tasks` (``backend``: "serial",
    "pool", "ray" or "auto", with ``jobs`` workers, Ray at ``address``; ``progress``: one bar over the models):
    the table is the same on every backend; warnings of a fit (e.g. faults excluded) reach the caller.
    """
    models = list(models) if models is not None else available_dampers()
    if not models:
        raise ValueError("models must not be empty")
    for m in models:
        if not isinstance(m, DamperModel) and m != NEURAL:
            damper_class(m)  # an unknown name is the caller's error, not a failed fit: refuse it before fitting
    names = [m.name if isinstance(m, DamperModel) else str(m) for m in models]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"models names {', '.join(twice)} more than once")
    if plot_window is not None:
        check_scalar("plot_window", plot_window, 0.0, lo_open=True, unit="s")
    presets = dict(presets or {})
    # options shared by every fit are refused once, here: a bad one would fail every model's fit alike
    search = as_options(SearchOptions, search, "search")
    data = as_options(DataOptions, data, "data")
    if validation_records is None:
        whole, fits, idx = split_records(records, fit_fraction, data.dt, data.faults)
    else:
        fits = [uniform_record(r, data.dt) for r in as_records(records)]
        whole = [uniform_record(r, data.dt) for r in as_records(validation_records)]
        idx = [0] * len(whole)
    if resolve_backend(backend, len(models), jobs) != "serial":
        search = dataclasses.replace(search, progress=False)  # one bar over the models, not one per worker
    tasks = []
    for name, model in zip(names, models):
        preset = None if (isinstance(model, DamperModel) or name == NEURAL) else presets.get(name)
        options = {"search": search, "data": data, **dict((model_options or {}).get(name, {}))}
        tasks.append(Task(_fit_and_validate, (name, model, fits, whole, idx, preset, options, stop_on_error),
                          label=f"fit {name}"))
    try:
        done = run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress,
                         desc="compare models", retry=not stop_on_error)
    except TaskFailed as exc:  # only with stop_on_error: the fit's own error, as a serial loop would raise it
        raise exc.error from None
    results = []
    for comparison, caught in done:
        for category, message in caught:  # raised in the task, maybe in another process
            warnings.warn(message, category, stacklevel=2)
        results.append(comparison)
    res = ComparisonResult(results, whole, idx, search.method, 1.0 if validation_records is not None
                           else float(fit_fraction), cross_record=validation_records is not None)
    if out is not None:
        res.files.update(write_comparison(res, out, title=title, plot_window=plot_window))
    return res


def _fit_and_validate(name: str, model, fits, whole, idx, preset, options: dict, stop_on_error: bool):
    """One row of the comparison (a task of :func:`compare_models`): the fit, its validation, and the warnings
    they raised as (category, message) pairs."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fr = fit_model(model, fits, preset=preset, **options)
            v_rows, v_all, forces, _ = validate(fr.damper, whole, idx, data=fr_data(fr, options["data"]),
                                                offset=validation_offsets(fr, whole, idx),
                                                **(options.get("integrator_options") or {}))
            row = ModelComparison(name, fr, v_rows, v_all, forces)
        except Exception as exc:  # noqa: BLE001 — a failed fit is a failed row, whatever its cause
            if stop_on_error:
                raise
            expected = isinstance(exc, (ValueError, SimulationDivergedError, ImportError))  # the user's input
            row = ModelComparison(name, None, error=str(exc) if expected else f"{type(exc).__name__}: {exc}")
    return row, [(w.category, str(w.message)) for w in caught]


def _offsets_label(offsets: list[int]):
    """The table's offset: the number where the records agree, else each record's ("0, 3")."""
    return offsets[0] if len(set(offsets)) == 1 else ", ".join(map(str, offsets))


def validation_offsets(fr: FitResult, whole: Sequence[DamperRecord], split_index: Sequence[int]) -> list[int]:
    """The force offsets to score ``whole`` with: each fit record's own where the held-back parts are of the fit
    records (``split_index`` > 0), else the fit's one offset (``ValueError`` if its records' offsets differ)."""
    offsets = list(fr.settings.get("offsets", [0]))
    if all(k > 0 for k in split_index) and len(offsets) == len(whole):
        return offsets
    if len(set(offsets)) != 1:
        raise ValueError(f"the fitted records' force offsets differ ({offsets} samples): give the validation records' "
                         "with --force-offset, or fit on records that agree")
    return [offsets[0]] * len(whole)


def fr_data(fr: FitResult, data: DataOptions) -> DataOptions:
    """The data options a fitted model is scored with: the fit's, with its command range."""
    return dataclasses.replace(data, command_range=fr.settings.get("command_range", data.command_range))


def _slug(s: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", s).strip("_") or "record"


def write_comparison(res: ComparisonResult, out: str | Path, *, title: str = "",
                     plot_window: float = 1.0) -> dict[str, Path]:
    """Table (Markdown + CSV), presets and figures of a comparison into folder ``out``."""
    from ..report import write_table

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    labels = ", ".join(r.label or f"record {i}" for i, r in enumerate(res.records))
    fitted = ", ".join(m.fit.records[0]["label"] for m in res.models[:1] if m.fit is not None)
    title = title or (f"Model comparison: fit on {fitted}, validation (E_t ... J2) on {labels}" if res.cross_record
                      else f"Model comparison ({res.method}): fit on the first {100 * res.fit_fraction:g} % of "
                           f"{labels}, errors on the held-back rest")
    md, csv_path = write_table(res.rows, out / "comparison", title=title, floatfmt=".4g")
    files["table_md"], files["table_csv"] = md, csv_path
    for m in res.models:
        if m.fit is not None:
            files[f"preset_{m.model}"] = save_preset(m.fit, out / f"{m.model}_fitted.json")
    ok = [m for m in res.models if m.fit is not None]
    for i, (r, k) in enumerate(zip(res.records, res.split_index)):
        slug = _slug(r.label or f"record{i}")
        if not ok:
            break
        curves = {m.model: m.forces[i] for m in ok}
        files[f"overlay_{slug}"] = plot_fit(r, curves, out / f"{slug}_overlay.png", split_index=k,
                                            window=plot_window, title=f"{r.label}: held-back part")
        for m in ok:
            files[f"fig_{slug}_{m.model}"] = plot_fit(
                r, {m.model: m.forces[i]}, out / f"{slug}_{m.model}.png", split_index=k, window=plot_window,
                title=(f"{m.model} on {r.label}, held-back part: E_t = {100 * m.validation[i]['E_t']:.1f} %, "
                       f"J2 = {m.validation[i]['J2']:.3g} N"))
    return files


def plot_fit(record: DamperRecord, forces: Mapping[str, np.ndarray], path: str | Path, *, split_index: int = 0,
             window: float | None = 1.0, title: str = "") -> Path:
    """Measured vs model force(s): over time (a ``window`` of s at the start of the held-back part, the whole
    held-back part if None) and force–velocity loops of the held-back part. Writes a PNG and returns its path."""
    from ..report import figure, save_figure

    t = record.t
    v = record.velocity()
    k0 = int(split_index)
    if k0 >= record.n - 2:
        k0 = 0
    k1 = record.n if window is None else min(record.n, k0 + max(3, int(round(window / record.dt)) + 1))
    fig, (ax1, ax2) = figure(1, 2, figsize=(13, 4.6), gridspec_kw={"width_ratios": [1.6, 1.0]})
    stride = max(1, (record.n - k0) // 20000)
    for name, F in forces.items():
        ax1.plot(t[k0:k1], F[k0:k1] / 1e3, lw=1.0, label=name)
        ax2.plot(v[k0::stride], F[k0::stride] / 1e3, ".", ms=1.0, alpha=0.4, label=name)
    # measured on top, thin, so that the models' departures from it stay visible
    ax1.plot(t[k0:k1], record.force[k0:k1] / 1e3, color="k", lw=0.8, label="measured", zorder=5)
    ax2.plot(v[k0::stride], record.force[k0::stride] / 1e3, ".", color="k", ms=0.6, alpha=0.6,
             label="measured", zorder=5)
    ax1.set_xlabel("time t (s)")
    ax2.set_xlabel("velocity ẋ (m/s)")
    for ax in (ax1, ax2):
        ax.set_ylabel("force F (kN)")
        ax.grid(True, alpha=0.3)
    ax1.legend(fontsize=8, loc="upper right")
    leg = ax2.legend(fontsize=8, markerscale=8, loc="upper left")
    for h in leg.legend_handles:
        h.set_alpha(1.0)
    fig.suptitle(title or "measured vs model force")
    return save_figure(fig, path)
