"""The termination part: limits on signals (a damper's stroke) that end an episode, and their penalty.

An episode is ``terminated`` when |signal| exceeds its limit at any physics step (or the simulation diverges);
the step's reward then loses ``penalty + penalty_per_step × (control steps left)``, so that ending an episode
early never pays (choose the penalty above the worst cost of the steps it skips).
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..validation import check_scalar
from .signals import SignalMap


class Limits:
    def __init__(self, limits: Mapping[str, float], penalty: float = 0.0, penalty_per_step: float = 1.0):
        if not isinstance(limits, Mapping):
            raise ValueError(f"limits must be a dict {{signal: limit}}, got {type(limits).__name__}")
        self.limits = {k: check_scalar(f"limit of {k!r}", v, 0.0, lo_open=True) for k, v in limits.items()}
        self.penalty = check_scalar("penalty", penalty, 0.0)
        self.penalty_per_step = check_scalar("penalty_per_step", penalty_per_step, 0.0)

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
