"""A Gymnasium ``VectorEnv`` over the quarter car's JAX step (:mod:`.jax_twin`; needs the ``[jax]`` extra).

Observations (float32, the default sensors), rewards, ``terminated``/``truncated`` and the ``NEXT_STEP`` autoreset
mean what they mean in the native vector environment (``gymnasium.make_vec("mrd_env/QuarterCar-v1", ...)``; a test
compares the two on one road): the step after an episode ends resets that environment and returns its first
observation with reward 0 and both flags false. Not yet the native infos (constraint costs, episode metrics,
termination reason): ``infos`` holds ``t`` (s) and the effective command. Roads come from the bank of
:func:`~.jax_twin.make_params`; ``reset(seed=s)`` draws environment i's from a key made of s and i.

``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", backend="jax", **options)`` makes it
(:mod:`mrd_env.plants.registry`): the control step and action mode default to the native environment's (the
physics-level id's), and the RL id sets its own, as for the native vector environment.
"""
from __future__ import annotations

import inspect

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import jax_twin as qc
from .env import assembly

#: The options whose defaults are the native environment's, not :func:`~.jax_twin.make_params`'s (the RL set-up's).
_NATIVE_DEFAULTS = {k: inspect.signature(assembly).parameters[k].default for k in ("control_dt", "action_mode")}


class QuarterCarJaxVectorEnv(VectorEnv):
    """``num_envs`` quarter cars stepped by one jitted, vmapped call; ``options`` as
    :func:`~.jax_twin.make_params` (``action_mode`` "normalized" or "physical"; ``control_dt`` and ``action_mode``
    default to the native environment's), or ``road``: one road record (the native option's spelling, as
    ``roads=[road]``). ``autoreset_mode``: only ``NEXT_STEP``."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, autoreset_mode=AutoresetMode.NEXT_STEP, road=None, **options):
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.NEXT_STEP.value):
            raise ValueError(f"autoreset_mode must be NEXT_STEP (the only mode of the JAX environment), got "
                             f"{autoreset_mode!r}")
        if road is not None:
            if not hasattr(road, "data") or "roads" in options:
                raise ValueError("road must be a road record (a bank of roads: roads=[...]), and not given with roads")
            options["roads"] = [road]
        self.num_envs = int(num_envs)
        self.params = p = qc.make_params(**{**_NATIVE_DEFAULTS, **options})
        self.control_dt = p.dt * p.n_sub
        low, high = (-1.0, 1.0) if p.normalized else (p.v_min, p.v_max)
        self.single_action_space = spaces.Box(low, high, (1,), np.float32)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (len(qc.SENSORS),), np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        reset = jax.vmap(qc.reset, in_axes=(0, None))
        step = jax.vmap(qc.step, in_axes=(None, 0, 0, None))

        def advance(keys, state, actions, restart, params):
            obs, new, reward, terminated, truncated, info = step(None, state, actions, params)
            obs0, state0 = reset(keys, params)
            pick = lambda a, b: jnp.where(restart.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)  # noqa: E731
            new = jax.tree_util.tree_map(pick, state0, new)
            return (pick(obs0, obs), new, jnp.where(restart, 0.0, reward), terminated & ~restart,
                    truncated & ~restart, jnp.where(restart, state0.U[:, 0], info["effective_command"]))

        self._reset = jax.jit(reset)
        self._advance = jax.jit(advance)
        self._state = None
        self._restart = np.zeros(self.num_envs, bool)
        self._episode = 0

    def _keys(self, seed):
        base = jax.random.PRNGKey(seed)
        return jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(self.num_envs))

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._seed = int(seed)
            self._episode = 0
        elif not hasattr(self, "_seed"):
            self._seed = int(np.random.SeedSequence().entropy % 2 ** 31)
        self._episode += 1
        obs, self._state = self._reset(self._episode_keys(), self.params)
        self._restart[:] = False
        return np.asarray(obs, np.float32), {"t": np.zeros(self.num_envs), "_t": np.ones(self.num_envs, bool)}

    def _episode_keys(self):
        return jax.vmap(lambda k: jax.random.fold_in(k, self._episode))(self._keys(self._seed))

    def step(self, actions):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, 1)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions contain a non-finite value")
        self._episode += 1
        obs, self._state, reward, terminated, truncated, u = self._advance(
            self._episode_keys(), self._state, jnp.asarray(a), jnp.asarray(self._restart), self.params)
        terminated, truncated = np.asarray(terminated), np.asarray(truncated)
        self._restart = terminated | truncated
        t = np.asarray(self._state.k) * self.control_dt
        infos = {"t": t, "_t": np.ones(self.num_envs, bool), "effective_command": np.asarray(u),
                 "_effective_command": np.ones(self.num_envs, bool)}
        return np.asarray(obs, np.float32), np.asarray(reward), terminated, truncated, infos
