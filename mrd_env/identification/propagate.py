"""Monte-Carlo propagation of test-rig sensor errors to identified parameters and to the error measures.

A known damper is driven on the virtual rig (noise-free "true" stroke and force on a fine grid); each draw
records it through the rig's sensors (:func:`~mrd_env.identification.uncertainty.apply_sensors`: load-cell and
stroke-sensor static errors, noise, saturation, quantisation, velocity from the filtered stroke) with its own
child generator, fits the model to the readout (:func:`~mrd_env.identification.fit.fit_model`), and keeps the
fitted free parameters and the error measures — against the readout (what a user would report) and against
the true force (what the model is really worth). :func:`~mrd_env.identification.uncertainty.monte_carlo`
summarises the draws: mean, standard deviation, and the central percentile interval (GUM Supplement 1).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..dampers import DamperModel, make_damper
from ..records import DamperRecord
from ..rig import random_test
from .fit import fit_model
from .parameters import COMMAND_PARAMS, initial_values
from .prepare import as_record
from .result import FitResult, record_measures, pooled_measures
from .simulate import predict
from .options import SearchOptions, as_options
from .uncertainty import MonteCarloResult, SensorSet, apply_sensors, as_generator, monte_carlo

__all__ = ["PropagationResult", "propagate_sensor_errors", "default_excitation"]

_MEASURES = ("E_t", "E_x", "E_v", "J2")


def default_excitation(damper: DamperModel, *, duration: float = 5.0, dt: float = 2.5e-4,
                       rng=0) -> list[DamperRecord]:
    """A band-limited random stroke (4 mm RMS, 8 Hz) with the command switched at random (2 Hz) between the
    preset's extremes, on a fine grid ``dt`` (finer than the sensors' sampling, which interpolates it)."""
    return [random_test(damper, rms=0.004, bandwidth=8.0, duration=duration, switch_rate=2.0, dt=dt,
                        rng=as_generator(rng))]


@dataclass(frozen=True, eq=False)
class PropagationResult:
    """Draws of the fitted free parameters and of the measures, and their summary.

    ``mc.samples`` holds one array per quantity: each free parameter (SI), ``E_t``, ``E_x``, ``E_v`` (ratios)
    and ``J2`` (N) of the fitted model against the sensor readout, and the same with the suffix ``_true``
    against the true (noise-free) force on the true grid.
    """

    model: str
    true_params: dict[str, float]
    free: tuple[str, ...]
    mc: MonteCarloResult
    units: dict[str, str]
    sensors: SensorSet
    files: dict[str, Path] = field(default_factory=dict)

    @property
    def n_draws(self) -> int:
        return int(next(iter(self.mc.samples.values())).size) + self.mc.n_failed

    def rows(self) -> list[dict]:
        """One row per quantity: true value (parameters), mean, std, CI, bias and spread relative to the truth."""
        s = self.mc.summary()
        pct = 100 * self.mc.confidence
        out = []
        for q, st in s.items():
            true = self.true_params.get(q, float("nan"))
            known = q in self.true_params and true != 0
            rel = (lambda x: 100 * x / abs(true)) if known else (lambda x: float("nan"))
            out.append({"quantity": q, "unit": self.units.get(q, ""), "true": true, "mean": st["mean"],
                        "std": st["std"], f"CI{pct:g} low": st["ci_low"], f"CI{pct:g} high": st["ci_high"],
                        "bias %": rel(st["mean"] - true) if q in self.true_params else float("nan"),
                        "std %": rel(st["std"])})
        return out

    def write(self, out: str | Path, *, title: str = "") -> dict[str, Path]:
        from ..report import write_table
        out = Path(out)
        md, csv_path = write_table(self.rows(), out / f"{self.model}_propagation",
                                   title=title or (f"{self.model}: sensor-error propagation, {self.n_draws} draws "
                                                   f"({self.mc.n_failed} failed)"), floatfmt=".5g")
        self.files.update({"table_md": md, "table_csv": csv_path})
        return dict(self.files)


@dataclass(frozen=True, eq=False)
class _Draw:
    """One Monte-Carlo draw of :func:`propagate_sensor_errors` (picklable, so draws run on any backend): the true
    records read through the sensors with the draw's generator, the fit, its measures against the readout and
    against the truth."""

    damper: DamperModel
    truth: tuple
    sensors: SensorSet
    overrange: str
    free: tuple | None
    initial: dict | None
    search: SearchOptions
    data: object
    integrator_options: dict

    def __call__(self, child: np.random.Generator) -> dict[str, float]:
        readouts = []
        for r, g in zip(self.truth, child.spawn(len(self.truth))):
            readouts.append(apply_sensors(r.t, r.x, r.force, self.sensors, g, command=r.command,
                                          command_unit=r.command_unit, overrange=self.overrange,
                                          label=f"{r.label} (measured)"))
        fr: FitResult = fit_model(self.damper, readouts, free=self.free, initial=self.initial, search=self.search,
                                  data=self.data, integrator_options=self.integrator_options)
        out = dict(fr.free_values())
        for k in _MEASURES:
            out[k] = fr.overall[k]
        pooled = pooled_measures([record_measures(*predict(fr.damper, r, **self.integrator_options)) for r in self.truth])
        for k in _MEASURES:
            out[f"{k}_true"] = pooled[k]
        return out


def propagate_sensor_errors(damper: DamperModel | str = "spencer_dyke", *,
                            excitation: Sequence[DamperRecord] | None = None, sensors: SensorSet | None = None,
                            n_draws: int = 20, rng=0,
                            search=None, data=None, free: Sequence[str] | None = None,
                            initial: Mapping[str, float] | None = None, integrator_options: Mapping | None = None,
                            confidence: float = 0.95, progress: bool = True, on_error: str = "skip",
                            overrange: str = "raise", out: str | Path | None = None, backend: str = "serial",
                            jobs: int | None = None, address: str | None = None) -> PropagationResult:
    """Propagate sensor errors to the parameters fitted to ``damper`` (a configured damper or a model name
    with its default preset, the "truth"), by Monte Carlo over ``n_draws`` independent sensor draws.

    ``excitation``: the true rig records (default :func:`default_excitation`); give them on a finer grid than
    the sensors' sampling. ``sensors``: default ``SensorSet()`` (review Table 7). Each fit starts from the true
    parameters (``initial`` overrides some of them), so the spread is that of the optimum, not of the search.
    ``rng``: int seed or Generator; draw i uses child i of it (:func:`monte_carlo`). ``on_error="skip"`` drops
    (and counts) draws whose fit fails. ``out``: folder for the table ``<model>_propagation.md/.csv``.
    ``backend``/``jobs``/``address``: where the draws run (:mod:`mrd_env.executor`; the same result on each).
    """
    if isinstance(damper, str):
        damper = make_damper(damper)
    sensors = SensorSet() if sensors is None else sensors
    if not isinstance(sensors, SensorSet):
        raise ValueError(f"sensors must be a SensorSet, got {type(sensors).__name__}")
    true_recs = list(excitation) if excitation is not None else default_excitation(damper)
    if not true_recs:
        raise ValueError("excitation must not be empty")
    truth = [as_record(r, i) for i, r in enumerate(true_recs)]
    search = as_options(SearchOptions, search, "search")
    if search == SearchOptions():  # no progress bar per draw unless asked
        search = dataclasses.replace(search, progress=False)
    units = {**damper.Params.units(), **{k: v[1] for k, v in COMMAND_PARAMS.items()}, "E_t": "-", "E_x": "-",
             "E_v": "-", "J2": "N", "E_t_true": "-", "E_x_true": "-", "E_v_true": "-", "J2_true": "N"}
    draw = _Draw(damper, tuple(truth), sensors, overrange, None if free is None else tuple(free),
                 None if initial is None else dict(initial), search, data, dict(integrator_options or {}))
    mc = monte_carlo(draw, n_draws, as_generator(rng), confidence=confidence, progress=progress,
                     on_error=on_error, desc=f"propagate {damper.name}", backend=backend, jobs=jobs,
                     address=address)
    true_params = initial_values(damper.params, damper.command)
    # the fitted free parameters are the draws' keys before the measures (fit_model's choice when free is None)
    free_t = tuple(k for k in mc.samples if k not in _MEASURES and not k.endswith("_true"))
    res = PropagationResult(damper.name, {k: true_params[k] for k in free_t}, free_t, mc, units, sensors)
    if out is not None:
        res.write(out)
    return res
