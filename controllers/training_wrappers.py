"""Stable-Baselines3 ``VecEnvWrapper``\\ s for training agents on mrd-env (any SB3 or sb3-contrib algorithm).

Both wrap the SB3 bridge (:func:`mrd_env.envs.sb3.make_sb3_vec_env`) directly, below ``VecMonitor`` and
``VecNormalize``, because they read raw observations and rewards::

    venv = make_sb3_vec_env("mrd_env/QuarterCarPhysical-v0", n_envs=16, seed=0, action_mode="normalized", control_dt=0.01)
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
from .residual import Residual, check_hold


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
    (:meth:`~controllers.residual.Residual.observe`); it must wrap the bridge directly (it reads raw observations).

    ``hold = k``: one step of the agent is k steps of the environment, the correction held while the law's command
    follows every observation; the reward is their sum (the environment's rewards are integrals over their step, so
    the return is unchanged). A step ends early, for every environment, at the step where an episode ends, so that
    no environment steps into its next episode on a stale correction; ``infos[i]["held_steps"]`` says how many
    steps it took (:class:`PairedBaselineVecEnv` steps its twin as many)."""

    def __init__(self, venv, law: str | Controller, scale: float = 1.0, hold: int = 1, **law_options):
        self.hold = check_hold(hold)
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
        self._actions = actions
        self.venv.step_async(self.residual.combine(self._u_law, actions))

    def step_wait(self):
        total = 0.0
        for j in range(self.hold):
            obs, rewards, dones, infos = self.venv.step_wait()
            total = total + np.asarray(rewards, dtype=np.float64)  # summed as the twin's are
            if np.any(dones) or j == self.hold - 1:
                break
            # the law follows the observation; the correction is held
            self._u_law = self.residual.law_command(obs, None)
            self.venv.step_async(self.residual.combine(self._u_law, self._actions))
        u_last = self._u_law
        for i in np.flatnonzero(dones):
            # the value bootstrap of a truncated episode sees its last command (the law's memory of that episode
            # is not advanced past its end)
            infos[i]["terminal_observation"] = self.residual.observe(infos[i]["terminal_observation"], u_last[i])
        if self.hold > 1:
            for info in infos:
                info["held_steps"] = j + 1
        return self._observe(obs, np.asarray(dones, dtype=bool)), np.asarray(total, dtype=rewards.dtype), dones, infos


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
        return obs

    def step_async(self, actions):
        # the generators as the agents' next episodes will find them (they change only when an episode starts)
        self._rng_states = [g.bit_generator.state for g in self._native._rngs]
        self.venv.step_async(actions)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        n = int(infos[0].get("held_steps", 1)) if len(infos) else 1  # the agent's step: n of the environment's
        N = self.num_envs
        zero = np.zeros((N, self.twin_law.n_dampers))
        r_ref = np.zeros(N)
        ended_at = np.full(N, -1)  # the twin's step (0 … n − 1) at which its episode ended
        t_obs, start = self._twin_obs, self._twin_start
        for j in range(n):
            t_obs, r, t_term, t_trunc, _ = self.twin.step(self.twin_law.actions(t_obs, zero, start))
            live = ended_at < 0
            r_ref += np.where(live, r.astype(np.float32), 0.0)  # rounded as the bridge rounds the agent's
            start = t_term | t_trunc
            ended_at[start & live] = j
        dones = np.asarray(dones, dtype=bool)
        # the twin's episode ended before the agent's (an agent's episode ends at the step's last physics step)
        first = (ended_at >= 0) & ~(dones & (ended_at == n - 1))
        paired = ~self._waiting & ~first  # rows whose reference met the same disturbance over the same steps
        out = rewards - np.where(paired, r_ref, 0.0).astype(rewards.dtype)
        # both ended at the same physics step: the twin has already drawn the agent's next episode
        together = dones & ~self._waiting & (ended_at == n - 1)
        restart = dones & ~together  # the twin starts the agent's next episode, from the agent's generator
        self._waiting = (self._waiting | first) & ~dones
        if restart.any():
            for b in np.flatnonzero(restart):
                self.twin._rngs[b].bit_generator.state = self._rng_states[b]
            t_obs = t_obs.copy()
            t_obs[restart] = self.twin.reset(options={"reset_mask": restart})[0][restart]
        self._twin_obs, self._twin_start = t_obs, start | restart
        for i, info in enumerate(infos):
            info["paired"] = bool(paired[i])
        return obs, out, dones, infos
