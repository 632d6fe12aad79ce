"""Stable-Baselines3 ``VecEnvWrapper``\\ s for training agents on mrd-env (any SB3 or sb3-contrib algorithm).

Both wrap the SB3 bridge (:func:`mrd_env.envs.sb3.make_sb3_vec_env`) directly, below ``VecMonitor`` and
``VecNormalize``, because they read raw observations and rewards::

    venv = make_sb3_vec_env("mrd_env/QuarterCar-v0", n_envs=16, seed=0, action_mode="normalized", control_dt=0.01)
    venv = VecMonitor(ResidualVecEnv(venv, "skyhook_continuous"))   # below the paired baseline: the own returns
    venv = VecNormalize(PairedBaselineVecEnv(venv, "skyhook_continuous"))

- :class:`ResidualVecEnv`: the agent's actions are corrections to a law's command (:mod:`controllers.residual`).
- :class:`PairedBaselineVecEnv`: variance reduction by a paired baseline. A twin of the environments, a copy taken
  at reset (the same roads or ground motions, the same generators), is driven by a reference law in lockstep; the
  agent's reward is r_t − r_t^ref. The reference rewards depend on the disturbance only, never on the agent's
  actions, so within an episode of fixed length the return changes by a policy-independent amount and the best
  policy is unchanged, while the disturbance's share of the return's variance — which dominates the advantages
  on random roads — cancels (an input-driven baseline, Mao et al., ICLR 2019, arXiv:1807.02264). An episode the
  agent ends early (a stroke limit) is not of fixed length: it forgoes the reference's remaining −Σ r_ref > 0, an
  extra termination penalty of the law's remaining cost (same sign as the environment's own). The episode infos
  (``infos[i]["episode"]``) hold the environment's own return when a ``VecMonitor`` sits below this wrapper (as
  above; one above it would record the paired return).
"""
from __future__ import annotations

import copy

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnvWrapper

from .base import Controller
from .residual import Residual


def _native(venv):
    """The native vector environment under the SB3 bridge of ``venv``."""
    inner = venv.unwrapped
    native = getattr(inner, "venv", None)
    if native is None or not hasattr(native, "core"):
        raise ValueError("the wrapper needs the SB3 bridge of mrd-env (mrd_env.envs.sb3.make_sb3_vec_env) under it")
    return native


class ResidualVecEnv(VecEnvWrapper):
    """Actions a ∈ [−1, 1]^nd are corrections to the command of ``law`` (see :class:`controllers.residual.Residual`:
    ``scale``, ``boundary``, ``law_options``), observations are the environment's with the law's command appended
    (:meth:`~controllers.residual.Residual.observe`); it must wrap the bridge directly (it reads raw observations)."""

    def __init__(self, venv, law: str | Controller, scale: float = 1.0, **law_options):
        self.residual = Residual(_native(venv), law, scale, **law_options)
        nd = self.residual.n_dampers
        space = venv.observation_space
        obs_space = spaces.Box(np.concatenate([space.low, -np.ones(nd, np.float32)]),
                               np.concatenate([space.high, np.ones(nd, np.float32)]), dtype=np.float32)
        super().__init__(venv, observation_space=obs_space,
                         action_space=spaces.Box(-1.0, 1.0, (nd,), np.float32))
        self._u_law = None

    def _observe(self, obs, start):
        self._u_law = self.residual.law_command(obs, start)
        return self.residual.observe(obs, self._u_law)

    def reset(self):
        return self._observe(self.venv.reset(), np.ones(self.num_envs, dtype=bool))

    def step_async(self, actions):
        self.venv.step_async(self.residual.combine(self._u_law, actions))

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        u_last = self._u_law
        for i in np.flatnonzero(dones):
            # the value bootstrap of a truncated episode sees its last command (the law's memory of that episode
            # is not advanced past its end)
            infos[i]["terminal_observation"] = self.residual.observe(infos[i]["terminal_observation"], u_last[i])
        return self._observe(obs, np.asarray(dones, dtype=bool)), rewards, dones, infos


class PairedBaselineVecEnv(VecEnvWrapper):
    """Rewards r − r_ref, with r_ref the reward of the reference ``law`` (a name, with ``law_options``) on a twin
    of the environments that meets the same disturbances (see the module docstring). ``infos[i]["paired"]`` is
    False at a step whose reference could not be paired (the twin's episode ended before the agent's, e.g. at a
    stroke limit: the reward is then r, unpaired, until the agent's episode ends too)."""

    def __init__(self, venv, law: str = "skyhook_continuous", **law_options):
        super().__init__(venv)
        self._law, self._law_options = law, law_options
        self._native = _native(venv)
        Residual(self._native, law, **law_options)  # a law that does not apply fails now, not at reset
        self.twin = None

    def reset(self):
        obs = self.venv.reset()
        # the twin: a copy of the environments right after their reset (same state, same generators)
        self.twin = copy.deepcopy(self._native)
        self.twin_law = Residual(self.twin, self._law, **self._law_options)
        self._twin_obs = self.twin.core.obs.copy()
        self._twin_start = np.ones(self.num_envs, dtype=bool)
        self._waiting = np.zeros(self.num_envs, dtype=bool)  # twin ended first: unpaired until the agent's end
        self._rng_copy: dict[int, object] = {}
        return obs

    def step_async(self, actions):
        for b in np.flatnonzero(self._waiting):  # the generator as the agent's next episode will find it
            self._rng_copy[b] = copy.deepcopy(self._native._rngs[b])
        self.venv.step_async(actions)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        zero = np.zeros((self.num_envs, self.twin_law.n_dampers))
        u_ref = self.twin_law.actions(self._twin_obs, zero, self._twin_start)
        t_obs, r_ref, t_term, t_trunc, _ = self.twin.step(u_ref)
        t_done = t_term | t_trunc
        dones = np.asarray(dones, dtype=bool)
        paired = ~self._waiting & ~(t_done & ~dones)  # rows whose reference step met the same disturbance
        out = rewards - np.where(paired, r_ref, 0.0).astype(rewards.dtype)
        self._waiting |= t_done & ~dones
        # the agent's episode ended first: the twin starts the next one too, from the same generator
        early = dones & ~t_done & ~self._waiting
        realign = dones & self._waiting
        for b in np.flatnonzero(realign):
            self.twin._rngs[b] = self._rng_copy.pop(b)
        restart = early | realign
        if restart.any():
            t_obs = t_obs.copy()
            t_obs[restart] = self.twin.reset(options={"reset_mask": restart})[0][restart]
        self._waiting &= ~realign
        self._twin_obs, self._twin_start = t_obs, t_done | restart
        for i, info in enumerate(infos):
            info["paired"] = bool(paired[i])
        return obs, out, dones, infos
