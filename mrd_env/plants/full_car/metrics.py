"""The full car's ride metrics: ISO 2631-1 comfort in heave, pitch and roll, suspension travel and road holding per
corner (SI).

Heave is weighted by Wk (:func:`mrd_env.metrics.weighting_sos`). Pitch and roll are weighted by the rotational
weighting We of ISO 2631-1 (Annex A: the band limits f1 = 0.4 Hz, f2 = 100 Hz, the acceleration–velocity
transition f3 = f4 = 1 Hz with Q4 = 0.63, no upward step, unit gain), which :mod:`mrd_env.metrics` does not have
(it has Wk and Wd): it is built here the same way (each factor discretised by the bilinear transform with its
corners pre-warped). Its parameters are those of ISO 8041's table of the weightings as reproduced in two
instrument manuals (Larson Davis HVM200, Table 3.1; Rion SLA-PA201, Table 1), not read in the standard itself.

The comfort of the three together is ISO 2631-1's point vibration total value a_v = √(a_wz² + (k_y a_wθ)² +
(k_x a_wφ)²) with the multiplying factors of rotational vibration on a seat, k_x = 0.63 m/rad (roll) and
k_y = 0.40 m/rad (pitch) (§8.2.2 of ISO 2631-1, from memory: **unverified**), at the body's centre of mass (a
stand-in for the seat, which the 7-DOF model does not have).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ...metrics import as_series, as_signal, mtvv, rms, sample_interval, vdv, weighted_acceleration
from ...validation import check_scalar

#: The rotational weighting We (ISO 2631-1 Annex A; see the module docstring).
WE = {"f1": 0.4, "f2": 100.0, "f3": 1.0, "f4": 1.0, "q4": 0.63}
#: Multiplying factors of rotational vibration for the point vibration total value (m/rad; unverified).
K_ROLL = 0.63
K_PITCH = 0.40


def _sections(omega) -> list[tuple[list, list]]:
    """Hh, Hl, Ht of We as (num, den) polynomials in s; ``omega`` maps Hz to the angular frequency used."""
    q = 1.0 / math.sqrt(2.0)
    w1, w2, w3, w4 = (omega(WE[k]) for k in ("f1", "f2", "f3", "f4"))
    return [([1.0, 0.0, 0.0], [1.0, w1 / q, w1 ** 2]),
            ([w2 ** 2], [1.0, w2 / q, w2 ** 2]),
            ([1.0 / w3, 1.0], [1.0 / w4 ** 2, 1.0 / (WE["q4"] * w4), 1.0])]


def we_magnitude(f) -> np.ndarray:
    """|We(j2πf)| of the analog weighting at frequencies ``f`` (Hz)."""
    s = 2j * np.pi * np.asarray(f, dtype=float)
    h = np.ones_like(s)
    for b, a in _sections(lambda f: 2.0 * math.pi * f):
        h = h * np.polyval(b, s) / np.polyval(a, s)
    return np.abs(h)


@lru_cache(maxsize=16)
def _we_sos(dt: float) -> np.ndarray:
    from scipy import signal  # imported where used: see mrd_env.metrics._sos

    fs = 1.0 / dt
    rows = []
    for b, a in _sections(lambda f: 2.0 * fs * math.tan(math.pi * f / fs)):
        bz, az = signal.bilinear(b, a, fs)
        rows.append(np.concatenate([np.pad(bz, (3 - bz.size, 0)), az]) / az[0])
    sos = np.array(rows)
    sos.flags.writeable = False
    return sos


def we_sos(dt: float) -> np.ndarray:
    """The digital We at sample interval ``dt`` (s) as second-order sections (``scipy.signal.sosfilt`` layout);
    the sample rate must exceed 200 Hz (twice f2)."""
    dt = check_scalar("dt", dt, 0.0, 1.0 / (2.0 * WE["f2"]), lo_open=True, hi_open=True, unit="s")
    return _we_sos(dt).copy()


def vibration_total(a_wz, a_wpitch, a_wroll):
    """ISO 2631-1's point vibration total value √(a_wz² + (k_y a_wθ)² + (k_x a_wφ)²) (m/s²) of weighted r.m.s.
    values (m/s², rad/s², rad/s²)."""
    return np.sqrt(np.square(a_wz) + (K_PITCH * np.asarray(a_wpitch)) ** 2 + (K_ROLL * np.asarray(a_wroll)) ** 2)


def full_car_metrics(dt, heave_acc, pitch_acc, roll_acc, travel, dynamic_tyre_load=None, *,
                     static_tyre_loads=None, tau: float = 1.0) -> dict[str, float]:
    """Ride comfort, suspension working space and road holding of one full-car record (what the environment's
    episode metrics are, computed offline).

    ``heave_acc`` (m/s²), ``pitch_acc``, ``roll_acc`` (rad/s²) 1-D; ``travel`` (m, from static equilibrium) and
    ``dynamic_tyre_load`` (N, positive = more load than static) (n, 4) in the corners' order fl, fr, rl, rr;
    ``static_tyre_loads`` (N, 4). Returns: ``acc_weighted_rms`` (Wk, m/s²), ``pitch_acc_weighted_rms``,
    ``roll_acc_weighted_rms`` (We, rad/s²), ``comfort_rms`` (:func:`vibration_total`, m/s²), ``acc_rms``,
    ``pitch_acc_rms``, ``roll_acc_rms``, ``acc_vdv`` (Wk, m/s^1.75), ``acc_mtvv`` (Wk over ``tau``),
    ``travel_rms``, ``travel_peak`` (the largest corner's, m), ``tyre_load_rms`` (the largest corner's, N) with
    ``tyre_load_rms_<corner>``, and ``tyre_load_ratio`` (the largest of each corner's r.m.s. over its static load)
    with ``tyre_load_ratio_<corner>``.
    """
    a = as_series("heave_acc", heave_acc)
    n = a.shape[0]
    p, r = as_series("pitch_acc", pitch_acc, n), as_series("roll_acc", roll_acc, n)
    x = as_signal("travel", travel, n=n, columns=True)
    step = sample_interval(dt, n)
    a_w = weighted_acceleration(a, step, "Wk")
    sos = we_sos(step)
    from scipy import signal

    p_w, r_w = signal.sosfilt(sos, p), signal.sosfilt(sos, r)
    out = {"acc_weighted_rms": float(rms(a_w)), "pitch_acc_weighted_rms": float(rms(p_w)),
           "roll_acc_weighted_rms": float(rms(r_w)), "acc_rms": float(rms(a)), "pitch_acc_rms": float(rms(p)),
           "roll_acc_rms": float(rms(r)), "acc_vdv": float(vdv(a_w, step)), "acc_mtvv": float(mtvv(a_w, step, tau)),
           "travel_rms": float(np.max(rms(x))), "travel_peak": float(np.max(np.abs(x)))}
    out["comfort_rms"] = float(vibration_total(out["acc_weighted_rms"], out["pitch_acc_weighted_rms"],
                                               out["roll_acc_weighted_rms"]))
    if dynamic_tyre_load is not None:
        load = as_signal("dynamic_tyre_load", dynamic_tyre_load, n=n, columns=True)
        out["tyre_load_rms"] = float(np.max(rms(load)))
        out.update({f"tyre_load_rms_{c}": float(v) for c, v in zip(("fl", "fr", "rl", "rr"), rms(load))})
        if static_tyre_loads is not None:
            ratio = rms(load) / np.asarray(static_tyre_loads, dtype=float)
            out["tyre_load_ratio"] = float(np.max(ratio))
            out.update({f"tyre_load_ratio_{c}": float(v) for c, v in zip(("fl", "fr", "rl", "rr"), ratio)})
    return out
