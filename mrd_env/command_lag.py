"""The command dynamics shared by every damper model: a pure delay and an asymmetric first-order lag.

From the commanded current/voltage v to the effective one u that the force law sees::

    u̇ = −η (u − v(t − τ)),     η = η_rise if v(t − τ) > u else η_fall

η_rise (``CommandSpec.eta``) and η_fall (``CommandSpec.eta_fall``, η_rise when not given) are the rates of the
driver/coil lag on a rising and on a falling command (u completes 63.2 % of a step after 1/η seconds); τ
(``CommandSpec.delay``, s) is a pure transport delay. Commands are held over each step of dt (zero-order
hold); with τ = m·dt + s (m whole steps, 0 <= s < dt) the delayed command inside step k is v_{k−m−1} up to
t_k + s and v_{k−m} after it. Inside each
piece the command is constant and u moves monotonically towards it, so η does not switch inside a piece and
the lag is integrated exactly (two exponentials per step). The stepping kernel (``_kernel_template.py``), the
rig (:func:`effective_command`) and identification all call :func:`lag_value` below.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

#: Columns of the per-damper lag vector (η_rise, η_fall, τ) passed to the kernels.
LAG_RISE, LAG_FALL, LAG_DELAY = 0, 1, 2


@nb.njit(cache=True)
def lag_value(u0, va, vb, ts, eta_rise, eta_fall, tau):
    """u at time ``tau`` (s) after a step's start, from u0 there, with the command va until ``ts`` and vb after."""
    if tau <= ts:
        e = eta_rise if va > u0 else eta_fall
        return va + (u0 - va) * math.exp(-e * tau)
    us = u0
    if ts > 0.0:
        e = eta_rise if va > u0 else eta_fall
        us = va + (u0 - va) * math.exp(-e * ts)
    e = eta_rise if vb > us else eta_fall
    return vb + (us - vb) * math.exp(-e * (tau - ts))


@nb.njit(cache=True)
def delay_split(delay, dt):
    """(m, s): a delay τ of m whole steps of dt plus the time s = τ − m·dt (0 <= s < dt) into the next one."""
    m = int(math.floor(delay / dt * (1.0 + 1e-12)))
    s = delay - m * dt
    if s < 0.0:
        s = 0.0
    return m, s


def queue_length(delays, dt: float) -> int:
    """Commands a kernel keeps per damper for delays up to ``max(delays)`` (s): the current one, m older ones
    and the one before them."""
    d = float(np.max(delays)) if np.size(delays) else 0.0
    return int(delay_split(d, dt)[0]) + 2


@nb.njit(cache=True)
def _lag_sequence(v, u0, dt, eta_rise, eta_fall, m, s):
    n = v.shape[0]
    u = np.empty(n)
    u[0] = u0
    for j in range(n - 1):
        # step j: the command of step j − m − 1 until t_j + s, then that of step j − m (u0 before the record)
        va = v[j - m - 1] if j - m - 1 >= 0 else u0
        vb = v[j - m] if j - m >= 0 else u0
        u[j + 1] = lag_value(u[j], va, vb, s, eta_rise, eta_fall, dt)
    return u


def effective_command(command, v: np.ndarray, dt: float, u0: float | None = None) -> np.ndarray:
    """The effective command u at the samples t_k = k·dt for commands ``v`` held over each step, from
    u(0) = ``u0`` (default: v[0], a settled driver; the command before t = 0 is u0). ``command`` is the
    :class:`~mrd_env.dampers.CommandSpec` whose lag and delay apply."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    u0 = float(v[0]) if u0 is None else float(u0)
    m, s = delay_split(command.delay, dt)
    return _lag_sequence(v, u0, float(dt), command.eta, command.eta_down, m, s)


def check_lag(lag: np.ndarray) -> None:
    """``ValueError`` unless every (η_rise, η_fall, τ) row has finite rates > 0 and a delay in [0, 1] s."""
    lag = np.asarray(lag, dtype=np.float64)
    rates, delay = lag[..., :LAG_DELAY], lag[..., LAG_DELAY]
    if not (np.all(np.isfinite(rates)) and np.all(rates > 0)):
        raise ValueError(f"command lag rates eta/eta_fall must be finite and > 0 1/s, got {rates.min():g}..."
                         f"{rates.max():g}")
    if not (np.all(np.isfinite(delay)) and np.all((delay >= 0) & (delay <= 1.0))):
        raise ValueError(f"command delay must be in [0, 1] s, got {delay.min():g}...{delay.max():g}")
