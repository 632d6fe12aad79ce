"""A constant sample offset between the force channel and the motion channels of a record.

Data acquisition systems may sample the load cell and the stroke sensor with a small skew, or filter one of them:
the force then lags (or leads) the motion by a constant number of samples, which a model driven by the motion
cannot reproduce. The offset ``s`` (samples, positive when the force lags) is estimated two ways:

* :func:`estimate_offset` — model-free: the shift of the motion channels for which a static regression of the
  force on features of (x, ẋ, command) — a Bingham-like basis with several tanh velocity scales — leaves the
  smallest residual (the best cross-correlation in the least-squares sense), on the samples where the command
  has been steady for :data:`SETTLED` s (elsewhere the force follows the command's lag, which a shift of the
  motion would otherwise be chosen to mimic);
* :func:`best_offset` — from a model's force: the shift of the measured force that a simulated force matches
  best; no simulation is repeated, since shifting the measured force is only indexing.

:func:`~mrd_env.identification.fit.fit_model` (``align=True``) starts from the first, fits, checks the second with
the fitted model, and fits again if they differ; the offset used is reported in the result.
"""
from __future__ import annotations

import numpy as np

from .prepare import PreparedRecord, shift_channel

__all__ = ["estimate_offset", "best_offset", "MAX_OFFSET"]

MAX_OFFSET = 5  # samples searched on each side
SETTLED = 0.03  # s since the last command switch (several lag time constants of a driver/coil)


def settled(command: np.ndarray, dt: float) -> np.ndarray:
    """Mask of the samples at least :data:`SETTLED` s after the last switch (a change > 2 % of the range)."""
    span = float(command.max() - command.min())
    switch = np.r_[True, np.abs(np.diff(command)) > 0.02 * span] if span > 0 else np.r_[True, np.zeros(
        command.size - 1, dtype=bool)]
    last = np.maximum.accumulate(np.where(switch, np.arange(command.size), 0))
    return (np.arange(command.size) - last) * dt >= SETTLED


def _features(x: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    vs = max(float(np.std(v)), 1e-12)
    cols = [np.ones_like(x), x, v, u, u * v, v * np.abs(v) / vs]
    for k in (0.03, 0.1, 0.3):
        th = np.tanh(v / (k * vs))
        cols += [th, u * th]
    return np.stack(cols, axis=1)


def estimate_offset(prep: PreparedRecord, max_shift: int = MAX_OFFSET) -> int:
    """The offset (samples) that best explains the force by a static function of the motion and command at
    the shifted time; searched over ±``max_shift``."""
    max_shift = int(max_shift)
    if max_shift < 0:
        raise ValueError(f"max_shift = {max_shift} is invalid: must be >= 0")
    n = prep.n
    k = np.arange(max_shift, n - max_shift)
    steady = prep.mask & settled(prep.command, prep.dt)
    k = k[steady[k]] if np.count_nonzero(steady[k]) > 100 else k[prep.mask[k]]
    b = prep.force[k]
    best, best_res = 0, np.inf
    for s in range(-max_shift, max_shift + 1):
        A = _features(prep.x[k - s], prep.v[k - s], prep.command[k])
        coef, *_ = np.linalg.lstsq(A, b, rcond=None)
        res = float(np.sum((b - A @ coef) ** 2))
        if res < best_res:
            best, best_res = s, res
    return best


def best_offset(F_model: np.ndarray, prep: PreparedRecord, center: int = 0, max_shift: int = MAX_OFFSET) -> int:
    """The total offset in center ± ``max_shift`` for which the simulated force ``F_model`` (driven by ``prep``,
    whose force is already shifted by ``prep.offset``) matches the measured force best (RMS over the mask)."""
    raw, _ = shift_channel(prep.force, -prep.offset)  # the force as measured
    best, best_err = center, np.inf
    for s in range(center - max_shift, center + max_shift + 1):
        f, ok = shift_channel(raw, s)
        m = prep.mask & ok
        err = float(np.mean((F_model[m] - f[m]) ** 2))
        if err < best_err:
            best, best_err = s, err
    return best
