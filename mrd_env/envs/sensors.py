"""The sensors part: which signals an observation holds, with Gaussian noise, a delay and a history.

``names``: signals in the order of the observation; ``noise``: {name: std} in the signal's SI unit (a scalar or
one value per channel); ``delay``: the observation at control step k is the measurement of step k − delay;
``history``: the last ``history`` measurements stacked, oldest first (so that a memoryless policy can infer
velocities and hysteresis; ``history=1`` is the plain observation).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .signals import SignalMap

MAX_STEPS = 10_000  # of delay or history (the FIFO is allocated per environment)


class Sensors:
    def __init__(self, names: Sequence[str], noise: Mapping | None = None, delay: int = 0, history: int = 1):
        if isinstance(names, str):
            names = (names,)
        try:
            names = tuple(names)
        except TypeError:
            raise ValueError(f"sensors must be a sequence of sensor names, got {names!r}") from None
        if not names or not all(isinstance(n, str) for n in names):
            raise ValueError(f"sensors must name at least one sensor (strings), got {names!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"sensors must not repeat a name, got {names}")
        for name, value, lo in (("sensor_delay", delay, 0), ("history", history, 1)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= MAX_STEPS:
                raise ValueError(f"{name} must be an int in [{lo}, {MAX_STEPS}] (control steps), got {value!r}")
        if noise is not None and not isinstance(noise, Mapping):
            raise ValueError(f"sensor_noise must be a dict {{sensor: std}}, got {type(noise).__name__}")
        self.names = names
        self.noise = dict(noise or {})
        self.delay = int(delay)
        self.history = int(history)

    def bind(self, signals: SignalMap, valid: Sequence[str]):
        """(measured columns, noise std per column, layout [(name, slice, unit)], labels) on ``signals``."""
        for s in self.names:
            if s not in valid:
                raise ValueError(f"unknown sensor {s!r}; valid sensors: {list(valid)}")
        cols, layout, labels, start = [], [], [], 0
        for name in self.names:
            sig = signals[name]
            cols.append(sig.columns)
            layout.append((name, slice(start, start + sig.width), sig.unit))
            labels += [name] if sig.width == 1 else [f"{name}[{i}]" for i in range(sig.width)]
            start += sig.width
        std = np.zeros(start)
        where = {name: sl for name, sl, _ in layout}
        for name, v in self.noise.items():
            if name not in where:
                raise ValueError(f"sensor_noise names {name!r}, which is not among the chosen sensors {self.names}")
            sl = where[name]
            a = _stds(v)
            width = sl.stop - sl.start
            if a is None or a.shape not in ((), (width,)) or not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ValueError(f"sensor_noise[{name!r}] must be a finite std >= 0 ({signals[name].unit}), "
                                 f"scalar or {width} values, got {v!r}")
            std[sl] = a
        if self.history > 1:
            labels = [f"{lab}[t-{self.history - 1 - k}]" if k < self.history - 1 else f"{lab}[t]"
                      for k in range(self.history) for lab in labels]
        return np.concatenate(cols).astype(np.int64), std, layout, labels


def _stds(value) -> np.ndarray | None:
    """``value`` as an array of real numbers, or None (text, complex, dicts, ragged lists, overflowing ints)."""
    if isinstance(value, (str, bytes, Mapping)):
        return None
    try:
        if np.iscomplexobj(value):
            return None
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return None


def newest_layout(env) -> dict[str, slice]:
    """Where each sensor's newest measurement sits in the observations of ``env`` (scalar or vector): its
    ``sensor_layout`` describes one measurement, and with ``history`` > 1 the observation stacks that many,
    oldest first, so the newest is the last block."""
    base = getattr(env, "unwrapped", env)
    width = max(sl.stop for _, sl, *_ in base.sensor_layout)
    offset = getattr(base, "single_observation_space", base.observation_space).shape[-1] - width
    return {name: slice(sl.start + offset, sl.stop + offset) for name, sl, *_ in base.sensor_layout}
