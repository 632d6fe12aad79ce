"""The constraint-cost part: soft limits on signals whose violation is a cost, beside the reward (the constrained
MDP of safe RL: safe-control-gym, OmniSafe, Safety-Gymnasium).

A constraint is a signal and a limit per channel, on one side or both: ``"both"`` is violated when |s| > limit,
``"above"`` when s > limit, ``"below"`` when s < −limit. Constraints are grouped into named *terms* (the half car's
"stroke" term holds both axles' strokes): a term is violated at a physics row when any of its constraints is.

**The per-step cost** is the time, in seconds, during the control period at which any constraint is violated: the
count of the period's physics rows (each ``dt`` long, at the end of each physics step) where one is, times ``dt``.
So 0 ≤ cost ≤ ``control_dt``, violations between control steps count, and the episode's total is the time in
violation, whatever the control rate (as the reward is the integral of its cost over the period). Per term, the
same time (``info["cost_terms"]``); the terms may overlap in time, so their sum may exceed ``cost``.

Why time rather than an indicator per step: Safety-Gymnasium's and safe-control-gym's costs are indicators per
step (1 at a step in violation, or a sum of such per constraint), summed over a fixed-length episode and
compared with a cost limit per episode (OmniSafe's ``cost_limit``, e.g. 25 of 1 000 steps). Here the same task
runs at a 1 ms (``Physical-v0``) and a 10 ms (``-v1``) control step, so an indicator per step would count a
violation ten times more often at 1 ms, and one per 10 ms step would count a 1 ms touch as ten; the time in
violation is the indicator integrated over time. At ``control_dt = dt`` it is the indicator times ``dt``;
``cost / control_dt`` is the fraction of the period in violation; a cost limit is a time (e.g. 0.1 s per 10 s
episode: a 1 % share).

The compiled step counts the rows (:class:`~mrd_env.stepping.driver.Processing` ``cost_*``), so the scalar and the
vector environments both have the costs at no measurable cost to the step.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .signals import SignalMap

#: A constraint's side: the kernel's code (0: |s| > limit, +1: s > limit, −1: s < −limit).
SIDES = {"both": 0, "above": 1, "below": -1}
#: The default soft stroke limit of the cars and the isolator, as a fraction of the hard ``stroke_limit``: the last
#: 20 % of the travel, where a suspension's bump and rebound stops engage (illustrative: a stop's free travel
#: varies from car to car; no standard fixes it).
SOFT_STROKE_FRACTION = 0.8


@dataclass(frozen=True)
class Constraint:
    """Signal ``signal`` (SI) must stay within ``limit`` (> 0; a scalar, or one value per channel) on ``side``:
    "both" (|s| ≤ limit), "above" (s ≤ limit) or "below" (s ≥ −limit)."""

    signal: str
    limit: float | Sequence[float] | np.ndarray
    side: str = "both"

    def __post_init__(self) -> None:
        if self.side not in SIDES:
            raise ValueError(f"a constraint's side must be one of {list(SIDES)}, got {self.side!r}")
        lim = np.asarray(self.limit, dtype=np.float64)
        if lim.ndim > 1 or lim.size == 0 or not np.all(np.isfinite(lim)) or np.any(lim <= 0):
            raise ValueError(f"the limit of the constraint on {self.signal!r} must be finite and > 0 (a scalar or one "
                             f"per channel), got {self.limit!r}")


class Costs:
    """Named terms of constraints (see the module docstring): ``{term: Constraint or [Constraint, ...]}``, in
    order; empty: no constraint, every cost 0."""

    def __init__(self, terms: Mapping[str, Constraint | Sequence[Constraint]] | None = None):
        if terms is None:
            terms = {}
        if not isinstance(terms, Mapping):
            raise ValueError(f"costs must be a dict {{term: constraint(s)}}, got {type(terms).__name__}")
        self.terms: dict[str, tuple[Constraint, ...]] = {}
        for name, cons in terms.items():
            if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
                raise ValueError(f"a cost term's name must be an identifier not starting with '_' (the batched "
                                 f"infos' masks do), got {name!r}")
            cons = (cons,) if isinstance(cons, Constraint) else tuple(cons)
            if not cons or not all(isinstance(c, Constraint) for c in cons):
                raise ValueError(f"cost term {name!r} must hold one or more Constraint, got {terms[name]!r}")
            self.terms[name] = cons

    @property
    def names(self) -> tuple[str, ...]:
        """The terms' names, in order (``info["cost_terms"]`` and ``cost_<term>`` of the episode metrics)."""
        return tuple(self.terms)

    def bind(self, signals: SignalMap) -> tuple[tuple, tuple, tuple, tuple]:
        """(columns, limits, sides, term starts) for :class:`~mrd_env.stepping.driver.Processing`: the columns of
        term t are ``columns[starts[t]:starts[t + 1]]``."""
        cols, lims, sides, starts = [], [], [], [0]
        for name, cons in self.terms.items():
            for c in cons:
                if c.signal not in signals:
                    raise ValueError(f"cost term {name!r} names the unknown signal {c.signal!r}")
                sig = signals[c.signal]
                lim = np.asarray(c.limit, dtype=np.float64)
                if lim.ndim == 1 and lim.size != sig.width:
                    raise ValueError(f"the limit of the constraint on {c.signal!r} has {lim.size} values; the "
                                     f"signal has {sig.width} channels")
                cols += [int(k) for k in sig.columns]
                lims += np.broadcast_to(lim, (sig.width,)).tolist()
                sides += [SIDES[c.side]] * sig.width
            starts.append(len(cols))
        return tuple(cols), tuple(lims), tuple(sides), tuple(starts)

    def __repr__(self) -> str:
        return f"Costs({self.terms!r})"


def soft_limit(name: str, value, hard: float, fraction: float, unit: str = "m") -> float:
    """A soft limit option: ``value`` (> 0 and ≤ the hard limit ``hard``), or ``fraction`` × ``hard`` if None;
    ``ValueError`` naming option ``name`` otherwise."""
    from ..validation import check_scalar

    if value is None:
        return fraction * hard
    v = check_scalar(name, value, 0.0, lo_open=True, unit=unit)
    if v > hard:
        raise ValueError(f"{name} must not exceed the hard limit ({hard:g} {unit}: the episode ends there), got "
                         f"{v:g} {unit}")
    return v


def car_costs(soft_stroke: float, static_tyre_load) -> Costs:
    """A car's constraints (the quarter and the half car): "stroke", |travel| beyond the soft stroke limit (m, each
    suspension); "tyre_lift_off", the dynamic tyre load (signal ``_tyre_load``, N, positive = more load than
    static) below −``static_tyre_load`` (a scalar, or one per tyre): the linear tyre would pull, i.e. the wheel
    leaves the road."""
    return Costs({"stroke": Constraint("travel", soft_stroke),
                  "tyre_lift_off": Constraint("_tyre_load", static_tyre_load, "below")})


def exceedance_share(stats, term: str = "stroke") -> float:
    """The share (−) of an episode's time (its rows after the first, :class:`~.core.EpisodeStats`) at which cost
    term ``term`` is violated: ``cost_<term>`` over the duration (0 for an episode of no step)."""
    duration = (stats.n_rows - 1) * stats.dt
    return stats.cost.get(f"cost_{term}", 0.0) / duration if duration > 0 else 0.0
