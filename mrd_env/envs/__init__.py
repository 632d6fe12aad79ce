"""Gymnasium environments: ``mrd_env/QuarterCar-v0``, ``mrd_env/ShearBuilding-v0`` and ``mrd_env/HalfCar-v0``,
scalar and native vector.

>>> import gymnasium as gym, mrd_env
>>> env = gym.make("mrd_env/QuarterCar-v0", road="iso8608", road_params={"road_class": "D"})
>>> venv = gym.make_vec("mrd_env/QuarterCar-v0", num_envs=64, vectorization_mode="vector_entry_point")

The environment classes are imported on first access, so that :func:`register_envs` (run by ``import mrd_env``)
stays cheap.
"""
from __future__ import annotations

import importlib

#: id → (module, scalar class, vector class)
ENVS = {
    "mrd_env/QuarterCar-v0": ("mrd_env.envs.quarter_car", "QuarterCarEnv", "QuarterCarVectorEnv"),
    "mrd_env/ShearBuilding-v0": ("mrd_env.envs.shear_building", "ShearBuildingEnv", "ShearBuildingVectorEnv"),
    "mrd_env/HalfCar-v0": ("mrd_env.envs.half_car", "HalfCarEnv", "HalfCarVectorEnv"),
}
ENV_IDS = {env_id: f"{m}:{c}" for env_id, (m, c, _) in ENVS.items()}

_LAZY = {"MRDamperEnv": ".base", "MRDamperVectorEnv": ".vector", "QuarterCarEnv": ".quarter_car",
         "QuarterCarVectorEnv": ".quarter_car", "ShearBuildingEnv": ".shear_building",
         "ShearBuildingVectorEnv": ".shear_building", "HalfCarEnv": ".half_car", "HalfCarVectorEnv": ".half_car",
         "env_info": ".vector", "Assembly": ".core", "EnvCore": ".core",
         "Sensors": ".sensors", "QuadraticReward": ".reward", "CallableReward": ".reward", "Limits": ".termination",
         "FixedRecord": ".disturbance", "Generated": ".disturbance", "Mixture": ".disturbance",
         "Disturbance": ".disturbance"}


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent: ids already registered are left alone).

    No ``max_episode_steps`` is registered: an environment's episode length depends on its options
    (``episode_seconds``, ``control_dt``, the disturbance), so each environment states its own in
    ``env.spec.max_episode_steps`` and truncates itself; a registered value would add a TimeLimit at the wrong
    length."""
    import gymnasium

    for env_id, (module, scalar, vector) in ENVS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=f"{module}:{scalar}", vector_entry_point=f"{module}:{vector}")


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ENVS", "ENV_IDS", "register_envs", *_LAZY]
