"""A building's seismic responses from a record and the structural-control benchmark's criteria J1–J6 (SI)."""
from __future__ import annotations

from typing import Iterable, Mapping

import numpy as np

from ...metrics import as_series, as_signal, rms, sample_interval
from ...validation import check_array, check_scalar


def _peak(x: np.ndarray) -> float:
    return float(np.max(np.abs(x)))


def _worst_rms(x: np.ndarray) -> float:
    """Largest per-channel r.m.s. (the benchmark's "normed" response, max over storeys/floors)."""
    return float(np.max(rms(x)))


def building_metrics(dt, drift, storey_heights, abs_acc, base_shear=None, damper_force=None, *,
                     floor_masses=None, damper_stroke=None, displacement=None) -> dict[str, float]:
    """Peak and r.m.s. responses of one seismic record of a building.

    Signals have time along axis 0 and the same number of samples; 2-D ones may be 1-D for one channel:

    * ``drift`` (n, n_storeys): interstorey drifts, m; ``storey_heights``: (n_storeys,) or scalar, m > 0;
    * ``abs_acc`` (n, n_floors): absolute floor accelerations, m/s²;
    * ``base_shear`` (n,): N; if omitted but ``floor_masses`` (n_floors,) kg are given, the base shear
      is the floors' total inertia force Σ m_i·ẍ_a,i (which includes any device at the base);
    * ``damper_force`` (n, n_dampers), N; ``damper_stroke`` (n, n_dampers), m;
      ``displacement`` (n, n_floors): floor displacements relative to the ground, m.

    Keys: ``drift_peak``, ``drift_rms`` (m); ``drift_ratio_peak``, ``drift_ratio_rms`` (−);
    ``acc_peak``, ``acc_rms`` (m/s²); and where the inputs are given ``base_shear_peak``,
    ``base_shear_rms`` (N), ``damper_force_peak`` (N), ``damper_stroke_peak`` (m), ``disp_peak`` (m).
    Peaks are over time and channels; r.m.s. values are the largest per-channel r.m.s. over the record.
    """
    d = as_signal("drift", drift, columns=True)
    n, n_storeys = d.shape
    # Uniform sampling makes peaks and r.m.s. values step-free; dt is checked for a consistent API.
    sample_interval(dt, n)
    h = check_array("storey_heights", storey_heights, unit="m")
    if h.ndim > 1 or (h.ndim == 1 and h.size != n_storeys):
        raise ValueError(f"storey_heights must be a scalar or have {n_storeys} entries (one per drift "
                         f"column), got shape {h.shape}")
    if np.any(h <= 0):
        raise ValueError(f"storey_heights must be > 0 m, got minimum {h.min():g} m")
    acc = as_signal("abs_acc", abs_acc, n=n, columns=True)
    ratio = d / h

    out = {
        "drift_peak": _peak(d), "drift_rms": _worst_rms(d),
        "drift_ratio_peak": _peak(ratio), "drift_ratio_rms": _worst_rms(ratio),
        "acc_peak": _peak(acc), "acc_rms": _worst_rms(acc),
    }
    if base_shear is None and floor_masses is not None:
        m = check_array("floor_masses", floor_masses, shape=(acc.shape[1],), unit="kg")
        if np.any(m <= 0):
            raise ValueError(f"floor_masses must be > 0 kg, got minimum {m.min():g} kg")
        base_shear = acc @ m
    if base_shear is not None:
        v = as_series("base_shear", base_shear, n)
        out["base_shear_peak"], out["base_shear_rms"] = _peak(v), _worst_rms(v)
    for name, value, key in (("damper_force", damper_force, "damper_force_peak"),
                             ("damper_stroke", damper_stroke, "damper_stroke_peak"),
                             ("displacement", displacement, "disp_peak")):
        if value is not None:
            out[key] = _peak(as_signal(name, value, n=n, columns=True))
    return out


# Criterion → the building_metrics key it normalises (controlled over uncontrolled).
_BENCHMARK_J = {
    "J1": "drift_ratio_peak", "J2": "acc_peak", "J3": "base_shear_peak",
    "J4": "drift_ratio_rms", "J5": "acc_rms", "J6": "base_shear_rms",
}


def _positive(d: Mapping[str, float], name: str, key: str, criterion: str) -> float:
    value = check_scalar(f"{name}[{key!r}]", d[key], 0.0)
    if value == 0.0:
        raise ValueError(f"{name}[{key!r}] = 0: {criterion} is undefined — the uncontrolled response it "
                         "normalises by must be non-zero")
    return value


def benchmark_criteria(controlled: Mapping[str, float], uncontrolled: Mapping[str, float], *,
                       building_weight: float | None = None) -> dict[str, float]:
    """Evaluation criteria of the seismic structural-control benchmark for one record.

    After the benchmark of Ohtori et al. (2004, J. Eng. Mech.) — an UNVERIFIED recollection: the
    project's reference page could not check the definitions or numbering against the paper.
    ``controlled``/``uncontrolled`` are :func:`building_metrics` dicts of the same record. Ratios,
    < 1 is better:

    J1 peak interstorey drift ratio, J2 peak absolute floor acceleration, J3 peak base shear;
    J4–J6 the same with r.m.s. ("normed") responses — each over the uncontrolled value (J3/J6 only if
    both dicts have base shear). Control effort, where the inputs exist: ``force_over_weight`` — peak
    device force over ``building_weight`` (N, e.g. ``G * total_mass``); ``stroke_peak`` — peak device
    stroke, m; ``stroke_over_disp`` — that stroke over the uncontrolled peak floor displacement (the
    normalisation is part of the same unverified recollection). The peak and total control power are
    :func:`control_power`'s.
    Take the maximum over several records with :func:`max_over_records`.
    """
    out = {}
    for criterion, key in _BENCHMARK_J.items():
        has_c, has_u = key in controlled, key in uncontrolled
        if has_c != has_u:
            which = "uncontrolled" if has_c else "controlled"
            raise ValueError(f"{which} lacks {key!r}, needed for {criterion}; compute both with the same inputs")
        if has_c:
            out[criterion] = (check_scalar(f"controlled[{key!r}]", controlled[key], 0.0)
                              / _positive(uncontrolled, "uncontrolled", key, criterion))
    if "damper_force_peak" in controlled and building_weight is not None:
        w = check_scalar("building_weight", building_weight, 0.0, lo_open=True, unit="N")
        out["force_over_weight"] = check_scalar("controlled['damper_force_peak']",
                                                controlled["damper_force_peak"], 0.0) / w
    if "damper_stroke_peak" in controlled:
        stroke = check_scalar("controlled['damper_stroke_peak']", controlled["damper_stroke_peak"], 0.0)
        out["stroke_peak"] = stroke
        if "disp_peak" in uncontrolled:
            out["stroke_over_disp"] = stroke / _positive(uncontrolled, "uncontrolled", "disp_peak",
                                                        "stroke_over_disp")
    return out


def control_power(dt, damper_force, damper_velocity) -> dict[str, float]:
    """The control power of a building's dampers on one record: the structural benchmarks' peak and total control
    power with the power of device i taken as the mechanical power it exchanges with the structure, |F_i·ẋ_i|
    (``damper_force`` (n, n_dampers) N, as measured; ``damper_velocity`` (n, n_dampers) m/s, its stroke rate):

    ``control_power_peak`` = max over the samples of Σ_i |F_i·ẋ_i| (W);
    ``control_power_total`` = Σ over the samples after the first of Σ_i |F_i·ẋ_i| × dt (J; each sample stands
    for the step ending at it, as the environments accumulate it).

    Unnormalised: the benchmark divides them by a velocity or displacement of the uncontrolled building and its
    weight, a normalisation this project could not check (the reference page recalls the criteria, not their
    definitions)."""
    f = as_signal("damper_force", damper_force, columns=True)
    v = as_signal("damper_velocity", damper_velocity, n=f.shape[0], columns=True)
    if v.shape != f.shape:
        raise ValueError(f"damper_velocity must have the shape of damper_force {f.shape}, got {v.shape}")
    step = sample_interval(dt, f.shape[0])
    p = np.sum(np.abs(f * v), axis=1)
    return {"control_power_peak": float(np.max(p)), "control_power_total": float(np.sum(p[1:]) * step)}


def max_over_records(records: Iterable[Mapping[str, float]]) -> dict[str, float]:
    """Key-wise maximum of per-record criteria — the benchmark's worst case over earthquakes."""
    records = list(records)
    if not records:
        raise ValueError("records must hold at least one criteria dict")
    keys = set(records[0])
    for i, r in enumerate(records[1:], start=1):
        if set(r) != keys:
            raise ValueError(f"records[{i}] has keys {sorted(r)}, expected {sorted(keys)} like records[0]")
    return {k: max(check_scalar(f"records[{i}][{k!r}]", r[k]) for i, r in enumerate(records))
            for k in records[0]}
