"""A Stable-Baselines3 ``VecEnv`` over the native vector environment (SB3 cannot take a Gymnasium vector
environment: SB3 issues #1568, #1608, #1745).

SB3's conventions, as ``DummyVecEnv`` over the scalar environments gives them (a test checks it step by step):
``reset()`` returns the observations only (seeds from ``seed()``, applied at the next reset; the reset infos in
``reset_infos``); ``step_wait()`` returns (obs, rewards, dones, infos) with dones = terminated | truncated, every
``infos[i]`` the environment's step info (``t``, the constraint ``cost`` and ``cost_terms``) with
``TimeLimit.truncated``, and the environment already reset in the same
step where an episode ended — then ``infos[i]`` is its last step's info (``episode_metrics``, a
``termination_reason``) with its last observation in ``terminal_observation``, ``TimeLimit.truncated`` true when
the episode was cut by time rather than ended by the plant, and ``episode`` (return, length, time: what SB3's
Monitor writes), and ``reset_infos[i]`` the new episode's. The native environment runs in ``SAME_STEP`` autoreset
mode for this.

>>> from mrd_env.envs.sb3 import make_sb3_vec_env
>>> venv = make_sb3_vec_env("mrd_env/QuarterCarPhysical-v0", n_envs=8, seed=0, control_dt=0.01)
"""
from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from .entry import warn_torch_threads
from .vector import env_info


class SB3VecEnv(VecEnv):
    """SB3's VecEnv over a :class:`~mrd_env.envs.vector.MRDamperVectorEnv` built in SAME_STEP mode.

    Each ending step's ``infos[i]["episode"]`` = {"r": return, "l": length, "t": seconds since the start}, as
    SB3's ``Monitor`` writes it, so that SB3 logs ``ep_rew_mean`` and ``ep_len_mean`` without a ``VecMonitor``
    (wrapping one around it is harmless: it writes the same). The N environments are one object: ``get_attr``
    reads the shared attribute, ``set_attr`` and ``env_method`` apply to all of them (``indices`` None or every
    index; a subset raises ``ValueError``)."""

    def __init__(self, venv):
        base = getattr(venv, "unwrapped", venv)
        if base.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
            raise ValueError("the vector environment must be built with autoreset_mode=SAME_STEP "
                             "(make_sb3_vec_env does it)")
        self.venv = base
        self.render_mode = base.render_mode
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self._actions = None
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._t0 = time.time()

    def reset(self):
        if any(self._options):  # set_options: these environments take no reset options (refused, as they do)
            raise ValueError(f"reset options {self._options} are not known: these environments take none")
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else [int(s) if s is not None else None for s in seeds]
        obs, info = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [env_info(info, i) for i in range(self.num_envs)]
        self._returns[:] = 0.0
        self._lengths[:] = 0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        rewards = rewards.astype(np.float32)
        self._returns += rewards
        self._lengths += 1
        dones = terminated | truncated
        # as DummyVecEnv gives them: each environment's step info with TimeLimit.truncated; where an episode ended,
        # its last step's info with the last observation, and the new episode's reset info in reset_infos
        t, cost, terms = info["t"].tolist(), info["cost"].tolist(), info["cost_terms"]
        names = [k for k in terms if not k.startswith("_")]
        per_term = [terms[k].tolist() for k in names]
        infos: list[dict[str, Any]] = [{"t": t[i], "cost": cost[i],
                                        "cost_terms": {k: v[i] for k, v in zip(names, per_term)},
                                        "TimeLimit.truncated": False} for i in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            d = infos[i] = env_info(info["final_info"], i)
            d["terminal_observation"] = info["final_obs"][i]
            d["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            d["episode"] = {"r": float(self._returns[i]), "l": int(self._lengths[i]),
                            "t": round(time.time() - self._t0, 6)}
            self.reset_infos[i] = {k: v for k, v in env_info(info, i).items()
                                   if k not in ("final_obs", "final_info")}
            self._returns[i], self._lengths[i] = 0.0, 0
        return obs, rewards, dones, infos

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        idx = [indices] if isinstance(indices, (int, np.integer)) else list(indices)
        if not all(isinstance(i, (int, np.integer)) and 0 <= i < self.num_envs for i in idx):
            raise ValueError(f"indices must be None or environment indices in [0, {self.num_envs}), got {indices!r}")
        return idx

    def _all(self, indices, what: str) -> list[int]:
        idx = self._indices(indices)
        if sorted(set(idx)) != list(range(self.num_envs)):
            raise ValueError(f"{what}: the {self.num_envs} environments are one native vector environment whose "
                             f"attributes they share; indices must be None or all of 0..{self.num_envs - 1}, "
                             f"got {indices!r}")
        return idx

    def get_attr(self, attr_name: str, indices=None) -> list:
        return [getattr(self.venv, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        self._all(indices, "set_attr")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        idx = self._all(indices, "env_method")
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * len(idx)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def get_images(self):
        if self.render_mode != "rgb_array":
            return [None] * self.num_envs
        return list(self.venv.render())


def make_sb3_vec_env(env_id: str, n_envs: int = 1, seed: int | None = None, **env_kwargs) -> SB3VecEnv:
    """SB3's VecEnv over ``n_envs`` environments of ``env_id`` in one compiled call (env i seeded seed + i)."""
    import mrd_env  # noqa: F401  (registers the environments)

    warn_torch_threads()  # SB3 has imported torch: its threads against these environments' (once per process)
    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
    out = SB3VecEnv(venv)
    if seed is not None:
        out.seed(seed)
    return out
