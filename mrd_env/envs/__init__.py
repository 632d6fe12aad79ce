"""Gymnasium environments: ``mrd_env/QuarterCar-v0`` and ``mrd_env/ShearBuilding-v0``.

>>> import gymnasium as gym, mrd_env
>>> env = gym.make("mrd_env/QuarterCar-v0", road="iso8608", road_params={"road_class": "D"})

The environment classes (:class:`MRDamperEnv`, :class:`QuarterCarEnv`, :class:`ShearBuildingEnv`) are imported
on first access, so that :func:`register_envs` (run by ``import mrd_env``) stays cheap.
"""
from __future__ import annotations

import importlib

ENV_IDS = {
    "mrd_env/QuarterCar-v0": "mrd_env.envs.quarter_car:QuarterCarEnv",
    "mrd_env/ShearBuilding-v0": "mrd_env.envs.shear_building:ShearBuildingEnv",
}

_LAZY = {"MRDamperEnv": ".base", "QuarterCarEnv": ".quarter_car", "ShearBuildingEnv": ".shear_building"}


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent: ids already registered are left alone)."""
    import gymnasium

    for env_id, entry_point in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["MRDamperEnv", "QuarterCarEnv", "ShearBuildingEnv", "ENV_IDS", "register_envs"]
