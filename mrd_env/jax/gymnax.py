"""Any plant's JAX environment as gymnax users hold it: an object with gymnax's method names and signatures
(``reset(key, params)``, ``step(key, state, action, params)`` with its auto-reset, ``default_params``, the spaces),
so trainers written for gymnax (PureJaxRL's single-file PPO and its wrappers) run on it unchanged.

It is duck-typed: gymnax itself is not needed (it pins an older Gymnasium than the project's). The functions are
:mod:`mrd_env.jax.env`'s; this module only gives them gymnax's shape. ``done`` is ``terminated | truncated``, as
gymnax's; ``info`` keeps the two apart (``terminated``, ``truncated``; ``discount`` is 0 only after a termination)
with the step's own entries (``cost``, ``cost_terms``, ``effective_command``, ...) and ``final_observation``.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..envs.base import action_space as native_action_space
from . import env as je
from .vector import DEFAULT_SCHEME


class Box:
    """gymnax's ``spaces.Box``: ``low``, ``high``, ``shape``, ``dtype``, ``sample(key)``, ``contains(x)``. A
    dimension unbounded on both sides samples a standard normal (Gymnasium's rule), a bounded one uniformly."""

    def __init__(self, low, high, shape: tuple, dtype=jnp.float64):
        self.low, self.high, self.shape, self.dtype = low, high, tuple(shape), dtype

    def sample(self, key):
        low = jnp.broadcast_to(jnp.asarray(self.low, self.dtype), self.shape)
        high = jnp.broadcast_to(jnp.asarray(self.high, self.dtype), self.shape)
        bounded = jnp.isfinite(low) & jnp.isfinite(high)
        k1, k2 = jax.random.split(key)
        u = jax.random.uniform(k1, self.shape, self.dtype, jnp.where(bounded, low, 0.0),
                               jnp.where(bounded, high, 1.0))
        return jnp.where(bounded, u, jax.random.normal(k2, self.shape, self.dtype))

    def contains(self, x):
        x = jnp.asarray(x)
        return (x.shape == self.shape) & jnp.all(x >= self.low) & jnp.all(x <= self.high)

    def __repr__(self) -> str:
        return f"Box(low={self.low}, high={self.high}, shape={self.shape}, dtype={jnp.dtype(self.dtype).name})"


class GymnaxEnv:
    """One set-up's twin (its :class:`~mrd_env.jax.env.EnvParams`, ``default_params``) with gymnax's methods. Every
    method takes ``params`` (``None``: ``default_params``), so a batch of parameters (e.g. drawn with
    :func:`~mrd_env.jax.env.draw_params`) can be vmapped as in gymnax. ``name``: the environment id."""

    def __init__(self, params: je.EnvParams, name: str, action_low, action_high):
        self._params, self._name = params, name
        self._action = (np.asarray(action_low, np.float64), np.asarray(action_high, np.float64))

    @property
    def default_params(self) -> je.EnvParams:
        return self._params

    @property
    def name(self) -> str:
        return self._name

    @property
    def num_actions(self) -> int:
        """The action's length (one command per damper)."""
        return int(self._params.nd)

    def reset(self, key, params: je.EnvParams | None = None):
        """(observation, state) of a new episode on a record of the bank drawn from ``key``."""
        return je.reset(key, self._params if params is None else params)

    def reset_env(self, key, params: je.EnvParams | None = None):
        return self.reset(key, params)

    def step_env(self, key, state, action, params: je.EnvParams | None = None):
        """One control period without auto-reset: (observation, state, reward, done, info)."""
        obs, state, reward, terminated, truncated, info = je.step(key, state, action,
                                                                 self._params if params is None else params)
        return obs, state, reward, terminated | truncated, self._info(info, terminated, truncated)

    def step(self, key, state, action, params: je.EnvParams | None = None):
        """One control period; an episode that ended is replaced by a new one in the same call (gymnax's
        auto-reset: the returned observation and state are the new episode's, ``info["final_observation"]`` the
        ended one's last). The key splits as gymnax's: one part for the step, one for the reset."""
        obs, state, reward, terminated, truncated, info = je.step_autoreset(
            key, state, action, self._params if params is None else params)
        return obs, state, reward, terminated | truncated, self._info(info, terminated, truncated)

    @staticmethod
    def _info(info: dict, terminated, truncated) -> dict:
        return {**info, "terminated": terminated, "truncated": truncated,
                "discount": 1.0 - terminated.astype(jnp.float64)}

    def action_space(self, params: je.EnvParams | None = None) -> Box:
        """The commands' Box (one per damper; [−1, 1] with normalised actions), float64 as the twin computes."""
        low, high = self._action
        return Box(low, high, low.shape)

    def observation_space(self, params: je.EnvParams | None = None) -> Box:
        """The measurement's Box (unbounded, as the native environment's), float64 as the twin returns it."""
        p = self._params if params is None else params
        return Box(-np.inf, np.inf, (len(p.meas_cols) * p.history,))

    def __repr__(self) -> str:
        return f"GymnaxEnv({self._name!r}, scheme={self._params.scheme!r}, records={self._params.W.shape[0]})"


def make_gymnax(env_id: str, *, seeds=None, records=None, randomise=None, scheme: str = DEFAULT_SCHEME,
                substeps: int = 1, newton_iterations: int = 2, jacobian: str = "kernel", **options) -> GymnaxEnv:
    """The twin of ``gymnasium.make(env_id, **options)`` as a gymnax environment: its bank of episodes, scheme and
    options as :func:`mrd_env.jax.env.make_params` takes them (default bank: the records a native environment
    meets at ``reset(seed=s)`` for s in 0…15; default scheme the vector environment's, ``differentiable``: fixed
    work per step). Bad values raise ``ValueError`` naming the option."""
    params = je.make_params(env_id, seeds=range(16) if seeds is None else seeds, records=records,
                            randomise=randomise, scheme=scheme, substeps=substeps,
                            newton_iterations=newton_iterations, jacobian=jacobian, **options)
    asm, _ = je.assembly_of(env_id, options)
    box = native_action_space(asm)
    return GymnaxEnv(params, env_id, box.low, box.high)


__all__ = ["Box", "GymnaxEnv", "make_gymnax"]
