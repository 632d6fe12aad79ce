"""Gymnasium's registrations, generated from the plants' specs (:func:`mrd_env.plants.plants`): for every plant
the physics-level id ``mrd_env/<Name>Physical-v0``, the RL id ``mrd_env/<Name>-v1`` and its former ids, each with a
scalar entry point (the environment in a TimeLimit at its own episode length: :mod:`mrd_env.envs.entry`) and a
vector entry point (the plant's native vector environment, or with ``backend="jax"`` its JAX one,
:class:`mrd_env.jax.vector.JaxVectorEnv` of the same id and options, for every plant: JAX is imported only then).

The two set-ups are two environments, not two versions of one: Gymnasium reads ``-v0`` beside ``-v1`` of the same
name as an outdated version (it says "out of date" at every ``make``), so the physics-level set-up has its own name.
Its former ids (``mrd_env/QuarterCar-v0``, ...) still make the same environment, with a warning naming the new one.

>>> import gymnasium as gym, mrd_env
>>> env = gym.make("mrd_env/QuarterCarPhysical-v0", road="iso8608", road_params={"road_class": "D"})
>>> venv = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=64, vectorization_mode="vector_entry_point")
>>> jvenv = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=64, vectorization_mode="vector_entry_point", backend="jax")

With ``backend="jax"`` the JAX environment steps with its fast ``scheme="differentiable"`` (within 0.5 % NRMSE of the
exact scheme, at or above the native speed); pass ``scheme="exact"`` for the native environment's numbers
(cross-checks, a fraction of the speed).
"""
from __future__ import annotations

from ..envs import RL_DEFAULTS
from ..envs.entry import FormerIdEntryPoint, TimeLimitedEntryPoint, warn_torch_threads
from . import plants


def envs() -> dict[str, tuple[str, str, str]]:
    """physics-level id → (module, scalar class, vector class), for every plant."""
    return {s.physics_id: (s.env_module, s.env_class, s.vector_env_class) for s in plants().values()}


def v1() -> dict[str, tuple[str, dict]]:
    """RL id → (its physics-level id, the options it sets: :data:`~mrd_env.envs.RL_DEFAULTS` and the plant's
    ``v1_options``) — every option that differs between the two ids, in one table."""
    return {s.rl_id: (s.physics_id, {**RL_DEFAULTS, **s.v1_options}) for s in plants().values()}


def renamed() -> dict[str, str]:
    """former id → the physics-level id it makes now."""
    return {former: s.physics_id for s in plants().values() for former in s.former_ids}


def former_id_entry(former: str) -> str:
    """The entry point's attribute name of a former id (``mrd_env/QuarterCar-v0`` → ``QuarterCar_v0``)."""
    return former.split("/")[-1].replace("-", "_")


def entry_point(env_id: str) -> str:
    """``gym.make``'s entry point of a physics-level id: ``mrd_env.plants.registry:<Name>Env``."""
    return f"{__name__}:{envs()[env_id][1]}"


def register_envs() -> None:
    """Register every plant's ids with Gymnasium (idempotent: ids already registered are left alone).

    No ``max_episode_steps`` is registered: an environment's episode length depends on its options
    (``episode_seconds``, ``control_dt``, the disturbance), so the entry point wraps each environment in a
    TimeLimit at its own length, which ``env.spec.max_episode_steps`` states; a registered value would add a
    TimeLimit at the wrong length. Every registered keyword is JSON's (lists, not tuples), so that the specs
    survive ``EnvSpec.to_json``/``from_json``."""
    import gymnasium

    for s in plants().values():
        vector = f"{__name__}:{s.vector_env_class}"
        scalar = f"{__name__}:{s.env_class}"
        if s.physics_id not in gymnasium.registry:
            gymnasium.register(id=s.physics_id, entry_point=scalar, vector_entry_point=vector)
        if s.rl_id not in gymnasium.registry:
            gymnasium.register(id=s.rl_id, entry_point=scalar, vector_entry_point=vector,
                               kwargs={**RL_DEFAULTS, **s.v1_options})
        for former in s.former_ids:
            if former not in gymnasium.registry:
                gymnasium.register(id=former, entry_point=f"{__name__}:{former_id_entry(former)}",
                                   vector_entry_point=vector)


#: The vector entry points' ``backend`` values.
BACKENDS = ("native", "jax")


class VectorEntryPoint:
    """A plant's vector entry point: its native vector environment, or (``backend="jax"``) its JAX one
    (:class:`mrd_env.jax.vector.JaxVectorEnv`, by default with the fast differentiable scheme; ``scheme="exact"``
    for the native environment's numbers)."""

    def __init__(self, spec):
        self.spec = spec

    def __call__(self, num_envs: int = 1, backend: str = "native", **kwargs):
        warn_torch_threads()  # SB3 over make_vec's environments: the same once-per-process advice as gym.make's
        if backend == "native":
            return self.spec.vector_env(num_envs=num_envs, **kwargs)
        if backend != "jax":
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        from ..jax.vector import JaxVectorEnv  # JAX missing: its own ImportError (pip install mrd-env[jax])

        # the physics-level id: make_vec passes an RL id's registered options (control_dt, ...) in kwargs
        return JaxVectorEnv(self.spec.physics_id, num_envs=num_envs, **kwargs)


def __getattr__(name: str) -> TimeLimitedEntryPoint | VectorEntryPoint:
    """The registered entry points: ``<Name>Env`` (every plant's scalar class in its TimeLimit), ``<Name>VectorEnv``
    (:class:`VectorEntryPoint`) and a former id's ``<Name>_v0``."""
    for s in plants().values():
        if s.env_class == name:
            return TimeLimitedEntryPoint(s.env_module, s.env_class)
        if s.vector_env_class == name:
            return VectorEntryPoint(s)
        for former in s.former_ids:
            if former_id_entry(former) == name:
                return FormerIdEntryPoint(s.env_module, s.env_class, former, s.physics_id)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
