"""Disturbance sources: where each episode's input record (road profile, ground motion) comes from.

A source has ``channels`` (the plant's input names, in order) and ``sample(rng, dt) -> Record``: a record on the
environment's grid with exactly those channels. :class:`FixedRecord` replays one record every episode;
:class:`Generated` draws a new one per episode from the environment's random generator (``np_random``, so
that ``reset(seed=...)`` reproduces it); :class:`Mixture` draws the kind of record too (a training
distribution over several sources).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Callable, Sequence

import numpy as np

from ..disturbances import Record


class Disturbance(ABC):
    """Base class: ``sample(rng, dt)`` returns the next episode's record (see the module docstring)."""

    channels: tuple[str, ...] = ()
    random: bool = False
    #: the most samples a record of this source has (None: not known), for the episode length an environment
    #: declares (``env.spec.max_episode_steps``)
    max_samples: int | None = None

    @abstractmethod
    def sample(self, rng: np.random.Generator, dt: float) -> Record:
        """The next episode's record on the grid ``dt`` with exactly ``channels``."""

    def describe(self) -> str:
        return type(self).__name__


def with_preview(record: Record, channel: str, steps: Sequence[int], names: Sequence[str], unit: str) -> Record:
    """``record`` with one more channel per preview: ``channel`` shifted ``steps[j]`` samples ahead (the value at
    t + steps[j]·dt), the last sample held beyond the end of the record."""
    x = record.channel(channel)
    idx = np.arange(x.size)
    ahead = [x[np.minimum(idx + k, x.size - 1)] for k in steps]
    return Record(record.dt, np.column_stack([record.data, *ahead]), (*record.channels, *names),
                  (*record.units, *[unit] * len(names)), record.name)


def on_grid(record: Record, channels: Sequence[str], units: Sequence[str], dt: float) -> Record:
    """``record`` with exactly ``channels`` (in that order) on the grid dt (resampled if needed)."""
    missing = [c for c in channels if c not in record.channels]
    if missing:
        raise ValueError(f"the record {record.name!r} must have channels {tuple(channels)} "
                         f"({', '.join(units)}); it lacks {missing}")
    data = np.column_stack([record.channel(c) for c in channels])
    out = Record(record.dt, data, tuple(channels), tuple(units), record.name)
    return out if abs(out.dt - dt) <= 1e-12 * dt else out.resample(dt)


class FixedRecord(Disturbance):
    """The same record every episode."""

    def __init__(self, record: Record, channels: Sequence[str], units: Sequence[str], dt: float):
        self.channels = tuple(channels)
        self.record = on_grid(record, channels, units, dt)
        self.max_samples = self.record.n_samples

    def sample(self, rng, dt):
        return self.record

    def describe(self) -> str:
        return self.record.name or "record"


class Generated(Disturbance):
    """A new record per episode: ``generator(rng) -> Record`` with the source's channels on the grid
    (``max_samples``: the longest record it returns, if known). A generator defined at module level (or a
    ``functools.partial`` of one) keeps the environment picklable."""

    random = True

    def __init__(self, generator: Callable[[np.random.Generator], Record], channels: Sequence[str],
                 name: str = "generated", max_samples: int | None = None):
        self.channels = tuple(channels)
        self.generator = generator
        self.name = name
        self.max_samples = max_samples

    def sample(self, rng, dt):
        rec = self.generator(rng)
        if tuple(rec.channels) != self.channels or abs(rec.dt - dt) > 1e-12 * dt:
            raise RuntimeError(f"{self.name}: the generator must return channels {self.channels} at dt = {dt:g} s, "
                               f"got {rec.channels} at {rec.dt:g} s")
        return rec

    def describe(self) -> str:
        return self.name


class Mixture(Disturbance):
    """A distribution over sources: each episode picks one (with ``weights``) and samples it."""

    random = True

    def __init__(self, sources: Sequence[Disturbance], weights: Sequence[float] | None = None):
        if not sources:
            raise ValueError("a Mixture needs at least one source")
        self.sources = list(sources)
        self.channels = self.sources[0].channels
        if any(s.channels != self.channels for s in self.sources):
            raise ValueError("every source of a Mixture must give the same channels")
        w = np.ones(len(self.sources)) if weights is None else np.asarray(weights, dtype=float)
        if w.shape != (len(self.sources),) or np.any(w < 0) or not w.sum() > 0:
            raise ValueError("Mixture weights must be one non-negative number per source, not all zero")
        self.p = w / w.sum()
        sizes = [s.max_samples for s in self.sources]
        self.max_samples = None if None in sizes else max(sizes)

    def sample(self, rng, dt):
        k = int(rng.choice(len(self.sources), p=self.p))
        return self.sources[k].sample(rng, dt)

    def describe(self) -> str:
        return " | ".join(s.describe() for s in self.sources)
