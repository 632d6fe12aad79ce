"""The environment machinery every plant's environment is assembled from: the scalar and native vector
environments (:class:`MRDamperEnv`, :class:`MRDamperVectorEnv`), the core (an :class:`Assembly` of parts turned
into one compiled driver), sensors, rewards, limits, disturbances, actuation, the renderer's frame and the entry
points. The plants' environments are in their folders (``mrd_env/plants/<plant>/env.py``) and registered from
their specs (:mod:`mrd_env.plants.registry`).

The names are imported on first access, so that ``import mrd_env`` stays cheap.
"""
from __future__ import annotations

import importlib

#: The RL set-up of every ``-v1`` id: what an RL user expects out of the box (Stable-Baselines3's docs and RL Zoo),
#: the set-up the project's own training and benchmark use — a 10 ms control step (100 Hz: 1 000 steps per 10 s
#: episode, physics still at 1 ms) and actions normalised to [−1, 1]. The physics-level ids keep commands in V or
#: A at every 1 ms step. A plant adds its own v1 options in its spec (``PlantSpec.v1_options``).
RL_DEFAULTS = {"control_dt": 0.01, "action_mode": "normalized"}

_LAZY = {"MRDamperEnv": ".base", "MRDamperVectorEnv": ".vector", "env_info": ".vector", "Assembly": ".core",
         "EnvCore": ".core", "Sensors": ".sensors", "QuadraticReward": ".reward", "CallableReward": ".reward",
         "Limits": ".termination", "FixedRecord": ".disturbance", "Generated": ".disturbance",
         "Mixture": ".disturbance", "Disturbance": ".disturbance", "EpisodeTimeLimit": ".entry",
         "TimeLimitedEntryPoint": ".entry"}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["RL_DEFAULTS", *_LAZY]
