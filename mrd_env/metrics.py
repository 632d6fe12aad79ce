"""Performance metrics: ISO 2631-1 ride comfort (frequency weighting, r.m.s., VDV, MTVV) and the signal checks the
plants' metrics share (each plant's own metrics are in its folder: ``mrd_env/plants/<plant>/metrics.py``).

All inputs and outputs are in SI units; time runs along axis 0 of every signal. Wherever a sample
interval ``dt`` (s) is expected, a uniformly spaced time vector of the signal's length is accepted too.

ISO 2631-1 frequency weighting
------------------------------
``W = Hh·Hl·Ht·Hs`` (ISO 2631-1:1997, Annex A): Hh, Hl second-order Butterworth high/low-pass band
limits at f1 = 0.4 Hz and f2 = 100 Hz, Ht the acceleration–velocity transition and Hs the upward step
(Wk only). :func:`weighting_magnitude` evaluates the analog weighting exactly.

Sampled signals are weighted by :func:`weighted_acceleration`:

* ``method="iir"`` (default, causal, usable sample by sample with :func:`weighting_sos`): every
  factor is discretised by the bilinear transform with its own corner frequencies pre-warped, so each
  corner keeps its analog frequency. The residual error comes from the warping of the 1/f slope above
  f4. Measured magnitude error of the digital Wk against the analog one:

  ========  ==========  =======  =======  =======  =======
  fs        ≤ 12.5 Hz   16 Hz    31.5 Hz  63 Hz    80 Hz
  ========  ==========  =======  =======  =======  =======
  2 kHz     < 0.01 %    −0.01 %  −0.06 %  −0.18 %  −0.35 %
  1 kHz     < 0.01 %    −0.02 %  −0.23 %  −0.75 %  −1.4 %
  500 Hz    < 0.03 %    −0.09 %  −0.93 %  −3.1 %   −5.7 %
  200 Hz    < 0.11 %    −0.63 %  −6.8 %   —        —
  100 Hz    < 0.45 %    −2.8 %   −32 %    —        —
  ========  ==========  =======  =======  =======  =======

  Wd at 1 kHz: within 0.12 % up to 20 Hz, −0.27 % at 31.5 Hz, −1.4 % at 80 Hz (at 100 Hz: −2 % at
  8 Hz). When fs ≤ 2·f2 the band-limiting low-pass Hl cannot be represented and is omitted
  (|Hl| > 0.987 below 0.4·f2, so this alone adds at most +1.3 % below 40 Hz).
* ``method="fft"``: multiplies the spectrum of the zero-padded record by the exact analog W(j2πf);
  exact at any sample rate for the band-limited signal (zero before and after the record), but
  needs the whole record (offline only). Prefer it below fs ≈ 1 kHz.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Callable

import numpy as np
from scipy import fft as sfft

from .constants import GRAVITY as G  # noqa: F401 (standard gravity, m/s²; ``metrics.G`` kept for callers)
from .validation import check_array, check_scalar

_Q_BUTTERWORTH = 1.0 / math.sqrt(2.0)

# ISO 2631-1:1997 Annex A, values as on the project's reference page. Wb (ISO 2631-4) is deliberately
# absent: its parameters could not be checked against the standard here.
_WEIGHTINGS: dict[str, dict[str, float]] = {
    "Wk": dict(f1=0.4, f2=100.0, f3=12.5, f4=12.5, q4=0.63, f5=2.37, q5=0.91, f6=3.35, q6=0.91),
    "Wd": dict(f1=0.4, f2=100.0, f3=2.0, f4=2.0, q4=0.63),
}

# Padding of the FFT method, in decay time constants of the slowest pole: e^-14 ≈ 1e-6, so the
# circular wrap-around of the impulse response stays below 1 ppm.
_FFT_PAD_TIME_CONSTANTS = 14.0

# Relative jitter tolerated in a time vector before it is rejected as non-uniform.
_UNIFORM_TOL = 1e-6


# ----------------------------------------------------------------------------------------------
# input checks
# ----------------------------------------------------------------------------------------------

def _weighting_params(kind: str) -> dict[str, float]:
    try:
        return _WEIGHTINGS[kind]
    except (KeyError, TypeError):
        raise ValueError(f"kind = {kind!r} is invalid: must be one of {sorted(_WEIGHTINGS)}") from None


def as_signal(name: str, value, *, n: int | None = None, columns: bool = False) -> np.ndarray:
    """A finite signal with time along axis 0 (``columns``: 2-D (n_samples, n_channels), 1-D = one
    channel); ``n`` the required number of samples."""
    try:
        a = check_array(name, value)
    except ValueError as e:  # the shared check names the argument; add what is valid
        raise ValueError(f"{e}: must be finite real numbers") from None
    if columns and a.ndim == 1:
        a = a[:, None]
    if (columns and a.ndim != 2) or a.ndim == 0:
        want = "(n_samples, n_channels) or (n_samples,)" if columns else "at least 1-dimensional"
        raise ValueError(f"{name} must be {want}, got shape {a.shape}")
    if a.shape[0] == 0 or a.size == 0:
        raise ValueError(f"{name} must hold at least one sample, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} must have {n} samples along axis 0 (like the other signals), got {a.shape[0]}")
    return a


def as_series(name: str, value, n: int | None = None) -> np.ndarray:
    """A finite 1-D signal of ``n`` samples."""
    a = as_signal(name, value, n=n)
    if a.ndim != 1:
        raise ValueError(f"{name} must be 1-dimensional (n_samples,), got shape {a.shape}")
    return a


def sample_interval(dt, n: int) -> float:
    """Sample interval in s from a scalar ``dt`` or a uniformly spaced time vector of ``n`` samples."""
    if np.ndim(dt) == 0:
        return check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    t = check_array("dt (time vector)", dt, ndim=1)
    if t.size != n or n < 2:
        raise ValueError(f"dt (time vector) must have the signals' {n} samples (and at least 2), got {t.size}")
    steps = np.diff(t)
    step = (t[-1] - t[0]) / (n - 1)
    if step <= 0 or np.max(np.abs(steps - step)) > _UNIFORM_TOL * step:
        raise ValueError("dt (time vector) must be strictly increasing and uniformly spaced "
                         f"(steps within {_UNIFORM_TOL:g} relative); resample the record first")
    return float(step)


# ----------------------------------------------------------------------------------------------
# ISO 2631-1 frequency weighting
# ----------------------------------------------------------------------------------------------

def _sections(kind: str, omega: Callable[[float], float], low_pass: bool = True) -> list[tuple[list, list]]:
    """The factors Hh, Hl, Ht, Hs of ISO 2631-1 Annex A as (num, den) polynomials in s.

    ``omega`` maps a frequency in Hz to the angular frequency used in the formula: 2πf for the analog
    filter, the pre-warped value for the bilinear transform.
    """
    p = _weighting_params(kind)
    q = _Q_BUTTERWORTH
    w1, w3, w4 = omega(p["f1"]), omega(p["f3"]), omega(p["f4"])
    secs = [([1.0, 0.0, 0.0], [1.0, w1 / q, w1 ** 2])]                              # Hh
    if low_pass:
        w2 = omega(p["f2"])
        secs.append(([w2 ** 2], [1.0, w2 / q, w2 ** 2]))                            # Hl
    secs.append(([1.0 / w3, 1.0], [1.0 / w4 ** 2, 1.0 / (p["q4"] * w4), 1.0]))     # Ht
    if "f5" in p:
        w5, w6 = omega(p["f5"]), omega(p["f6"])
        secs.append(([1.0, w5 / p["q5"], w5 ** 2], [1.0, w6 / p["q6"], w6 ** 2]))   # Hs
    return secs


def _analog_omega(f: float) -> float:
    return 2.0 * math.pi * f


def iso2631_weighting(kind: str = "Wk", *, as_tf: bool = False):
    """Analog ISO 2631-1 weighting W(s) = Hh·Hl·Ht·Hs (Annex A).

    ``kind``: "Wk" (vertical, seated/standing/recumbent) or "Wd" (horizontal). Returns ``(num, den)``,
    polynomial coefficients in s in descending powers, or a ``control.TransferFunction`` if ``as_tf``.
    """
    num, den = np.array([1.0]), np.array([1.0])
    for b, a in _sections(kind, _analog_omega):
        num, den = np.polymul(num, b), np.polymul(den, a)
    # Ht's denominator is written with a unit constant term; make den monic as scipy/control prefer.
    num, den = num / den[0], den / den[0]
    if as_tf:
        import control  # deferred: python-control is slow to import and only needed here

        return control.TransferFunction(num, den)
    return num, den


def _analog_response(kind: str, f: np.ndarray) -> np.ndarray:
    """Complex W(j2πf), evaluated factor by factor (better conditioned than the expanded polynomials)."""
    s = 2j * np.pi * f
    h = np.ones_like(s)
    for b, a in _sections(kind, _analog_omega):
        h = h * np.polyval(b, s) / np.polyval(a, s)
    return h


def weighting_magnitude(kind: str, f) -> np.ndarray:
    """|W(j2πf)| of the analog ISO 2631-1 weighting at frequencies ``f`` (Hz, ≥ 0)."""
    return np.abs(_analog_response(kind, check_array("f", f, lo=0.0, unit="Hz")))


@lru_cache(maxsize=64)
def _sos(kind: str, dt: float) -> np.ndarray:
    from scipy import signal  # ~1 s of import: only where a weighting is built (cars, isolator; no building)

    fs = 1.0 / dt
    low_pass = _weighting_params(kind)["f2"] < fs / 2

    def prewarped(f: float) -> float:
        return 2.0 * fs * math.tan(math.pi * f / fs)

    rows = []
    for b, a in _sections(kind, prewarped, low_pass):
        bz, az = signal.bilinear(b, a, fs)
        rows.append(np.concatenate([bz, az]) / az[0])
    sos = np.array(rows)
    sos.flags.writeable = False  # shared by the cache; callers get copies
    return sos


def weighting_sos(kind: str, dt: float) -> np.ndarray:
    """Digital ISO 2631-1 weighting as second-order sections (``scipy.signal.sosfilt`` layout), for
    sample interval ``dt`` in s.

    Bilinear transform of each factor with its corner frequencies pre-warped (see the module docstring
    for the accuracy). The sample rate must exceed twice every corner frequency other than f2.
    """
    p = _weighting_params(kind)
    # pre-warping tan(πf/fs) only maps corners below the Nyquist frequency
    f_max = max(v for k, v in p.items() if k in ("f1", "f3", "f4", "f5", "f6"))
    try:
        dt = check_scalar("dt", dt, 0.0, 1.0 / (2.0 * f_max), lo_open=True, hi_open=True, unit="s")
    except ValueError as e:
        raise ValueError(f"{e} (the {kind} weighting needs a sample rate above 2 x {f_max:g} Hz)") from None
    return _sos(kind, dt).copy()


def _weighting_fft(a: np.ndarray, dt: float, kind: str) -> np.ndarray:
    _, den = iso2631_weighting(kind)
    decay = np.min(-np.roots(den).real)  # slowest pole's decay rate, 1/s
    n = a.shape[0]
    nfft = sfft.next_fast_len(n + int(math.ceil(_FFT_PAD_TIME_CONSTANTS / (decay * dt))), real=True)
    h = _analog_response(kind, sfft.rfftfreq(nfft, dt))
    spec = sfft.rfft(a, nfft, axis=0) * h.reshape((-1,) + (1,) * (a.ndim - 1))
    return sfft.irfft(spec, nfft, axis=0)[:n]


def weighted_acceleration(a, dt, kind: str = "Wk", method: str = "iir") -> np.ndarray:
    """Frequency-weighted acceleration a_w (m/s²) per ISO 2631-1, the signal at rest before t = 0.

    ``a``: acceleration in m/s², time along axis 0. ``method``: "iir" (causal digital filter,
    :func:`weighting_sos`) or "fft" (exact analog weighting, offline); see the module docstring.
    """
    if method not in ("iir", "fft"):
        raise ValueError(f"method = {method!r} is invalid: must be 'iir' or 'fft'")
    a = as_signal("a", a)
    step = sample_interval(dt, a.shape[0])
    if method == "iir":
        from scipy import signal

        return signal.sosfilt(weighting_sos(kind, step), a, axis=0)
    _weighting_params(kind)
    return _weighting_fft(a, step, kind)


def rms(x, axis: int = 0):
    """Root mean square over ``axis`` (ISO 2631-1 §6.2 basic evaluation: mean over the whole record)."""
    x = as_signal("x", x)
    return np.sqrt(np.mean(np.square(x), axis=axis))


def weighted_rms(a, dt, kind: str = "Wk", method: str = "iir"):
    """Overall weighted r.m.s. acceleration a_w (m/s², ISO 2631-1 §6.2) of ``a`` (m/s²)."""
    return rms(weighted_acceleration(a, dt, kind, method))


def vdv(a_w, dt):
    """Fourth-power vibration dose value VDV = (∫ a_w⁴ dt)^¼ in m/s^1.75 (ISO 2631-1 §6.3.2).

    ``a_w`` must already be frequency-weighted (:func:`weighted_acceleration`).
    """
    a_w = as_signal("a_w", a_w)
    return np.sum(a_w ** 4, axis=0) ** 0.25 * sample_interval(dt, a_w.shape[0]) ** 0.25


def running_rms(a_w, dt, tau: float = 1.0) -> np.ndarray:
    """Running r.m.s. a_w(t0) = [1/τ ∫ a_w² dt over (t0 − τ, t0)]^½ (ISO 2631-1 §6.3.1, linear
    integration; τ = 1 s recommended).

    The signal is taken as zero before the record, so the first ``tau`` s ramp up as in a meter
    started at rest. ``a_w`` must already be frequency-weighted.
    """
    a_w = as_signal("a_w", a_w)
    step = sample_interval(dt, a_w.shape[0])
    tau = check_scalar("tau", tau, 0.0, lo_open=True, unit="s")
    window = max(1, int(round(tau / step)))
    energy = np.cumsum(np.square(a_w), axis=0)
    energy[window:] -= energy[:-window].copy()
    # cumulative-sum differences can dip a hair below zero in quiet stretches
    return np.sqrt(np.maximum(energy, 0.0) / window)


def mtvv(a_w, dt, tau: float = 1.0):
    """Maximum transient vibration value MTVV = max a_w(t0) of :func:`running_rms` (ISO 2631-1 §6.3.1), m/s²."""
    return np.max(running_rms(a_w, dt, tau), axis=0)


# ----------------------------------------------------------------------------------------------
# constraint exceedance (the environments' constraint costs, on a record)
# ----------------------------------------------------------------------------------------------

_SIDES = ("both", "above", "below")


def exceedance_time(dt, x, limit, side: str = "both") -> float:
    """Time (s) a record spends beyond a limit: ``dt`` × the number of samples after the first at which any
    channel of ``x`` (n,) or (n, channels) is beyond ``limit`` (> 0; a scalar or one per channel) — |x| > limit
    (``side="both"``), x > limit ("above") or x < −limit ("below"). The samples after the first, each standing for
    the step that ends at it, as the environments count their physics rows (:mod:`mrd_env.envs.costs`: the
    episode total of a cost term is this time)."""
    a = as_signal("x", x, columns=True)
    step = sample_interval(dt, a.shape[0])
    if side not in _SIDES:
        raise ValueError(f"side must be one of {list(_SIDES)}, got {side!r}")
    lim = check_array("limit", limit, lo=0.0)
    if np.any(lim <= 0) or lim.ndim > 1 or (lim.ndim == 1 and lim.size != a.shape[1]):
        raise ValueError(f"limit must be > 0, a scalar or one per channel ({a.shape[1]}), got {limit!r}")
    v = np.abs(a) if side == "both" else (a if side == "above" else -a)
    return float(np.count_nonzero(np.any(v[1:] > lim, axis=1)) * step)


def exceedance_share(dt, x, limit, side: str = "both") -> float:
    """The share (−) of a record's duration ((n − 1)·dt) spent beyond the limit: :func:`exceedance_time` over the
    duration (0 for a record of one sample)."""
    a = as_signal("x", x, columns=True)
    n = a.shape[0]
    time = exceedance_time(dt, a, limit, side)
    return time / ((n - 1) * sample_interval(dt, n)) if n > 1 else 0.0
