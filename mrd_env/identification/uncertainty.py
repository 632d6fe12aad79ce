"""Test-rig sensors, the uncertainty budget of a testing machine, and a Monte-Carlo propagation helper.

Review section 4: sensors of a damper tester (Table 7) and the root-sum-square (RSS) combination of the
uncertainty contributions of a testing machine during use (Table 8). Every random draw takes a
``numpy.random.Generator`` or an integer seed and is reproducible bit for bit.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping

import numpy as np

from .. import storage
from ..executor import Task, TaskFailed, run_tasks
from ..records import DamperRecord, hold_previous, lowpass_zero_phase
from ..validation import as_generator, check_signal, check_time

__all__ = [
    "LoadCell", "DisplacementSensor", "SensorSet", "apply_sensors",
    "Contribution", "UncertaintyBudget", "rss_budget", "table8_contributions", "TABLE8_DEFAULTS",
    "MonteCarloResult", "monte_carlo", "as_generator",
]


def _positive(owner: str, name: str, value: float, *, allow_zero: bool, unit: str = "") -> None:
    v = float(value)
    ok = math.isfinite(v) and (v >= 0.0 if allow_zero else v > 0.0)
    if not ok:
        raise ValueError(f"{owner}.{name} = {value!r} is invalid: must be {'>=' if allow_zero else '>'} 0"
                         f"{' ' + unit if unit else ''}")


# --- sensors (review Table 7) -------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Sensor(ABC):
    """Common error model of an analogue sensor read by an ADC.

    Output = value + static error + white noise, saturated at ±``full_scale``, then quantised to the
    resolution. The static (calibration/linearity) error is drawn once per record as a gain error
    g ~ U(-a/2, a/2) plus an offset o ~ U(-a·FS/2, a·FS/2), with a = ``accuracy_fs``: it never exceeds the
    data-sheet bound ±a·FS anywhere in the range, and its rectangular shape matches Table 8's convention.
    """

    @abstractmethod
    def _params(self) -> tuple[float, float, float, float]:
        """(full_scale, accuracy_fs, noise_rms, resolution) in the sensor's SI unit."""

    def measure(self, value: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(reading, saturated-sample mask). Draw order is fixed: gain, offset, noise."""
        fs, acc, noise, res = self._params()
        gain = rng.uniform(-acc / 2, acc / 2) if acc > 0 else 0.0
        offset = rng.uniform(-acc * fs / 2, acc * fs / 2) if acc > 0 else 0.0
        out = value * (1.0 + gain) + offset
        if noise > 0:
            out = out + noise * rng.standard_normal(value.shape)
        saturated = np.abs(out) > fs
        out = np.clip(out, -fs, fs)
        if res > 0:
            out = res * np.round(out / res)
        return out, saturated


@dataclass(frozen=True)
class LoadCell(_Sensor):
    """Force sensor; defaults: S-type load cell of Table 7, ±5.394 kN, ±0.03 % FS.

    ``range_N``: measuring range ±range_N (N), also the full scale FS. ``noise_rms`` (N) is an assumed
    0.01 % FS white noise; ``resolution`` (N) is a 16-bit ADC spanning ±range_N. Neither is in the review.
    """

    range_N: float = 5394.0
    accuracy_fs: float = 0.0003
    noise_rms: float = 5394.0 * 1e-4
    resolution: float = 2 * 5394.0 / 2**16

    def __post_init__(self):
        _positive("LoadCell", "range_N", self.range_N, allow_zero=False, unit="N")
        _positive("LoadCell", "accuracy_fs", self.accuracy_fs, allow_zero=True)
        _positive("LoadCell", "noise_rms", self.noise_rms, allow_zero=True, unit="N")
        _positive("LoadCell", "resolution", self.resolution, allow_zero=True, unit="N")

    def _params(self):
        return self.range_N, self.accuracy_fs, self.noise_rms, self.resolution


@dataclass(frozen=True)
class DisplacementSensor(_Sensor):
    """Stroke sensor; defaults: PCR-A-1 linear potentiometer of Table 7, 150 mm, ±0.02 % FS.

    ``range_m`` is the total travel (the full scale FS), mounted at mid-stroke, so strokes |x| <= range_m/2
    can be measured. ``resolution_m`` is a 16-bit ADC over the travel; ``noise_rms_m`` an assumed 0.002 % FS.
    For an LVDT use e.g. ``DisplacementSensor(range_m=0.008, accuracy_fs=0.0025)``.
    """

    range_m: float = 0.150
    accuracy_fs: float = 0.0002
    resolution_m: float = 0.150 / 2**16
    noise_rms_m: float = 0.150 * 2e-5

    def __post_init__(self):
        _positive("DisplacementSensor", "range_m", self.range_m, allow_zero=False, unit="m")
        _positive("DisplacementSensor", "accuracy_fs", self.accuracy_fs, allow_zero=True)
        _positive("DisplacementSensor", "resolution_m", self.resolution_m, allow_zero=True, unit="m")
        _positive("DisplacementSensor", "noise_rms_m", self.noise_rms_m, allow_zero=True, unit="m")

    def _params(self):
        # the ADC spans ±range_m/2 about mid-stroke; doubling the relative accuracy keeps the absolute bound
        # accuracy_fs·range_m of the data sheet, which refers to the whole travel
        return self.range_m / 2, self.accuracy_fs * 2, self.noise_rms_m, self.resolution_m


@dataclass(frozen=True)
class SensorSet:
    """A rig's acquisition: load cell, stroke sensor, sampling rate (Hz) and the velocity filter.

    Velocity is not measured but computed from the recorded stroke, as in Table 7 ("computed from displacement
    signal"): zero-phase 4th-order Butterworth low-pass at ``velocity_cutoff_Hz`` (``None``: no filter), then
    second-order central differences. The 50 Hz default keeps Table 7's 0.5-12 Hz test frequencies intact
    while cutting the quantisation noise that differentiation amplifies.
    """

    load_cell: LoadCell = field(default_factory=LoadCell)
    displacement: DisplacementSensor = field(default_factory=DisplacementSensor)
    sample_rate_Hz: float = 1000.0
    velocity_cutoff_Hz: float | None = 50.0

    def __post_init__(self):
        _positive("SensorSet", "sample_rate_Hz", self.sample_rate_Hz, allow_zero=False, unit="Hz")
        if self.velocity_cutoff_Hz is not None:
            fc = float(self.velocity_cutoff_Hz)
            if not (math.isfinite(fc) and 0.0 < fc < self.sample_rate_Hz / 2):
                raise ValueError(f"SensorSet.velocity_cutoff_Hz = {self.velocity_cutoff_Hz!r} is invalid: must "
                                 f"be > 0 and < the Nyquist frequency {self.sample_rate_Hz / 2:g} Hz, or None")


def apply_sensors(t, x, F, sensors: SensorSet, rng, *, command, command_unit: str = "V", overrange: str = "raise",
                  label: str = "") -> DamperRecord:
    """Record a true stroke ``x`` (m) and force ``F`` (N), given on time grid ``t`` (s), with ``sensors``: what
    the rig records, as a :class:`~mrd_env.records.DamperRecord` on the acquisition grid t0 + k/sample_rate.

    The true signals are interpolated linearly onto that grid (give them on a finer grid than the acquisition's),
    then each sensor adds its static error and noise, saturates at its range and quantises (see ``_Sensor``).
    Velocity comes from the recorded stroke (see :class:`SensorSet`); ``command`` (V or A: one level, or one
    value per sample of ``t``) is recorded as given, held over each acquisition interval. ``overrange``: "raise"
    — ``ValueError`` if a true value exceeds a sensor's range; "clip" — the reading saturates; the record's
    ``saturated_x`` / ``saturated_force`` flag the saturated samples (noise alone reaching the range is flagged in
    either mode). ``rng``: Generator or int seed; each sensor draws from its own child stream, so changing one
    sensor leaves the other's errors unchanged.
    """
    if not isinstance(sensors, SensorSet):
        raise ValueError(f"sensors must be a SensorSet, got {type(sensors).__name__}")
    if overrange not in ("raise", "clip"):
        raise ValueError(f"overrange = {overrange!r} is invalid: must be 'raise' or 'clip'")
    rng = as_generator(rng)
    t = check_time("t", t)
    x = check_signal("x", x, n=t.shape[0])
    F = check_signal("F", F, n=t.shape[0])
    command = check_signal("command", np.broadcast_to(command, t.shape) if np.ndim(command) == 0 else command,
                           n=t.shape[0])
    if overrange == "raise":
        for what, sig, lim, unit in (("F", F, sensors.load_cell.range_N, "N"),
                                     ("x", x, sensors.displacement.range_m / 2, "m")):
            over = np.flatnonzero(np.abs(sig) > lim)
            if over.size:
                i = int(over[0])
                raise ValueError(f"{what} exceeds the sensor range ±{lim:g} {unit}: |{what}| reaches "
                                 f"{np.abs(sig).max():g} {unit}, first at t = {t[i]:g} s (pass "
                                 f"overrange='clip' to record it saturated)")
    dt = 1.0 / sensors.sample_rate_Hz
    n = int(math.floor((t[-1] - t[0]) / dt * (1 + 1e-12))) + 1
    if n < 3:
        raise ValueError(f"the record ({t[-1] - t[0]:g} s) is shorter than 2 sampling intervals of "
                         f"{dt:g} s")
    tm = t[0] + np.arange(n) / sensors.sample_rate_Hz
    rng_x, rng_f = rng.spawn(2)
    xm, sat_x = sensors.displacement.measure(np.interp(tm, t, x), rng_x)
    Fm, sat_f = sensors.load_cell.measure(np.interp(tm, t, F), rng_f)
    xf = xm
    if sensors.velocity_cutoff_Hz is not None:
        xf = lowpass_zero_phase(xm, sensors.velocity_cutoff_Hz, sensors.sample_rate_Hz)
    vm = np.gradient(xf, dt, edge_order=2)
    return DamperRecord(tm, xm, hold_previous(t, command, tm), Fm, vm, command_unit, label, saturated_x=sat_x,
                        saturated_force=sat_f)


# --- uncertainty budget (review Table 8) --------------------------------------------------------------------

_DIVISORS = {"rectangular": math.sqrt(3.0), "triangular": math.sqrt(6.0)}


@dataclass(frozen=True)
class Contribution:
    """One uncertainty source: ``value`` in % of reading (R) and its distribution.

    rectangular/triangular: ``value`` is the half-width a of the distribution, u = a/√3 or a/√6.
    normal: ``value`` is an expanded uncertainty with coverage factor ``k`` (default 2, ≈95 %), u = value/k;
    pass k=1 when the value already is a standard uncertainty.
    """

    name: str
    value: float
    distribution: str = "rectangular"
    k: float = 2.0

    def __post_init__(self):
        if self.distribution not in ("rectangular", "triangular", "normal"):
            raise ValueError(f"Contribution '{self.name}': distribution = {self.distribution!r} is invalid: "
                             f"must be 'rectangular', 'triangular' or 'normal'")
        v = float(self.value)
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"Contribution '{self.name}': value = {self.value!r} is invalid: must be >= 0 %")
        if not (math.isfinite(float(self.k)) and self.k > 0):
            raise ValueError(f"Contribution '{self.name}': k = {self.k!r} is invalid: must be > 0")

    @property
    def standard_uncertainty(self) -> float:
        """u_i (% R)."""
        if self.distribution == "normal":
            return self.value / self.k
        return self.value / _DIVISORS[self.distribution]


# Table 8 rows with an example value. "Test speed" is 0.2-10 % in the review; 1 % (near the geometric mean of
# the range) is our default and should be set from the machine's own data. The review gives "Display" as 0.5
# in its % column; it is read here as 0.5 % R, normal, expanded with k = 2.
TABLE8_DEFAULTS: tuple[Contribution, ...] = (
    Contribution("Drift", 0.04),
    Contribution("Mechanical and electrical noise", 0.1),
    Contribution("Resolution", 0.5),
    Contribution("Backlash", 0.1),
    Contribution("Temperature compensation", 0.01),
    Contribution("System zeroing", 0.1),
    Contribution("Display (readings error)", 0.5, "normal"),
    Contribution("Test speed", 1.0),
)
_CASE_DEPENDENT = {"stability": "Stability", "power_fluctuations": "Power fluctuations",
                   "specimen_alignment": "Specimen alignment and preparation"}


def table8_contributions(*, test_speed: float = 1.0, stability: float | None = None,
                         power_fluctuations: float | None = None,
                         specimen_alignment: float | None = None) -> list[Contribution]:
    """Table 8 contributions with the chosen test-speed value (0.2-10 % R) and the case-dependent rows
    (stability, power fluctuations, specimen alignment; % R, rectangular) included only when given."""
    if not (0.2 <= float(test_speed) <= 10.0):
        raise ValueError(f"test_speed = {test_speed!r} % is invalid: Table 8 gives 0.2 to 10 % R")
    rows = [c if c.name != "Test speed" else Contribution("Test speed", float(test_speed))
            for c in TABLE8_DEFAULTS]
    given = {"stability": stability, "power_fluctuations": power_fluctuations,
             "specimen_alignment": specimen_alignment}
    rows += [Contribution(_CASE_DEPENDENT[k], v) for k, v in given.items() if v is not None]
    return rows


@dataclass(frozen=True)
class UncertaintyBudget:
    """RSS budget (review Table 8): u_c = sqrt(Σ u_i²) and U = k·u_c, all in % of reading."""

    contributions: tuple[Contribution, ...]
    k: float = 2.0

    @property
    def combined(self) -> float:
        """u_c (% R)."""
        return math.sqrt(sum(c.standard_uncertainty ** 2 for c in self.contributions))

    @property
    def expanded(self) -> float:
        """U = k·u_c (% R)."""
        return self.k * self.combined

    def absolute(self, reading: float) -> float:
        """U for a reading (same unit as the reading, e.g. N)."""
        return abs(float(reading)) * self.expanded / 100.0

    def rows(self) -> list[list[str]]:
        out = [["Source", "Value (% R)", "Distribution", "Divisor", "u_i (% R)"]]
        for c in self.contributions:
            div = c.k if c.distribution == "normal" else _DIVISORS[c.distribution]
            out.append([c.name, f"{c.value:g}", c.distribution, f"{div:.4g}", f"{c.standard_uncertainty:.4g}"])
        out.append(["Combined standard uncertainty u_c", "", "", "", f"{self.combined:.4g}"])
        out.append([f"Expanded uncertainty U (k = {self.k:g})", "", "", "", f"{self.expanded:.4g}"])
        return out

    def to_markdown(self) -> str:
        rows = self.rows()
        lines = ["| " + " | ".join(rows[0]) + " |", "|" + "|".join("---" for _ in rows[0]) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
        return "\n".join(lines) + "\n"

    def to_csv(self, path: str | Path | None = None) -> str:
        """The budget as CSV text; also written to ``path`` if given."""
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(self.rows())
        if path is not None:
            storage.write_text(path, buf.getvalue())
        return buf.getvalue()


def rss_budget(contributions: Iterable[Contribution | tuple] = TABLE8_DEFAULTS, k: float = 2.0) -> UncertaintyBudget:
    """Combine contributions by root-sum-square (review section 4, Table 8).

    Each item is a :class:`Contribution` or a tuple (name, value %, distribution[, k_i]).
    """
    items = tuple(c if isinstance(c, Contribution) else Contribution(*c) for c in contributions)
    if not items:
        raise ValueError("contributions must not be empty")
    if not (math.isfinite(float(k)) and k > 0):
        raise ValueError(f"k = {k!r} is invalid: must be > 0")
    return UncertaintyBudget(items, float(k))


# --- Monte-Carlo propagation ----------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Per quantity: ``samples`` (array over successful draws), mean, std (ddof=1), the standard error of the
    mean ``sem``, and the central percentile interval [ci_low, ci_high] holding ``confidence`` of the draws
    (the coverage interval of GUM Supplement 1)."""

    samples: dict[str, np.ndarray]
    confidence: float
    n_failed: int = 0

    def _apply(self, fn) -> dict[str, float]:
        return {k: float(fn(v)) for k, v in self.samples.items()}

    @property
    def mean(self) -> dict[str, float]:
        return self._apply(np.mean)

    @property
    def std(self) -> dict[str, float]:
        return self._apply(lambda v: np.std(v, ddof=1))

    @property
    def sem(self) -> dict[str, float]:
        return self._apply(lambda v: np.std(v, ddof=1) / math.sqrt(v.size))

    @property
    def ci_low(self) -> dict[str, float]:
        return self._apply(lambda v: np.percentile(v, 50 * (1 - self.confidence)))

    @property
    def ci_high(self) -> dict[str, float]:
        return self._apply(lambda v: np.percentile(v, 50 * (1 + self.confidence)))

    def summary(self) -> dict[str, dict[str, float]]:
        """{quantity: {"mean", "std", "sem", "ci_low", "ci_high"}}."""
        parts = {"mean": self.mean, "std": self.std, "sem": self.sem, "ci_low": self.ci_low,
                 "ci_high": self.ci_high}
        return {q: {name: vals[q] for name, vals in parts.items()} for q in self.samples}


def monte_carlo(func: Callable[[np.random.Generator], Mapping[str, float] | float], n_draws: int, rng, *,
                confidence: float = 0.95, progress: bool = False, on_error: str = "raise",
                desc: str = "Monte Carlo", backend: str = "serial", jobs: int | None = None,
                address: str | None = None) -> MonteCarloResult:
    """Call ``func(rng_i)`` for ``n_draws`` independent child generators and summarise the results.

    ``func`` returns a dict of floats (a bare float is stored as "value"). The children come from
    ``SeedSequence.spawn`` of ``rng`` (Generator or int seed), so draw i is the same whatever the number of
    draws or the order they run in. ``on_error="skip"`` drops draws whose ``func`` raises (e.g. a fit that
    diverges) and counts them in ``n_failed``; ``progress`` shows a tqdm bar. The draws are tasks of
    :func:`mrd_env.executor.run_tasks` (``backend``, ``jobs``, ``address``; a pool or Ray needs a picklable
    ``func``): the result is the same on every backend.
    """
    if isinstance(n_draws, bool) or not isinstance(n_draws, (int, np.integer)) or n_draws < 2:
        raise ValueError(f"n_draws = {n_draws!r} is invalid: must be an int >= 2")
    c = float(confidence)
    if not (0.0 < c < 1.0):
        raise ValueError(f"confidence = {confidence!r} is invalid: must be in (0, 1)")
    if on_error not in ("raise", "skip"):
        raise ValueError(f"on_error = {on_error!r} is invalid: must be 'raise' or 'skip'")
    children = as_generator(rng).spawn(int(n_draws))
    tasks = [Task(_draw, (func, child, on_error == "skip"), label=f"{desc} draw {i}")
             for i, child in enumerate(children)]
    try:
        outcomes = run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress, desc=desc,
                             retry=False)  # a draw's error is deterministic: counted ("skip") or raised at once
    except TaskFailed as exc:  # on_error="raise": the draw's own error
        raise exc.error from None
    values: dict[str, list[float]] | None = None
    failed = 0
    for i, (ok, out) in enumerate(outcomes):
        if not ok:
            failed += 1
            continue
        out = {"value": out} if not isinstance(out, Mapping) else out
        if values is None:
            values = {k: [] for k in out}
        if set(out) != set(values):
            raise ValueError(f"func returned keys {sorted(out)} at draw {i}, but {sorted(values)} before")
        for k, val in out.items():
            values[k].append(float(val))
    n_ok = int(n_draws) - failed
    if values is None or n_ok < 2:
        raise ValueError(f"only {n_ok} of {n_draws} draws succeeded; need at least 2")
    return MonteCarloResult({k: np.asarray(v) for k, v in values.items()}, c, failed)


def _draw(func, child: np.random.Generator, skip_errors: bool):
    """One Monte-Carlo draw: (True, result), or (False, the error) when errors are skipped."""
    try:
        return True, func(child)
    except Exception as exc:  # noqa: BLE001 — counted as a failed draw by monte_carlo
        if not skip_errors:
            raise
        return False, f"{type(exc).__name__}: {exc}"
