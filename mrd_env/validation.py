"""Input checks shared by the whole package: every bad value raises a ``ValueError`` that names it."""
from __future__ import annotations

import math

import numpy as np


def check_scalar(name: str, value, lo: float = -math.inf, hi: float = math.inf, *,
                 lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a float if it is finite and inside the range, else raise ``ValueError``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    lo_ok = v > lo if lo_open else v >= lo
    hi_ok = v < hi if hi_open else v <= hi
    if not math.isfinite(v) or not (lo_ok and hi_ok):
        raise ValueError(f"{name} = {value!r} is invalid: must be {describe_range(lo, hi, lo_open, hi_open, unit)}")
    return v


def describe_range(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False, unit: str = "") -> str:
    u = f" {unit}" if unit else ""
    parts = []
    if lo > -math.inf:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}{u}")
    if hi < math.inf:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}{u}")
    return ("finite and " + " and ".join(parts)) if parts else "finite"


def check_array(name: str, value, *, ndim: int | None = None, shape: tuple | None = None,
                lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> np.ndarray:
    """Return ``value`` as a float64 array after checking shape, finiteness and range."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of real numbers") from None
    if ndim is not None and a.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-dimensional, got shape {a.shape}")
    if shape is not None and a.shape != tuple(shape):
        raise ValueError(f"{name} must have shape {tuple(shape)}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        i = np.flatnonzero(~np.isfinite(a.ravel()))[0]
        raise ValueError(f"{name} contains a non-finite value at flat index {i}")
    if a.size and (a.min() < lo or a.max() > hi):
        raise ValueError(f"{name} has values in [{a.min():g}, {a.max():g}] outside the valid range "
                         f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''}")
    return a
