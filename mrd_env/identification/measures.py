"""Normalised model-error measures of the review: E_t, E_x, E_v (eq. 3) and J1, J2 (eqs. 25-26).

All inputs are SI (s, m, m/s, N). Time integrals use the trapezoidal rule on the sampled time grid, which may
be non-uniform but must be strictly increasing. Derivatives use ``numpy.gradient`` with ``edge_order=2``:
second-order central differences on the (possibly non-uniform) grid and second-order one-sided differences at
the two ends.

Eq. (3) weights the squared force error by |dx/dt| for E_x and by |d(dx/dt)/dt| (the acceleration) for E_v,
so E_x stresses the fast part of a stroke and E_v the velocity reversals. F̄_exp, the "average along the T
period", is the time average (1/T)∫F_exp dt, computed with the same trapezoidal rule so that F = F̄_exp gives
E_t = 1 exactly on any grid.
"""
from __future__ import annotations

import math

import numpy as np

from ..validation import check_signal, check_time

__all__ = ["error_time", "error_displacement", "error_velocity", "j1", "j2", "error_measures"]

def _forces_and_time(F_exp, F, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    F_exp = check_signal("F_exp", F_exp)
    F = check_signal("F", F, n=F_exp.shape[0])
    t = check_time("t", t, n=F_exp.shape[0])
    return F_exp, F, t


def _velocity(t: np.ndarray, x, v) -> np.ndarray:
    """Measured velocity if given, else dx/dt of the displacement on the time grid."""
    if v is not None:
        return check_signal("v", v, n=t.shape[0])
    if x is None:
        raise ValueError("give the displacement x (m) or the velocity v (m/s)")
    return np.gradient(check_signal("x", x, n=t.shape[0]), t, edge_order=2)


def scored_intervals(t: np.ndarray, mask=None) -> np.ndarray:
    """The lengths of the time steps the integrals run over (s): every step of ``t``, or with ``mask`` (a bool per
    sample) only the steps whose two ends are scored — an excluded span (a fault) is not bridged."""
    h = np.diff(t)
    if mask is None:
        return h
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != t.shape:
        raise ValueError(f"mask must have one value per sample ({t.shape[0]}), got shape {mask.shape}")
    h = np.where(mask[:-1] & mask[1:], h, 0.0)
    if not h.sum() > 0.0:
        raise ValueError("mask must keep at least two consecutive samples")
    return h


def _integral(g: np.ndarray, h: np.ndarray) -> float:
    """∫g dt by the trapezoidal rule over the steps of lengths ``h`` (those of length 0 left out)."""
    return float(np.sum(0.5 * (g[:-1] + g[1:]) * h))


def _normalised_error(F_exp: np.ndarray, F: np.ndarray, w: np.ndarray, name: str, h: np.ndarray) -> float:
    """sqrt(∫(F_exp-F)² w dt / ∫(F_exp-F̄_exp)² w dt), trapezoidal in time over the steps ``h``
    (:func:`scored_intervals`) — the common form of eq. (3)."""
    mean = _integral(F_exp, h) / h.sum()
    den = _integral((F_exp - mean) ** 2 * w, h)
    if not den > 0.0:
        raise ValueError(f"{name} is undefined: the weighted variance of F_exp is zero (constant measured force "
                         f"or zero weight everywhere)")
    return math.sqrt(_integral((F_exp - F) ** 2 * w, h) / den)


# --- public measures --------------------------------------------------------------------------------------------

def error_time(F_exp, F, t) -> float:
    """E_t of review eq. (3): RMS force error over the measured force's RMS deviation from its time mean."""
    F_exp, F, t = _forces_and_time(F_exp, F, t)
    return _normalised_error(F_exp, F, np.ones_like(t), "E_t", np.diff(t))


def error_displacement(F_exp, F, t, x=None, *, v=None) -> float:
    """E_x of review eq. (3): as E_t, weighted by |dx/dt|.

    ``x`` is the displacement (m), differentiated on ``t``; or give the measured velocity ``v`` (m/s).
    """
    F_exp, F, t = _forces_and_time(F_exp, F, t)
    return _normalised_error(F_exp, F, np.abs(_velocity(t, x, v)), "E_x", np.diff(t))


def error_velocity(F_exp, F, t, x=None, *, v=None) -> float:
    """E_v of review eq. (3): as E_t, weighted by |d(dx/dt)/dt| (the acceleration magnitude).

    The acceleration is the derivative of ``v`` (m/s) if given, else the second derivative of ``x`` (m).
    """
    F_exp, F, t = _forces_and_time(F_exp, F, t)
    a = np.gradient(_velocity(t, x, v), t, edge_order=2)
    return _normalised_error(F_exp, F, np.abs(a), "E_v", np.diff(t))


def j1(F_exp, F) -> float:
    """J1 of review eq. (25): sum of squared force errors over the samples (N²)."""
    F_exp = check_signal("F_exp", F_exp)
    F = check_signal("F", F, n=F_exp.shape[0])
    if F_exp.shape[0] == 0:
        raise ValueError("F_exp must have at least one sample")
    return float(np.sum((F_exp - F) ** 2))


def j2(F_exp, F) -> float:
    """J2 of review eq. (26): root-mean-square force error over the samples (N)."""
    F_exp = check_signal("F_exp", F_exp)
    return math.sqrt(j1(F_exp, F) / F_exp.shape[0])


def error_measures(F_exp, F, t, x=None, *, v=None, mask=None) -> dict[str, float]:
    """All five measures {"E_t", "E_x", "E_v", "J1", "J2"} (review eqs. 3, 25, 26).

    E_* are dimensionless ratios (multiply by 100 for the review's percentages), J1 is in N², J2 in N.
    Needs the displacement ``x`` (m) or the measured velocity ``v`` (m/s) for E_x and E_v. ``mask`` (a bool per
    sample): score only those samples — the integrals over the steps between two scored samples, the derivatives
    on the whole grid, J1 and J2 over the scored samples — so that an excluded span is neither scored nor bridged.
    """
    F_exp, F, t = _forces_and_time(F_exp, F, t)
    vel = _velocity(t, x, v)
    acc = np.gradient(vel, t, edge_order=2)
    h = scored_intervals(t, mask)
    m = slice(None) if mask is None else np.asarray(mask, dtype=bool)
    return {
        "E_t": _normalised_error(F_exp, F, np.ones_like(t), "E_t", h),
        "E_x": _normalised_error(F_exp, F, np.abs(vel), "E_x", h),
        "E_v": _normalised_error(F_exp, F, np.abs(acc), "E_v", h),
        "J1": j1(F_exp[m], F[m]),
        "J2": j2(F_exp[m], F[m]),
    }
