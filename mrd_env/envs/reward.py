"""The reward part: quadratic forms of named signals (compiled, every physics step) or any Python callable.

:class:`QuadraticReward` — r = −Δt Σ_k Σ_i w_i h_i(t_k)² over the n_sub physics steps t_k of a control
period (the integral of the cost rate Σ_i w_i h_i² over the period, so that returns do not depend on the
control rate), w_i ≥ 0 per signal channel (1/reference² times a weight); the weights may be rescaled per
episode (``episode_scale``, e.g. by the uncontrolled building's response to that record). Evaluated inside
the compiled step.

:class:`CallableReward` — any ``fn(period) -> float`` of the signals of the period (a dict {name: array
(n_sub, width)}); the documented slower path (one Python call per step, the period's rows copied out).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from .signals import SignalMap


class QuadraticReward:
    def __init__(self, weights: Mapping[str, float], episode_scale: Callable | None = None):
        if not isinstance(weights, Mapping):
            raise ValueError(f"reward weights must be a dict {{signal: weight}}, got {type(weights).__name__}")
        self.weights = {}
        for k, v in weights.items():
            w = np.asarray(v, dtype=float) if np.isrealobj(v) and not isinstance(v, (str, bytes)) else None
            if w is None or w.ndim > 1 or not np.all(np.isfinite(w)) or np.any(w < 0):
                raise ValueError(f"reward weight of {k!r} must be finite and >= 0 (scalar or per channel), got {v!r}")
            self.weights[k] = w
        self.episode_scale = episode_scale

    def bind(self, signals: SignalMap) -> tuple[np.ndarray, np.ndarray]:
        """(columns, weights) of the terms."""
        cols, w = [], []
        for name, weight in self.weights.items():
            if name not in signals:
                raise ValueError(f"the reward names the unknown signal {name!r}; signals: {sorted(signals.signals)}")
            sig = signals[name]
            cols.append(sig.columns)
            w.append(np.broadcast_to(weight, (sig.width,)))
        if not cols:
            return np.zeros(0, np.int64), np.zeros(0)
        return np.concatenate(cols).astype(np.int64), np.concatenate(w).astype(float)

    def scales(self, episode, base: np.ndarray) -> np.ndarray:
        """The weights of this episode."""
        return base if self.episode_scale is None else base * self.episode_scale(episode)


class CallableReward:
    def __init__(self, fn: Callable[[Mapping[str, np.ndarray]], float]):
        if not callable(fn):
            raise ValueError("reward must be callable")
        self.fn = fn

    def __call__(self, period: Mapping[str, np.ndarray]) -> float:
        r = float(self.fn(period))
        if not np.isfinite(r):
            raise ValueError(f"the reward function returned {r!r}; it must return a finite number")
        return r
