"""Road inputs for vehicle models: ISO 8608 random roads, a (1 - cos) bump, sine sweeps and measured profiles.

Every generator returns a :class:`~mrd_env.disturbances.record.Record` with channels ``("z_r", "zdot_r")``:
the road elevation under the tyre in m and its time derivative in m/s, sampled at ``t_k = k * dt``.
"""
from __future__ import annotations

import math
import os
from typing import Mapping

import numpy as np
import scipy.fft

from ..resources import Budget
from ..validation import check_n_samples, check_scalar
from .record import (Record, as_generator, check_column, check_duration_dt, n_samples_for, read_table,
                     split_unit, unit_factor, LENGTH_UNITS, TIME_UNITS)

ROAD_CHANNELS = ("z_r", "zdot_r")
ROAD_UNITS = ("m", "m/s")

#: ISO 8608 reference spatial frequency n0, cycle/m.
ISO8608_N0 = 0.1

#: ISO 8608:2016 roughness classes: geometric mean of the displacement PSD G_d(n0) at n0 = 0.1 cycle/m, in m^3.
#: The class limits are half and double these values (A has no lower limit, H no upper limit). Using the
#: upper limit as "the class value" (a common slip) makes a road 2x too rough in PSD.
ISO8608_CLASSES: dict[str, float] = {
    "A": 16e-6, "B": 64e-6, "C": 256e-6, "D": 1024e-6,
    "E": 4096e-6, "F": 16384e-6, "G": 65536e-6, "H": 262144e-6,
}

#: Default spatial-frequency band, cycle/m: the band ISO 8608 uses to classify profiles (wavelengths from
#: about 91 m down to 0.35 m); shorter waves are filtered by the tyre contact patch, longer ones are slopes.
ISO8608_N_MIN = 0.011
ISO8608_N_MAX = 2.83

# Above this many sinusoids the direct sum is slow (cost n_samples * n_waves); method="fft" has no such limit.
_MAX_AUTO_WAVES = 10_000
# More sinusoids than this take hours (and an int beyond float64 cannot even set the band width).
_MAX_WAVES = 1_000_000


def _check_class(road_class) -> str:
    key = road_class.strip().upper() if isinstance(road_class, str) else None
    if key not in ISO8608_CLASSES:
        raise ValueError(f"road_class must be one of A..H, got {road_class!r}")
    return key


def iso8608_gd(road_class: str) -> float:
    """G_d(n0) in m^3 for an ISO 8608 class: the class's geometric mean (A 16e-6 ... H 262144e-6)."""
    return ISO8608_CLASSES[_check_class(road_class)]


def iso8608_class_limits(road_class: str) -> tuple[float, float]:
    """(lower, upper) limits of G_d(n0) in m^3 for an ISO 8608 class: half and double its geometric mean.

    ISO 8608 leaves class A without a lower and class H without an upper limit: they are returned as 0 and inf.
    """
    key = _check_class(road_class)
    gd = ISO8608_CLASSES[key]
    return (0.0 if key == "A" else gd / 2.0, math.inf if key == "H" else gd * 2.0)


def iso8608_classify(gd_n0: float) -> str:
    """The ISO 8608 class whose limits contain a measured G_d(n0) in m^3 (a boundary value goes to the
    smoother class)."""
    gd_n0 = check_scalar("gd_n0", gd_n0, 0.0, lo_open=True, unit="m^3")
    for key in ISO8608_CLASSES:
        if gd_n0 <= iso8608_class_limits(key)[1]:
            return key
    raise AssertionError("unreachable: class H has no upper limit")


def iso8608_psd(n, road_class: str, waviness: float = 2.0) -> np.ndarray:
    """One-sided displacement PSD G_d(n) = G_d(n0) (n / n0)^(-w) in m^3 (m^2 per cycle/m), ISO 8608:2016.

    ``n`` is the spatial frequency in cycle/m (> 0); ``waviness`` w = 2 is the ISO classification value.
    """
    gd = iso8608_gd(road_class)
    w = check_scalar("waviness", waviness, 0.0, lo_open=True)
    n = np.asarray(n, dtype=np.float64)
    if np.any(~np.isfinite(n)) or np.any(n <= 0):
        raise ValueError("n must be finite and > 0 cycle/m")
    return gd * (n / ISO8608_N0) ** (-w)


def iso8608_road(road_class: str, speed: float, duration: float, dt: float = 1e-3, rng=None, *,
                 n_min: float = ISO8608_N_MIN, n_max: float = ISO8608_N_MAX, method: str = "sinusoids",
                 n_waves: int | None = None, waviness: float = 2.0) -> Record:
    """A random road of ISO 8608 class ``road_class`` driven at constant ``speed`` (m/s).

    Harmonic superposition (Shinozuka & Jan 1972; Cebon & Newland 1983) of the ISO 8608:2016 PSD::

        z_r(x) = sum_i sqrt(2 G_d(n_i) dn) cos(2 pi n_i x + phi_i),   x = speed * t,  phi_i ~ U[0, 2 pi)

    with G_d(n) from :func:`iso8608_psd` on the band [n_min, n_max] cycle/m (default 0.011 - 2.83, the ISO
    classification band) and zdot_r its exact time derivative (not a finite difference).

    ``method="sinusoids"`` sums ``n_waves`` cosines at the mid-points of equal bands dn (default: enough that
    dn <= 1 / (speed * duration), so the road does not repeat within the record; capped at 10 000, so a record
    longer than 10 000 / ((n_max − n_min)·speed) — 177 s at 20 m/s on the default band — repeats with that
    period as a phase-rotated copy of itself (the same spectrum): use ``method="fft"`` or ``n_waves`` for longer
    drives). Its cost is
    n_samples * n_waves. ``method="fft"`` evaluates the same sum with the frequencies on the FFT grid of the
    record (dn = 1 / (speed * M * dt), M >= n_samples), in O(n log n): use it for long records.

    ``rng`` is a ``numpy.random.Generator`` or an int seed (same seed -> bit-identical road).
    """
    key = _check_class(road_class)
    speed = check_scalar("speed", speed, 0.0, lo_open=True, unit="m/s")
    duration, dt = check_duration_dt(duration, dt)
    n_min = check_scalar("n_min", n_min, 0.0, lo_open=True, unit="cycle/m")
    n_max = check_scalar("n_max", n_max, n_min, lo_open=True, unit="cycle/m")
    waviness = check_scalar("waviness", waviness, 0.0, lo_open=True)
    if method not in ("sinusoids", "fft"):
        raise ValueError(f"method must be 'sinusoids' or 'fft', got {method!r}")
    f_nyquist = 0.5 / dt
    if n_max * speed >= f_nyquist:
        raise ValueError(f"dt must be < 1 / (2 n_max speed) = {0.5 / (n_max * speed):g} s so that the shortest "
                         f"road wave (n_max = {n_max:g} cycle/m at {speed:g} m/s) is resolved, got {dt:g} s")
    gen = as_generator(rng)
    n = n_samples_for(duration, dt)
    distance = speed * duration

    if method == "sinusoids":
        if n_waves is None:
            n_waves = int(min(max(math.ceil((n_max - n_min) * distance), 100), _MAX_AUTO_WAVES))
        elif (isinstance(n_waves, bool) or not isinstance(n_waves, (int, np.integer))
              or not 1 <= n_waves <= _MAX_WAVES):
            raise ValueError(f"n_waves must be an int in [1, {_MAX_WAVES:.0e}] or None (method='fft' for finer "
                             f"spectra), got {n_waves!r}")
        dn = (n_max - n_min) / n_waves
        n_i = n_min + (np.arange(n_waves) + 0.5) * dn
        amp = np.sqrt(2.0 * iso8608_psd(n_i, key, waviness) * dn)
        phase = gen.uniform(0.0, 2.0 * math.pi, n_waves)
        z, zdot = _sum_cosines(amp, 2.0 * math.pi * n_i * speed, phase, dt, n)
    else:
        if n_waves is not None:
            raise ValueError("n_waves applies to method='sinusoids' only; method='fft' uses the FFT grid")
        m = scipy.fft.next_fast_len(n, real=True)
        df = 1.0 / (m * dt)                       # temporal frequency step, Hz
        k = np.arange(1, m // 2)                  # no DC, no Nyquist bin: both would be real-only
        n_k = k * df / speed
        keep = (n_k >= n_min) & (n_k <= n_max)
        if not keep.any():
            raise ValueError(f"duration = {duration:g} s is too short to place any wave in [n_min, n_max] = "
                             f"[{n_min:g}, {n_max:g}] cycle/m at {speed:g} m/s")
        k, n_k = k[keep], n_k[keep]
        amp = np.sqrt(2.0 * iso8608_psd(n_k, key, waviness) * (df / speed))
        phase = gen.uniform(0.0, 2.0 * math.pi, k.size)
        spec = np.zeros(m // 2 + 1, dtype=np.complex128)
        spec[k] = amp * np.exp(1j * phase)
        # irfft(X) = (1/M) sum over both half-spectra, so M/2 * irfft gives sum_k A_k cos(2 pi k j / M + phi_k).
        z = scipy.fft.irfft(spec, m)[:n] * (m / 2.0)
        spec[k] *= 2j * math.pi * k * df
        zdot = scipy.fft.irfft(spec, m)[:n] * (m / 2.0)
    return _road_record(z, zdot, dt, f"ISO 8608 class {key} road at {speed:g} m/s",
                        "speed, n_min or waviness (the PSD at n_min)")


def _sum_cosines(amp: np.ndarray, omega: np.ndarray, phase: np.ndarray, dt: float, n: int):
    """sum_i amp_i cos(omega_i t_k + phase_i) at t_k = k dt, and its exact time derivative.

    Blocks of B samples share one table exp(i omega_i j dt), j < B; each block is then one complex
    matrix-vector product with amp_i exp(i (omega_i t_s + phase_i)) at the block start t_s. Every term is a
    product of two exactly evaluated exponentials (no accumulating recurrence), and the trigonometric work
    drops from n * n_waves to about B * n_waves.
    """
    block = int(min(n, max(1, (1 << 20) // omega.size)))
    table = np.exp(1j * np.multiply.outer(np.arange(block) * dt, omega))
    z = np.empty(n)
    zdot = np.empty(n)
    coef = np.empty((omega.size, 2), dtype=np.complex128)
    for s in range(0, n, block):
        m = min(block, n - s)
        c = amp * np.exp(1j * (omega * (s * dt) + phase))
        coef[:, 0] = c
        coef[:, 1] = 1j * omega * c           # d/dt of exp(i omega t)
        out = table[:m] @ coef
        z[s:s + m] = out[:, 0].real
        zdot[s:s + m] = out[:, 1].real
    return z, zdot


def _road_record(z: np.ndarray, zdot: np.ndarray, dt: float, name: str, culprits: str = "") -> Record:
    data = np.column_stack([z, zdot])
    if culprits and not np.all(np.isfinite(data)):  # huge but valid arguments: say which, not "data"
        raise ValueError(f"the road overflows float64 (a non-finite z_r or zdot_r): {culprits} too large")
    return Record(dt, data, ROAD_CHANNELS, ROAD_UNITS, name)


def bump(height: float, length: float, speed: float, t_start: float = 0.5, duration: float | None = None,
         dt: float = 1e-3) -> Record:
    """A single (1 - cos) bump crossed at constant speed; a negative ``height`` (m) gives a pothole.

    z_r = height/2 (1 - cos(2 pi speed (t - t_start) / length)) for t_start <= t <= t_start + length/speed,
    0 elsewhere; zdot_r is its exact derivative. ``duration`` defaults to the end of the bump plus 2 s so the
    vehicle's free response is in the record.
    """
    height = check_scalar("height", height, unit="m")
    length = check_scalar("length", length, 0.0, lo_open=True, unit="m")
    speed = check_scalar("speed", speed, 0.0, lo_open=True, unit="m/s")
    t_start = check_scalar("t_start", t_start, 0.0, unit="s")
    t_end = t_start + length / speed
    if duration is None:
        duration = t_end + 2.0
    duration, dt = check_duration_dt(duration, dt)
    if t_end > duration:
        raise ValueError(f"duration must be >= t_start + length/speed = {t_end:g} s so the whole bump is in the "
                         f"record, got {duration:g} s")
    t = np.arange(n_samples_for(duration, dt)) * dt
    on = (t >= t_start) & (t <= t_end)
    w = 2.0 * math.pi * speed / length
    z = np.zeros_like(t)
    zdot = np.zeros_like(t)
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported by _road_record, by name
        arg = w * (t[on] - t_start)
        z[on] = 0.5 * height * (1.0 - np.cos(arg))
        zdot[on] = 0.5 * height * w * np.sin(arg)
    kind = "bump" if height >= 0 else "pothole"
    return _road_record(z, zdot, dt, f"{kind} {abs(height):g} m x {length:g} m at {speed:g} m/s",
                        "height or speed / length")


def sine_sweep(amplitude: float, f_start: float, f_end: float, duration: float, dt: float = 1e-3,
               kind: str = "log") -> Record:
    """A constant-amplitude displacement sweep z_r = amplitude sin(phi(t)), for shaker-rig style tests.

    Instantaneous frequency f(t) = f_start + (f_end - f_start) t / T (``kind="linear"``) or
    f_start (f_end / f_start)^(t / T) (``kind="log"``, equal time per octave); phi = 2 pi int_0^t f and
    zdot_r = amplitude 2 pi f(t) cos(phi) exactly. A downward sweep (f_end < f_start) is allowed.
    """
    amplitude = check_scalar("amplitude", amplitude, 0.0, lo_open=True, unit="m")
    duration, dt = check_duration_dt(duration, dt)
    f_nyq = 0.5 / dt
    f_start = check_scalar("f_start", f_start, 0.0, f_nyq, lo_open=True, hi_open=True, unit="Hz")
    f_end = check_scalar("f_end", f_end, 0.0, f_nyq, lo_open=True, hi_open=True, unit="Hz")
    if kind not in ("log", "linear"):
        raise ValueError(f"kind must be 'log' or 'linear', got {kind!r}")
    t = np.arange(n_samples_for(duration, dt)) * dt
    ratio = f_end / f_start
    if kind == "linear":
        f = f_start + (f_end - f_start) * t / duration
        phi = 2.0 * math.pi * (f_start * t + 0.5 * (f_end - f_start) * t * t / duration)
    elif ratio == 1.0:
        f = np.full_like(t, f_start)
        phi = 2.0 * math.pi * f_start * t
    else:
        log_r = math.log(ratio)
        f = f_start * np.exp(log_r * t / duration)
        phi = 2.0 * math.pi * f_start * duration / log_r * np.expm1(log_r * t / duration)
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported by _road_record, by name
        z = amplitude * np.sin(phi)
        zdot = amplitude * 2.0 * math.pi * f * np.cos(phi)
    return _road_record(z, zdot, dt, f"{kind} sweep {f_start:g}-{f_end:g} Hz, {amplitude:g} m",
                        "amplitude")


def road_from_csv(path, *, height_column: str, distance_column: str | None = None, time_column: str | None = None,
                  speed: float | None = None, units: Mapping[str, str] | None = None, dt: float = 1e-3,
                  duration: float | None = None, budget=None) -> Record:
    """A measured road profile from a text table with a header row (comma, semicolon or whitespace separated).

    Either height vs distance (``distance_column`` and a vehicle ``speed`` in m/s: t = (x - x_0) / speed) or
    height vs time (``time_column``, t = t - t_0). Units are required for each column used, from ``units``
    (e.g. ``{"x": "m", "z": "mm"}``; lengths m/cm/mm/km, times s/ms) or from the header (``"z [mm]"``,
    ``"z (mm)"``); a column may be named with or without its bracketed unit.

    The profile is linearly interpolated onto t_k = k dt and zdot_r is estimated by ``np.gradient`` (second-order
    central differences inside, second-order one-sided at the ends). Measured points farther apart than
    speed*dt are joined by straight lines, so zdot_r is then the piecewise slope times speed.

    ``duration`` (s): keep only what an episode of that length reads (the first samples up to ``duration`` and
    two more, equal to those of the whole profile). The samples are checked against the memory limit before they
    are made (:mod:`mrd_env.resources`; ``budget``: an environment's :class:`~mrd_env.resources.Budget`).
    """
    if (distance_column is None) == (time_column is None):
        raise ValueError("give exactly one of distance_column (height vs distance, with speed) or time_column "
                         "(height vs time)")
    if distance_column is not None:
        if speed is None:
            raise ValueError("speed must be given (> 0 m/s) for a height-vs-distance profile")
        speed = check_scalar("speed", speed, 0.0, lo_open=True, unit="m/s")
    elif speed is not None:
        raise ValueError("speed applies only to a height-vs-distance profile (distance_column); a "
                         "height-vs-time profile already fixes the timing")
    dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    if units is not None and not isinstance(units, Mapping):
        raise ValueError(f"units must be a mapping column -> unit, e.g. {{'z': 'mm'}}, got {units!r}")

    header, table, lines = read_table(path, "road_from_csv")
    if header is None:
        raise ValueError(f"road_from_csv: {os.fspath(path)!r} has no header row: the columns must be named")
    x_col = distance_column if distance_column is not None else time_column
    x_par = "distance_column" if distance_column is not None else "time_column"
    x_table = LENGTH_UNITS if distance_column is not None else TIME_UNITS
    jx, x_unit = _find_column(header, x_col, x_par, units, path)
    jz, z_unit = _find_column(header, height_column, "height_column", units, path)
    x = table[:, jx] * unit_factor(f"unit of column {x_col!r}", x_unit, x_table)
    z = table[:, jz] * unit_factor(f"unit of column {height_column!r}", z_unit, LENGTH_UNITS)
    check_column(x, lines, x_col, path, increasing=True)
    check_column(z, lines, height_column, path, increasing=False)

    t = (x - x[0]) / speed if distance_column is not None else x - x[0]
    name = os.path.basename(os.fspath(path))
    seconds = t[-1]
    if duration is not None:
        seconds = min(seconds, check_scalar("duration", duration, 0.0, lo_open=True, unit="s"))
    what = (f"the road profile {name!r} ({t[-1]:g} s"
            + (f" at speed={speed:g} m/s" if distance_column is not None else "") + ")")
    check_n_samples(seconds / dt, f"{what} at dt = {dt:g} s")
    (budget or Budget()).check_record(seconds / dt + 1, dt, 2, what if seconds == t[-1] else
                                      f"episode_seconds={seconds:g}", what="the road")
    n = n_samples_for(t[-1], dt)
    if n < 2:
        raise ValueError(f"dt = {dt:g} s must be <= the profile's duration {t[-1]:g} s")
    if duration is not None:
        n = min(n, n_samples_for(seconds, dt) + 2)  # np.gradient's one-sided end stays outside the episode
    t_new = np.arange(n) * dt
    z_new = np.interp(t_new, t, z)
    zdot = np.gradient(z_new, dt, edge_order=2)
    return _road_record(z_new, zdot, dt, f"road profile {name}")


def _find_column(header: list[str], column: str, param: str, units, path) -> tuple[int, str]:
    """Index and unit of ``column`` in ``header``; raise ValueError naming the available columns or the
    missing unit."""
    if not isinstance(column, str) or not column.strip():
        raise ValueError(f"{param} must be a column name, got {column!r}")
    bases = [split_unit(h) for h in header]
    base, unit_in_name = split_unit(column)
    for j, (h, (h_base, h_unit)) in enumerate(zip(header, bases)):
        if column == h or base == h_base:
            unit = None
            if units is not None:
                unit = units.get(column, units.get(h, units.get(h_base)))
            unit = unit or unit_in_name or h_unit
            if unit is None:
                raise ValueError(f"units missing for column {h!r} of {os.fspath(path)!r}: pass units="
                                 f"{{{h_base!r}: 'm'}} or name the column '{h_base} [m]'")
            return j, unit
    raise ValueError(f"{param} {column!r} is not a column of {os.fspath(path)!r} (its header row names "
                     f"{len(header)} columns)")
