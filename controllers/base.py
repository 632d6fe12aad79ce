"""One interface for every controller: classical semi-active laws and trained agents alike.

``predict(observation, state=None, episode_start=None, deterministic=True) -> (action, state)`` as in
Stable-Baselines3, for one observation (n_obs,) or a batch (N, n_obs) from a vector environment, plus
``reset()``. A controller is built from the environment it drives (scalar or vector) and takes its knowledge of
the plant from what the environment declares — the sensor layout, the command range, the action mode, the
control rate, the roles of its signals (``env.roles``: which sensor is the body velocity, the damper velocity,
...), its linear model and output maps (``env.linear_plant``, ``env.signal_matrices(name)``) and its default
control objective (``env.objective``) — never from names. A law that needs a signal the environment does not
measure raises ``ValueError`` naming the missing sensors.

Batches: every law keeps its memory (a Kalman filter's estimate, the last extremum of a stroke) per row, for
as many rows as the batch has; ``episode_start`` (a boolean per row, SB3's convention) or ``reset(mask)``
clears the rows of environments that start a new episode.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar, Sequence

import numpy as np

from mrd_env.envs.sensors import newest_layout


class Controller(ABC):
    """Base class. Subclasses set ``roles`` (the roles of the signals they read, see ``env.roles``) or
    ``requires`` (sensor names) and implement :meth:`command`."""

    name: ClassVar[str] = "controller"
    requires: ClassVar[tuple[str, ...]] = ()
    needs_roles: ClassVar[tuple[str, ...]] = ()
    #: True for a controller whose actions are the environment's own (an agent): it also drives an environment in
    #: ``action_mode="force"``; the laws output commands and refuse it.
    acts_in_env_space: ClassVar[bool] = False

    def __init__(self, env):
        base = getattr(env, "unwrapped", env)
        self.env = base
        self.layout = newest_layout(base)  # a law reads the newest measurement of a stacked history
        declared = dict(getattr(base, "roles", {}))
        missing_roles = [r for r in self.needs_roles if r not in declared]
        if missing_roles:
            raise ValueError(f"{type(self).__name__} needs signals with the role(s) {missing_roles}, which the "
                             f"{getattr(base, 'plant_kind', 'plant')!r} environment does not declare "
                             f"(its roles: {declared})")
        self.signals = {r: declared[r] for r in self.needs_roles}
        missing = [s for s in self.required_sensors() if s not in self.layout]
        if missing:
            raise ValueError(f"{type(self).__name__} needs the sensor(s) {missing}, but the environment measures "
                             f"{list(self.layout)}; create it with sensors=(..., {', '.join(map(repr, missing))})")
        spec = base.command_spec
        self.v_min, self.v_max = float(spec.v_min), float(spec.v_max)
        self.n_dampers = int(base.n_dampers)
        mode = getattr(base, "action_mode", "physical")
        self.force_mode = mode == "force"
        if self.force_mode and not self.acts_in_env_space:
            raise ValueError(f"{type(self).__name__} outputs commands; build the environment with action_mode "
                             "'physical' or 'normalized', not 'force' (a desired force is an agent's action, or "
                             "ClippedOptimal(inverse=...))")
        self.normalized = mode == "normalized"
        self.control_dt = float(base.control_dt)
        # the damper's static preload (e.g. the accumulator's k1·x0) is balanced by the plant's static
        # deflection: the laws act on the force beyond it, the one the linear plant model sees
        self.f_static = float(getattr(base, "F_static", 0.0))
        self._n_rows = 0

    def required_sensors(self) -> Sequence[str]:
        return tuple(self.requires) + tuple(self.signals.values())

    # -- the SB3-style interface -------------------------------------------------------------------
    def reset(self, mask=None) -> None:
        """Forget what was learnt from past observations (all rows, or the rows where ``mask`` is true)."""
        if self._n_rows:
            self.reset_rows(np.ones(self._n_rows, bool) if mask is None else np.asarray(mask, bool))

    def reset_rows(self, mask: np.ndarray) -> None:
        """Clear the memory of the rows in ``mask`` (laws with memory override; ``allocate`` sized it)."""

    def allocate(self, n_rows: int) -> None:
        """Size the memory for batches of ``n_rows`` (laws with memory override, then call this)."""
        self._n_rows = n_rows

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation, dtype=np.float64)  # float32 observations: laws compute in float64
        single = obs.ndim == 1
        O = obs[None] if single else obs
        if O.ndim != 2:
            raise ValueError(f"observation must be (n_obs,) or (N, n_obs), got shape {obs.shape}")
        if O.shape[0] != self._n_rows:
            self.allocate(O.shape[0])
            self.reset()
        if episode_start is not None:
            start = np.broadcast_to(np.asarray(episode_start, dtype=bool), (O.shape[0],))
            if start.any():
                self.reset_rows(start)
        u = np.broadcast_to(self.command(O), (O.shape[0], self.n_dampers))
        a = self._to_action(u)
        return (a[0] if single else a), state

    @abstractmethod
    def command(self, obs: np.ndarray) -> np.ndarray:
        """The physical command (V or A) for each row and damper, (N, nd) or broadcastable to it."""

    # -- helpers ------------------------------------------------------------------------------------
    def sensor(self, obs: np.ndarray, name: str) -> np.ndarray:
        """The channels of sensor ``name`` of a batch of observations, (N, width)."""
        return obs[:, self.layout[name]]

    def role(self, obs: np.ndarray, role: str) -> np.ndarray:
        """The signal playing ``role`` (see ``env.roles``), (N, width)."""
        return obs[:, self.layout[self.signals[role]]]

    def dynamic_force(self, obs: np.ndarray) -> np.ndarray:
        """Measured damper force minus its static preload (N, positive resisting extension), (N, nd)."""
        return obs[:, self.layout["damper_force"]] - self.f_static

    def _to_action(self, u) -> np.ndarray:
        """Physical commands → the env's actions (float32, clipped; mapped to [-1, 1] if normalised)."""
        a = np.clip(np.asarray(u, dtype=np.float64), self.v_min, self.v_max).astype(np.float32)
        if self.normalized:
            a = (a - np.float32(self.v_min)) * np.float32(2.0 / (self.v_max - self.v_min)) - np.float32(1.0)
        return a

    def on_off(self, condition) -> np.ndarray:
        """u_max where ``condition`` holds, else u_min (the on–off laws' common form)."""
        return self.v_min + (self.v_max - self.v_min) * np.asarray(condition, dtype=np.float64)


class PassiveOff(Controller):
    """Constant minimum command (the damper's passive-off state)."""

    name = "passive_off"

    def command(self, obs):
        return np.full((obs.shape[0], 1), self.v_min)


class PassiveOn(Controller):
    """Constant maximum command (passive-on)."""

    name = "passive_on"

    def command(self, obs):
        return np.full((obs.shape[0], 1), self.v_max)


class RandomCommand(Controller):
    """A command drawn uniformly in [u_min, u_max] every control step (the baseline any learnt or designed
    law must beat); ``seed`` or a ``numpy.random.Generator`` makes it reproducible."""

    name = "random"

    def __init__(self, env, seed=0):
        super().__init__(env)
        self.rng = np.random.default_rng(seed)

    def command(self, obs):
        return self.rng.uniform(self.v_min, self.v_max, size=(obs.shape[0], self.n_dampers))


class AgentController(Controller):
    """A trained agent (anything with SB3's ``predict``) behind the same interface; actions pass through
    unchanged because the agent acts in the environment's own action space. ``env_kwargs``: the options of
    the environment it was trained in (``gym.make(id, **agent.env_kwargs)`` rebuilds it)."""

    name = "agent"
    acts_in_env_space = True

    def __init__(self, env, model, name: str = "agent", env_kwargs: dict | None = None):
        super().__init__(env)
        self.model = model
        self.name = name
        self.env_kwargs = dict(env_kwargs or {})
        self._state = None
        self._starts = None  # rows reset(mask) cleared: SB3's episode_start at the next predict

    def command(self, obs):
        """The agent's actions as physical commands, or desired forces in force mode (predict() passes its actions
        through unchanged)."""
        a = np.asarray(self.model.predict(obs, deterministic=True)[0], dtype=np.float64)
        if self.force_mode:
            return a
        return self.v_min + (a + 1.0) * 0.5 * (self.v_max - self.v_min) if self.normalized else a

    def reset(self, mask=None) -> None:
        if mask is None:
            self._state, self._starts = None, None
            if hasattr(self.model, "reset"):
                self.model.reset(mask)
            return
        # the other rows keep their memory (a recurrent agent's state, a held correction); the masked ones
        # restart at the next predict, as with episode_start
        m = np.asarray(mask, dtype=bool)
        self._starts = m if self._starts is None else self._starts | m
        if self._state is None and hasattr(self.model, "reset"):
            self.model.reset(m)

    def episode_starts(self, episode_start):
        """``episode_start`` with the rows :meth:`reset` cleared since the last predict."""
        if self._starts is None:
            return episode_start
        out = self._starts if episode_start is None else np.asarray(episode_start, bool) | self._starts
        self._starts = None
        return out

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        action, self._state = self.model.predict(observation, state=state if state is not None else self._state,
                                                 episode_start=self.episode_starts(episode_start),
                                                 deterministic=deterministic)
        return action, self._state
