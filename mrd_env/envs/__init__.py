"""Gymnasium environments: the quarter car, the shear building and the half car, scalar and native vector, each in two
set-ups: ``mrd_env/QuarterCar-v1`` (``ShearBuilding-v1``, ``HalfCar-v1``) with the defaults an RL user expects (10 ms
control, normalised actions, the benchmark's building), and ``mrd_env/QuarterCarPhysical-v0`` (...) with the
physics-level ones (1 ms control, commands in V or A, the lab building): see ``V1``.

The two set-ups are two environments, not two versions of one: Gymnasium reads ``-v0`` beside ``-v1`` of the same
name as an outdated version (it says "out of date" at every ``make``), so the physics-level set-up has its own name.
Its former ids (``mrd_env/QuarterCar-v0``, ...) still make the same environment, with a warning naming the new one
(:data:`RENAMED`).

>>> import gymnasium as gym, mrd_env
>>> env = gym.make("mrd_env/QuarterCarPhysical-v0", road="iso8608", road_params={"road_class": "D"})
>>> venv = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=64, vectorization_mode="vector_entry_point")

The environment classes are imported on first access, so that :func:`register_envs` (run by ``import mrd_env``)
stays cheap.

Episode length and the spec (issue 37): ``gym.make`` builds a scalar environment through an entry point of
:mod:`.entry`, which wraps it in a TimeLimit at the environment's own episode length (it depends on the options),
so that ``env.spec.max_episode_steps`` states it as Gymnasium's environments do and ``gym.make(env.spec)``
re-creates the environment; the native vector environment puts the length in its spec and in the spec's keywords
(see ``PlantDeclarations.spec`` in :mod:`.core`).
"""
from __future__ import annotations

import importlib

#: id → (module, scalar class, vector class)
ENVS = {
    "mrd_env/QuarterCarPhysical-v0": ("mrd_env.envs.quarter_car", "QuarterCarEnv", "QuarterCarVectorEnv"),
    "mrd_env/ShearBuildingPhysical-v0": ("mrd_env.envs.shear_building", "ShearBuildingEnv", "ShearBuildingVectorEnv"),
    "mrd_env/HalfCarPhysical-v0": ("mrd_env.envs.half_car", "HalfCarEnv", "HalfCarVectorEnv"),
}
#: The v1 ids: what an RL user expects out of the box (Stable-Baselines3's docs and RL Zoo), the set-up the project's
#: own training and benchmark use — a 10 ms control step (100 Hz: 1 000 steps per 10 s episode, physics still at
#: 1 ms), actions normalised to [−1, 1], and the building with its damper in storey 2, where the laws can be told
#: apart (in storey 1, passive-on is within 0.5 % of the best law). The v0 ids keep the physics-level defaults:
#: commands in V or A at every 1 ms step, the building as Dyke et al. (1996) built it (damper in storey 1).
RL_DEFAULTS = {"control_dt": 0.01, "action_mode": "normalized"}
#: The benchmark's building: its damper in storey 2 (between floors 1 and 2), where the laws can be told apart.
BENCHMARK_DAMPER_FLOORS = (2,)
#: former id → its name now (the same set-up; the former ids warn, then make it: agents saved before keep loading)
RENAMED = {"mrd_env/QuarterCar-v0": "mrd_env/QuarterCarPhysical-v0",
           "mrd_env/ShearBuilding-v0": "mrd_env/ShearBuildingPhysical-v0",
           "mrd_env/HalfCar-v0": "mrd_env/HalfCarPhysical-v0"}
V1 = {"mrd_env/QuarterCar-v1": ("mrd_env/QuarterCarPhysical-v0", dict(RL_DEFAULTS)),
      # a list, not a tuple: every registered keyword must survive EnvSpec.to_json/from_json unchanged (issue 37)
      "mrd_env/ShearBuilding-v1": ("mrd_env/ShearBuildingPhysical-v0",
                                   {**RL_DEFAULTS, "damper_floors": list(BENCHMARK_DAMPER_FLOORS)}),
      "mrd_env/HalfCar-v1": ("mrd_env/HalfCarPhysical-v0", dict(RL_DEFAULTS))}

_LAZY = {"MRDamperEnv": ".base", "MRDamperVectorEnv": ".vector", "QuarterCarEnv": ".quarter_car",
         "QuarterCarVectorEnv": ".quarter_car", "ShearBuildingEnv": ".shear_building",
         "ShearBuildingVectorEnv": ".shear_building", "HalfCarEnv": ".half_car", "HalfCarVectorEnv": ".half_car",
         "env_info": ".vector", "Assembly": ".core", "EnvCore": ".core",
         "Sensors": ".sensors", "QuadraticReward": ".reward", "CallableReward": ".reward", "Limits": ".termination",
         "FixedRecord": ".disturbance", "Generated": ".disturbance", "Mixture": ".disturbance",
         "Disturbance": ".disturbance", "EpisodeTimeLimit": ".entry", "TimeLimitedEntryPoint": ".entry"}


#: id → gym.make's entry point: the scalar class in a TimeLimit at its own episode length (:mod:`.entry`)
ENTRY_POINTS = {env_id: f"{__name__}.entry:{c}" for env_id, (_, c, _) in ENVS.items()}


def former_id_entry(former: str) -> str:
    """The entry point's attribute name of a former id (``mrd_env/QuarterCar-v0`` → ``QuarterCar_v0``)."""
    return former.split("/")[-1].replace("-", "_")


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent: ids already registered are left alone).

    No ``max_episode_steps`` is registered: an environment's episode length depends on its options
    (``episode_seconds``, ``control_dt``, the disturbance), so the entry point (:mod:`.entry`) wraps each
    environment in a TimeLimit at its own length, which ``env.spec.max_episode_steps`` states; a
    registered value would add a TimeLimit at the wrong length. Every registered keyword is JSON's (lists, not
    tuples), so that the specs survive ``EnvSpec.to_json``/``from_json``."""
    import gymnasium

    for env_id, (module, _, vector) in ENVS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=ENTRY_POINTS[env_id], vector_entry_point=f"{module}:{vector}")
    for env_id, (base, defaults) in V1.items():
        if env_id not in gymnasium.registry:
            module, _, vector = ENVS[base]
            gymnasium.register(id=env_id, entry_point=ENTRY_POINTS[base], vector_entry_point=f"{module}:{vector}",
                               kwargs=defaults)
    for former, now in RENAMED.items():
        if former not in gymnasium.registry:
            module, scalar, vector = ENVS[now]
            gymnasium.register(id=former, entry_point=f"{__name__}.entry:{former_id_entry(former)}",
                               vector_entry_point=f"{module}:{vector}")


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ENVS", "ENTRY_POINTS", "RL_DEFAULTS", "BENCHMARK_DAMPER_FLOORS", "V1", "RENAMED", "register_envs", *_LAZY]
