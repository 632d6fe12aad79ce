"""The termination part: limits on signals (a damper's stroke) that end an episode, and their penalty.

An episode is ``terminated`` when |signal| exceeds its limit at any physics step (or the simulation diverges);
the step's reward then loses ``penalty + penalty_rate × T``, T the episode's planned length in seconds. With
``penalty_rate`` above the cost rate of any controller (the environments' rewards are costs per second
relative to a reference), an episode ended by a limit scores worse than any controller that finishes, and
ending early never pays.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..validation import check_scalar
from .signals import SignalMap


class Limits:
    def __init__(self, limits: Mapping[str, float], penalty: float = 0.0, penalty_rate: float = 10.0):
        if not isinstance(limits, Mapping):
            raise ValueError(f"limits must be a dict {{signal: limit}}, got {type(limits).__name__}")
        self.limits = {k: check_scalar(f"limit of {k!r}", v, 0.0, lo_open=True) for k, v in limits.items()}
        self.penalty = check_scalar("penalty", penalty, 0.0)
        self.penalty_rate = check_scalar("penalty_rate", penalty_rate, 0.0, unit="1/s")

    def amount(self, episode_seconds: float) -> float:
        """The penalty of an episode of planned length ``episode_seconds`` ended by a limit."""
        return self.penalty + self.penalty_rate * episode_seconds

    def bind(self, signals: SignalMap) -> tuple[np.ndarray, np.ndarray]:
        """(columns, limit per column)."""
        cols, lim = [], []
        for name, limit in self.limits.items():
            if name not in signals:
                raise ValueError(f"a limit names the unknown signal {name!r}")
            sig = signals[name]
            cols.append(sig.columns)
            lim.append(np.full(sig.width, limit))
        if not cols:
            return np.zeros(0, np.int64), np.zeros(0)
        return np.concatenate(cols).astype(np.int64), np.concatenate(lim)


#: ``info["termination_reason"]`` of an episode ended because an observation or the reward was not finite (NaN or
#: infinite): the step's values are not physics, so the episode cannot go on; it is ``terminated`` with the penalty
#: of a divergence.
NON_FINITE = "non_finite"


def non_finite_reason(t: float) -> str:
    """The termination reason of an episode whose observation or reward became non-finite at time ``t`` (s)."""
    return (f"{NON_FINITE}: an observation or the reward is not finite at t = {t:g} s (the plant's, the damper's or "
            "the disturbance's parameters make the physics meaningless)")
