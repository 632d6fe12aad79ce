"""The native vector environment: N environments of one assembly advanced in one compiled call.

Gymnasium 1.x conventions: ``reset(seed=s)`` seeds environment i with s + i (or a list of seeds), each
environment draws its own disturbance records and sensor noise from its own generator, so that environment i
equals a scalar environment reset with the same seed, bit for bit. Autoreset ``NEXT_STEP`` (Gymnasium's
default): the step after an episode ends resets that environment and returns its first observation with
reward 0 and both flags false; ``SAME_STEP`` (used by the Stable-Baselines3 bridge): the ending step already
returns the next episode's first observation and puts the last one in ``info["final_obs"]``.

``infos``: ``t`` (s) for every environment; ``episode_metrics`` and ``termination_reason`` (with their masks
``_episode_metrics``, ``_termination_reason``) for the environments whose episode ended at this step.
"""
from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..driver import BAD_ACTION, DIVERGED, HIST_NONE, RUNNING, TERMINATED, TRUNCATED
from .base import action_space, as_action
from .core import Assembly, EnvCore, PlantDeclarations


class MRDamperVectorEnv(PlantDeclarations, VectorEnv):
    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, assembly: Assembly, num_envs: int = 1, *, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("the vector environment does not render; render a scalar environment instead")
        mode = AutoresetMode(autoreset_mode)
        if mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode must be NEXT_STEP or SAME_STEP")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        self.assembly = asm = assembly
        self.num_envs = N = int(num_envs)
        self.render_mode = None
        self.core = core = EnvCore(asm, N, history=HIST_NONE)
        self.single_observation_space = _box(core.driver.n_obs)
        self.single_action_space = action_space(asm)
        self.observation_space = batch_space(self.single_observation_space, N)
        self.action_space = batch_space(self.single_action_space, N)
        self.nd = asm.coupled.system.nd
        self.sensors = asm.sensors.names
        self.sensor_layout = core.layout
        self.observation_labels = core.labels
        self._rngs: list = [None] * N
        self._status = core.driver.int_state("STATUS")
        self._reward = core.driver.state("REWARD")[:, 0]
        self._pending = np.zeros(N, dtype=bool)  # NEXT_STEP: episodes that ended and reset at the next step
        self._any_pending = False
        self._ashape = (N, self.nd)
        self._started = False

    def reset(self, *, seed=None, options=None):
        N = self.num_envs
        super().reset(seed=seed if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) else None)
        if seed is None:
            seeds = [None] * N
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(N)]
        else:
            seeds = list(seed)
            if len(seeds) != N:
                raise ValueError(f"seed must be None, an int or {N} seeds, got {len(seeds)}")
        self._rngs = [seeding.np_random(s)[0] for s in seeds]
        self.core.start(self._rngs)
        self._pending = np.zeros(N, dtype=bool)
        self._any_pending = False
        self._started = True
        return self.core.obs.copy(), {"t": np.zeros(N)}

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        core = self.core
        N = self.num_envs
        if type(actions) is np.ndarray and actions.dtype == np.float64 and actions.shape == self._ashape:
            a = actions.reshape(-1)
        else:
            a = as_action(actions, self.nd, N)
        restart = None
        if self._any_pending:  # NEXT_STEP: the environments that ended last step start again, and do not step
            restart = self._pending
            core.start(self._rngs, restart)
            self._status[restart] = TRUNCATED
        core.step(a)
        if restart is not None:
            self._status[restart] = RUNNING
        rewards = self._reward.copy()
        infos = {"t": core._k * self.assembly.control_dt}
        if not self._status.any():  # every environment running (RUNNING = 0): the common step
            obs = core.obs.copy()
            if restart is not None:
                rewards[restart] = 0.0
                self._pending = np.zeros(N, dtype=bool)
                self._any_pending = False
            return obs, rewards, np.zeros(N, dtype=bool), np.zeros(N, dtype=bool), infos
        return self._ended(restart, rewards, infos)

    def _ended(self, restart, rewards, infos):
        """The step at which some episodes ended (or an action was refused)."""
        core = self.core
        N = self.num_envs
        status = self._status.copy()
        ran = np.ones(N, dtype=bool) if restart is None else ~restart
        if np.any(status[ran] == BAD_ACTION):
            self._status[status == BAD_ACTION] = RUNNING
            raise ValueError("actions must be finite (no NaN or infinity)")
        if restart is not None:
            rewards[restart] = 0.0
        terminated = ran & ((status == TERMINATED) | (status == DIVERGED))
        truncated = ran & (status == TRUNCATED)
        ended = np.flatnonzero(terminated | truncated)
        if ended.size:
            self._end_infos(infos, ended, status, rewards)
        obs = core.obs.copy()
        done = terminated | truncated
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            if ended.size:
                final = np.full(N, None, dtype=object)
                for b in ended:
                    final[b] = obs[b].copy()
                infos["final_obs"], infos["_final_obs"] = final, done
                core.start(self._rngs, done)
                obs[done] = core.obs[done]
            self._pending = np.zeros(N, dtype=bool)
        else:
            self._pending = done
        self._any_pending = bool(self._pending.any())
        return obs, rewards, terminated, truncated, infos

    def _end_infos(self, infos: dict, ended: np.ndarray, status: np.ndarray, rewards: np.ndarray) -> None:
        core = self.core
        asm = self.assembly
        N = self.num_envs
        mask = np.zeros(N, dtype=bool)
        mask[ended] = True
        metrics: dict[str, np.ndarray] = {}
        reasons = np.full(N, None, dtype=object)
        for b in ended:
            if status[b] == DIVERGED:
                rewards[b] = -asm.limits.amount(core._n_steps[b] * asm.control_dt)
                reasons[b] = f"diverged: {core.failure_message(b)}"
            elif status[b] == TERMINATED:
                reasons[b] = "stroke_limit"
            for k, v in core.episode_metrics(b).items():
                metrics.setdefault(k, np.zeros(N))[b] = v
        infos["episode_metrics"] = metrics
        infos["_episode_metrics"] = mask
        term_mask = np.array([r is not None for r in reasons])
        if term_mask.any():
            infos["termination_reason"], infos["_termination_reason"] = reasons, term_mask

    def close_extras(self, **kwargs):
        pass


def asm_dt(env) -> float:
    return env.assembly.control_dt


def _box(n: int):
    import gymnasium as gym

    return gym.spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)
