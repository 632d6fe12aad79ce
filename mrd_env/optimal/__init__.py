"""The yardstick: the best any controller could do on an episode, and a bound from above.

* :func:`episode_problem` — one seeded episode of an environment as optimisation data (:mod:`.problem`);
* :func:`clairvoyant` — the full-knowledge optimal command sequence, re-simulated in the environment
  (:mod:`.full_knowledge`, CasADi; the module is not named after the function, so that importing it never
  shadows the function on the package);
* :func:`active_bound` — the same episode with an ideal force actuator (:mod:`.bound`, a convex QP);
* :func:`dissipative_bound` — the same with the actuator barred from giving back more energy than it has absorbed
  (:mod:`.dissipative`, a convex SOCP): a bound on every passive device, tighter than the active one.

The solvers are optional dependencies (the ``[optimal]`` extra) and are imported on first use.
"""
from __future__ import annotations

import importlib

_LAZY = {"episode_problem": ".problem", "EpisodeProblem": ".problem", "CostTerm": ".problem", "Limit": ".problem",
         "Trajectory": ".problem", "clairvoyant": ".full_knowledge", "ClairvoyantResult": ".full_knowledge",
         "active_bound": ".bound", "BoundResult": ".bound", "dissipative_bound": ".dissipative",
         "DissipativeBoundResult": ".dissipative"}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = list(_LAZY)
