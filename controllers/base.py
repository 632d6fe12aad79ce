"""One interface for every controller: classical semi-active laws and trained agents alike.

``predict(observation, state=None, episode_start=None, deterministic=True) -> (action, state)`` as in
Stable-Baselines3, plus ``reset()`` at the start of an episode. A controller is built from the
environment it will drive: it reads the sensor layout, the command range, the action mode, the control
rate and (for model-based laws) the plant's linear model from ``env.unwrapped``, and uses only what the
observation exposes. A law that needs a signal the environment does not measure raises ``ValueError``
naming the missing sensors and how to ask for them.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar, Sequence

import numpy as np


class Controller(ABC):
    """Base class. Subclasses set ``requires`` (sensor names) and implement :meth:`command`."""

    name: ClassVar[str] = "controller"
    requires: ClassVar[tuple[str, ...]] = ()

    def __init__(self, env):
        base = getattr(env, "unwrapped", env)
        self.env = base
        self.layout = {name: sl for name, sl, *_ in base.sensor_layout}
        missing = [s for s in self.required_sensors(base) if s not in self.layout]
        if missing:
            raise ValueError(f"{type(self).__name__} needs the sensor(s) {missing}, but the environment measures "
                             f"{list(self.layout)}; create it with sensors=(..., {', '.join(map(repr, missing))})")
        spec = base.command_spec
        self.v_min, self.v_max = float(spec.v_min), float(spec.v_max)
        self.n_dampers = int(base.action_space.shape[0])
        self.normalized = getattr(base, "action_mode", "physical") == "normalized"
        self.control_dt = float(base.control_dt)
        # the damper's static preload (e.g. the accumulator's k1·x0) is balanced by the plant's static
        # deflection: the laws act on the force beyond it, the one the linear plant model sees
        self.f_static = float(getattr(base, "F_static", 0.0))

    def required_sensors(self, env) -> Sequence[str]:
        return self.requires

    # -- the SB3-style interface -------------------------------------------------------------------
    def reset(self) -> None:
        """Forget everything learnt from past observations (filter states, extrema)."""

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation, dtype=np.float64)  # float32 observations: laws compute in float64
        if obs.ndim == 2:  # a batch (vectorised envs): one controller instance per row is the user's job
            if obs.shape[0] != 1:
                raise ValueError("a classical controller drives one environment: pass one observation "
                                 "(make one controller per sub-environment)")
            return self.predict(obs[0], state, episode_start, deterministic)[0][None], state
        return self._to_action(self.command(obs)), state

    @abstractmethod
    def command(self, obs: np.ndarray) -> np.ndarray:
        """The physical command (V or A) for each damper."""

    # -- helpers ------------------------------------------------------------------------------------
    def sensor(self, obs: np.ndarray, name: str) -> np.ndarray:
        return obs[self.layout[name]]

    def dynamic_force(self, obs: np.ndarray) -> np.ndarray:
        """Measured damper force minus its static preload (N, positive resisting extension)."""
        return obs[self.layout["damper_force"]] - self.f_static

    def _to_action(self, u) -> np.ndarray:
        """Physical command(s) → the env's action (float32, clipped; mapped to [-1, 1] if normalised)."""
        a = np.empty(self.n_dampers, dtype=np.float32)
        a[:] = u  # a scalar or one value per damper
        np.minimum(np.maximum(a, self.v_min, out=a), self.v_max, out=a)
        if self.normalized:
            a -= self.v_min
            a *= 2.0 / (self.v_max - self.v_min)
            a -= 1.0
        return a

    def on_off(self, condition) -> np.ndarray:
        """u_max where ``condition`` holds, else u_min (the on–off laws' common form)."""
        return self.v_min + (self.v_max - self.v_min) * np.asarray(condition, dtype=np.float64)


class PassiveOff(Controller):
    """Constant minimum command (the damper's passive-off state)."""

    name = "passive_off"

    def command(self, obs):
        return self.v_min


class PassiveOn(Controller):
    """Constant maximum command (passive-on)."""

    name = "passive_on"

    def command(self, obs):
        return self.v_max


class AgentController(Controller):
    """A trained agent (anything with SB3's ``predict``) behind the same interface; actions pass through
    unchanged because the agent was trained on the environment's own action space."""

    name = "agent"

    def __init__(self, env, model, name: str = "agent"):
        super().__init__(env)
        self.model = model
        self.name = name
        self._state = None

    def command(self, obs):  # the agent acts in the env's own action space: see predict
        return self.model.predict(obs, deterministic=True)[0]

    def reset(self) -> None:
        self._state = None

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        action, self._state = self.model.predict(observation, state=state if state is not None else self._state,
                                                 episode_start=episode_start, deterministic=deterministic)
        return action, self._state
