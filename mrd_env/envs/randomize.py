"""Options drawn anew for every episode (training distributions): a tuple (lo, hi) is drawn uniformly, a list
is a choice of one of its values; anything else is a fixed value. The draws come from the environment's
generator, before the record's own random numbers, so ``reset(seed=...)`` reproduces them; a fixed value
draws nothing (its episodes are those of the plain option)."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..validation import check_scalar


def is_random(value) -> bool:
    return isinstance(value, (tuple, list))


def values(name: str, value, check: Callable | None = None) -> list:
    """Every value ``value`` may take, checked by ``check`` (default: a finite real number named ``name``) —
    the bounds of a range, each choice."""
    if check is None:
        def check(v):
            return check_scalar(name, v)
    if isinstance(value, tuple):
        if len(value) != 2:
            raise ValueError(f"{name}: a range is a pair (lo, hi), got {value!r}")
        lo, hi = (check_scalar(f"{name} range", v) for v in value)
        if not lo <= hi:
            raise ValueError(f"{name}: a range (lo, hi) needs lo <= hi, got {value!r}")
        return [check(lo), check(hi)]
    if isinstance(value, list):
        if not value:
            raise ValueError(f"{name}: a choice needs at least one value")
        return [check(v) for v in value]
    return [check(value)]


def draw(value, rng: np.random.Generator):
    """One episode's value."""
    if isinstance(value, tuple):
        return float(rng.uniform(value[0], value[1]))
    if isinstance(value, list):
        return value[int(rng.integers(len(value)))]
    return value


def describe(value, fmt: str = "g") -> str:
    if isinstance(value, tuple):
        return f"U({value[0]:{fmt}}, {value[1]:{fmt}})"
    if isinstance(value, list):
        return "{" + ", ".join(format(v, fmt) if not isinstance(v, str) else v for v in value) + "}"
    return format(value, fmt) if not isinstance(value, str) else value
