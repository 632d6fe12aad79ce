"""Input checks shared by the whole package: every bad value raises a ``ValueError`` that names it."""
from __future__ import annotations

import math
import reprlib

import numpy as np


def check_scalar(name: str, value, lo: float = -math.inf, hi: float = math.inf, *,
                 lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a float if it is finite and inside the range, else raise ``ValueError``."""
    v = as_real(name, value)
    lo_ok = v > lo if lo_open else v >= lo
    hi_ok = v < hi if hi_open else v <= hi
    if not math.isfinite(v) or not (lo_ok and hi_ok):
        raise ValueError(f"{name} = {shown(value)} is invalid: must be "
                         f"{describe_range(lo, hi, lo_open, hi_open, unit)}")
    return v


def as_real(name: str, value) -> float:
    """``float(value)``, or a ``ValueError`` naming ``name`` for anything that is not one real number (a complex
    value would lose its imaginary part silently, an int beyond float64 raises ``OverflowError``, and a string is
    text, not a number: ``float("1")`` would take a mistyped option as 1)."""
    try:
        if np.iscomplexobj(value) or isinstance(value, (str, bytes, np.str_, np.bytes_)):
            raise TypeError("not a real number")
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a real number, got {shown(value)}") from None


def shown(value) -> str:
    """A value as a message shows it: NumPy scalars as plain numbers (not ``np.float64(0.002)``), others by a
    short repr."""
    if isinstance(value, np.generic):
        value = value.item()
    return reprlib.repr(value)


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
        raw = np.asarray(value)
        if raw.dtype.kind in "cmMV":  # complex, time stamps, structured: a float cast would discard or invent data
            raise TypeError(raw.dtype)
        a = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
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


#: The fewest samples a time series may hold: second-order differences at both ends need three.
MIN_RECORD_SAMPLES = 3


def check_signal(label: str, value, *, n: int | None = None, item: str = "index") -> np.ndarray:
    """``value`` as a 1-D float64 array of finite numbers (of length ``n`` if given), else ``ValueError``."""
    try:
        if np.iscomplexobj(value):  # a float cast would drop the imaginary part silently
            raise TypeError("complex")
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{label} must be a 1-D array of real numbers") from None
    if a.ndim != 1:
        raise ValueError(f"{label} must be 1-D, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{label} has {a.shape[0]} samples, expected {n} (the length of the other columns)")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{label} has a non-finite value ({a[i]}) at {item} {i}")
    return a


def check_time(label: str, t, *, n: int | None = None, item: str = "index") -> np.ndarray:
    """A finite, strictly increasing time grid with at least three samples."""
    t = check_signal(label, t, n=n, item=item)
    if t.shape[0] < MIN_RECORD_SAMPLES:
        raise ValueError(f"{label} must have at least {MIN_RECORD_SAMPLES} samples, got {t.shape[0]}")
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{label} is not strictly increasing at {item} {i} "
                         f"({shown(t[i - 1])} followed by {shown(t[i])})")
    return t


#: The most samples one generated record may hold (0.8 GB per float64 channel): a larger count comes from a
#: mistyped duration, cycle count or step, and would otherwise end in an unrelated memory error.
MAX_SAMPLES = 100_000_000


def check_n_samples(n: float, what: str) -> float:
    """``n`` (a sample count computed from the arguments described by ``what``) if it is at most
    :data:`MAX_SAMPLES`, else a ``ValueError`` naming those arguments."""
    if not n <= MAX_SAMPLES:
        raise ValueError(f"{what} asks for {n:.3g} samples, more than the {MAX_SAMPLES:.0e} a record may hold")
    return n


def as_generator(rng, name: str = "rng") -> np.random.Generator:
    """``rng`` as a ``numpy.random.Generator`` — the project's one rule for random-number arguments: a Generator
    is used as is, a ``SeedSequence`` or an int seed >= 0 seeds a new one, None draws fresh OS entropy (not
    reproducible: what ``numpy.random.default_rng(None)`` does). Functions whose results must be reproducible take
    ``rng`` without a default or with an int default, so None is only ever the caller's explicit choice."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None:
        return np.random.default_rng()
    if isinstance(rng, np.random.SeedSequence):
        return np.random.default_rng(rng)
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and rng >= 0:
        return np.random.default_rng(int(rng))
    raise ValueError(f"{name} must be a numpy.random.Generator, a SeedSequence, an int seed >= 0 or None, got {reprlib.repr(rng)}")
