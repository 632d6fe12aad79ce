"""A constant sample offset between the force channel and the motion channels of a record.

Data acquisition systems may sample the load cell and the stroke sensor with a small skew, or filter one of them:
the force then lags (or leads) the motion by a constant number of samples, which a model driven by the motion
cannot reproduce. The offset ``s`` (samples, positive when the force lags) is *fitted*: :func:`best_offset` is the
shift of the measured force that a simulated force matches best (no simulation is repeated: shifting the measured
force is only indexing). :func:`~mrd_env.identification.fit.fit_model` with ``align=True`` takes the offset the
initial guess prefers, fits, asks the fitted model again, and fits again — from the initial guess and from the
fit so far, keeping the better — until the offset stays; the offset used is reported in the result.

A model-free estimate (a static regression of the force on the shifted motion, or a cross-correlation) is not
offered: a hysteretic damper's force lags its velocity by itself, which biases such estimates towards a lagging
force (on the NEES record a static regression says +2 samples where the fitted Spencer–Dyke model says −1), and a
black-box model over a motion history always fits better with more recent motion, so it cannot choose the offset
either: give the neural model the offset a parametric fit found (``data={"offset": s}``).
"""
from __future__ import annotations

import numpy as np

from .prepare import PreparedRecord, shift_channel

__all__ = ["best_offset", "MAX_OFFSET"]

MAX_OFFSET = 5  # samples searched on each side


def best_offset(F_model: np.ndarray, prep: PreparedRecord, max_shift: int = MAX_OFFSET) -> int:
    """The offset in ±``max_shift`` samples for which the simulated force ``F_model`` (driven by ``prep``, whose
    force is already shifted by ``prep.offset``) matches the measured force best (mean square over the mask)."""
    raw, _ = shift_channel(prep.series.force, -prep.offset)  # the force as measured
    best, best_err = 0, np.inf
    for s in range(-int(max_shift), int(max_shift) + 1):
        f, ok = shift_channel(raw, s)
        m = prep.mask & ok
        err = float(np.mean((F_model[m] - f[m]) ** 2))
        if err < best_err:
            best, best_err = s, err
    return best
