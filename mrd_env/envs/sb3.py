"""A Stable-Baselines3 ``VecEnv`` over the native vector environment (SB3 cannot take a Gymnasium vector
environment: SB3 issues #1568, #1608, #1745).

SB3's conventions: ``reset()`` returns the observations only (seeds from ``seed()``, applied at the next
reset); ``step_wait()`` returns (obs, rewards, dones, infos) with dones = terminated | truncated and the
environment already reset in the same step — its last observation in ``infos[i]["terminal_observation"]``,
``infos[i]["TimeLimit.truncated"]`` true when the episode was cut by time rather than ended by the plant, and
``infos[i]["episode_metrics"]``. The native environment runs in ``SAME_STEP`` autoreset mode for this.

>>> from mrd_env.envs.sb3 import make_sb3_vec_env
>>> venv = make_sb3_vec_env("mrd_env/QuarterCar-v0", n_envs=8, seed=0, control_dt=0.01)
"""
from __future__ import annotations

from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv


class SB3VecEnv(VecEnv):
    """SB3's VecEnv over a :class:`~mrd_env.envs.vector.MRDamperVectorEnv` built in SAME_STEP mode."""

    def __init__(self, venv):
        base = getattr(venv, "unwrapped", venv)
        if base.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
            raise ValueError("the vector environment must be built with autoreset_mode=SAME_STEP "
                             "(make_sb3_vec_env does it)")
        self.venv = base
        self.render_mode = None
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self._actions = None

    def reset(self):
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else [int(s) if s is not None else None for s in seeds]
        obs, _ = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            d = infos[i]
            d["terminal_observation"] = info["final_obs"][i]
            d["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            d["episode_metrics"] = {k: float(v[i]) for k, v in info["episode_metrics"].items()}
            if "termination_reason" in info and info["termination_reason"][i] is not None:
                d["termination_reason"] = info["termination_reason"][i]
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices

    def get_attr(self, attr_name: str, indices=None) -> list:
        return [getattr(self.venv, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * len(self._indices(indices))

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def get_images(self):
        return [None] * self.num_envs


def make_sb3_vec_env(env_id: str, n_envs: int = 1, seed: int | None = None, **env_kwargs) -> SB3VecEnv:
    """SB3's VecEnv over ``n_envs`` environments of ``env_id`` in one compiled call (env i seeded seed + i)."""
    import mrd_env  # noqa: F401  (registers the environments)

    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
    out = SB3VecEnv(venv)
    if seed is not None:
        out.seed(seed)
    return out
