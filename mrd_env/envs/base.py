"""The scalar MR-damper environment: an :class:`~.core.Assembly` of parts stepped by the compiled core.

A plant's module builds the assembly from the user's options and the class is a thin subclass (see
:class:`~.quarter_car.QuarterCarEnv`); everything below is shared.
"""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from ..driver import BAD_ACTION, DIVERGED, HIST_FULL, RUNNING, TERMINATED
from .core import Assembly, EnvCore, PlantDeclarations


def action_space(asm: Assembly) -> gym.spaces.Box:
    """One command per damper: [v_min, v_max] (V or A) in the physical mode, [−1, 1] in the normalised one."""
    nd = asm.coupled.system.nd
    cs = asm.damper.command
    if asm.action_mode == "physical":
        return gym.spaces.Box(float(cs.v_min), float(cs.v_max), shape=(nd,), dtype=np.float32)
    return gym.spaces.Box(-1.0, 1.0, shape=(nd,), dtype=np.float32)


def as_action(action, nd: int, N: int | None = None) -> np.ndarray:
    """``action`` (one environment's, or N environments' when ``N`` is given) as a float64 array of commands,
    else ``ValueError`` (shape, type)."""
    try:
        raw = np.asarray(action)
    except ValueError:  # a ragged sequence
        raise ValueError(f"action must be numeric with shape {(N, nd) if N else (nd,)}, got the ragged "
                         f"{action!r}") from None
    if raw.dtype.kind not in "fiu":  # complex, bool, strings, objects: not a command
        raise ValueError(f"action must be numeric (real numbers) with shape {(N, nd) if N else (nd,)}, "
                         f"got dtype {raw.dtype}")
    a = raw.astype(np.float64)
    if N is None:
        if nd == 1 and a.ndim == 0:
            a = a.reshape(1)
        if a.shape != (nd,):
            raise ValueError(f"action must have shape ({nd},) (one command per damper"
                             f"{'; a scalar is also accepted' if nd == 1 else ''}), got shape {a.shape}")
    elif a.shape != (N, nd) and not (nd == 1 and a.shape == (N,)):
        raise ValueError(f"actions must have shape ({N}, {nd}), got {a.shape}")
    return np.ascontiguousarray(a.reshape(-1))


class MRDamperEnv(PlantDeclarations, gym.Env):
    """An MR-damper environment (see the plant's class docstring for its specification).

    Actions: one command per damper, shape ``(nd,)`` (a scalar is accepted when nd = 1), clipped to the Box
    (``np.clip`` semantics, then mapped onto [v_min, v_max] in normalised mode); the command is held over the
    control period and reaches the damper through its lag u̇ = −η (u − v). A wrongly shaped, non-numeric or
    non-finite action raises ``ValueError``.

    Observations: float32, the chosen sensors in order (``sensor_layout`` lists ``(name, slice, unit)``;
    ``observation_labels`` names every entry), with noise, delay and history as configured.

    Episode end: ``terminated`` when a limit is exceeded (``info["termination_reason"] = "stroke_limit"``) or
    the simulation diverges (``"diverged: <message>"``, the last observation returned); ``truncated`` at the end
    of the episode. The last step's info holds ``episode_metrics``. Every step's info has ``t`` (s);
    ``damper_force`` and ``command`` (the last step's, (nd,)) are attributes of the environment.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 30}

    def __init__(self, assembly: Assembly, render_mode: str | None = None):
        super().__init__()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        self.render_mode = render_mode
        self.assembly = asm = assembly
        self.core = core = EnvCore(asm, 1, history=HIST_FULL)
        self.episode_seconds = asm.episode_seconds
        self.sensors = asm.sensors.names
        self.sensor_layout = core.layout
        self.observation_labels = core.labels
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(core.driver.n_obs,), dtype=np.float32)
        self.action_space = action_space(asm)
        self.record = None
        self._done = True
        self._renderer = None
        self._last_frame_t = -math.inf
        self._ashape = (self.n_dampers,)
        self._obs0 = core.obs[0]
        self._reward0 = core.driver.state("REWARD")[0]
        self._force0 = core.driver.state("F")[0]
        self._cmd0 = core.driver.state("CMD")[0]

    # --- Gymnasium API -----------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        core = self.core
        core.start([self.np_random])
        self.record = core.episodes[0].record
        self._done = False
        self._t = 0.0
        self._bind()
        self._last_frame_t = -math.inf
        if self.render_mode == "human":
            self._render_human()
        return self._obs0.copy(), {"t": 0.0, "disturbance": self.record.name}

    def _bind(self) -> None:
        """The arrays of the compiled step (W and H may have been reallocated by a new episode)."""
        d = self.core.driver
        self._args = (d.fc, d.ic, d.fs, d.is_, d.W, d.H)
        self._kstep = d.kernel.core_step

    def step(self, action):
        if self._done:
            raise RuntimeError("the episode is over (or reset() was never called): call reset() first")
        if type(action) is np.ndarray and action.dtype == np.float64 and action.shape == self._ashape:
            a = action
        else:
            a = as_action(action, self.n_dampers)
        status = self._kstep(*self._args, a, self.core.obs)
        obs = self._obs0.copy()
        reward = float(self._reward0[0])
        if self.core.python_reward and status != DIVERGED and status != BAD_ACTION:
            reward += self.assembly.reward(self.core.period(0))
        self._t += self.control_dt
        if status == RUNNING:
            if self.render_mode == "human" and self._t - self._last_frame_t >= 1.0 / self.metadata["render_fps"]:
                self._render_human()
            return obs, reward, False, False, {"t": self._t}
        return self._end(status, obs, reward)

    def _end(self, status: int, obs, reward):
        core = self.core
        if status == BAD_ACTION:
            self._t -= self.control_dt
            core.driver.int_state("STATUS")[0] = RUNNING
            raise ValueError("action must be finite (no NaN or infinity)")
        self._done = True
        info = {"t": self._t}
        if status == DIVERGED:
            asm = self.assembly
            reward = -asm.limits.amount(core._n_steps[0] * asm.control_dt)
            info["t"] = core.time(0)
            info["termination_reason"] = f"diverged: {core.failure_message(0)}"
        elif status == TERMINATED:
            info["termination_reason"] = "stroke_limit"
        info["episode_metrics"] = core.episode_metrics(0)
        terminated = status in (TERMINATED, DIVERGED)
        if self.render_mode == "human":
            self._render_human()
        return obs, reward, terminated, not terminated, info

    # --- what the environment exposes ---------------------------------------------------------------------------
    @property
    def damper_force(self) -> np.ndarray:
        """The damper forces at the end of the last step ((nd,), N; the measured force, preload included)."""
        return self._force0.copy()

    @property
    def plant_state(self) -> np.ndarray:
        """The plant's coordinates and velocities [q, q̇] now (a copy; ``linear_plant`` coordinates)."""
        return self.core.driver.state("Y")[0, :2 * self.linear_plant.n_dof].copy()

    @property
    def command(self) -> np.ndarray:
        """The command applied over the last step ((nd,), V or A)."""
        return self._cmd0.copy()

    def signal(self, name: str) -> np.ndarray:
        """History of a named signal over the episode so far, (rows, width) at ``dt`` from t = 0 (a copy)."""
        sig = self.assembly.signals[name]
        rows = int(self.core.driver.int_state("ROWS")[0])
        return self.core.driver.H[0, :rows][:, sig.columns]

    # --- rendering ---------------------------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.record is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode == "rgb_array":
            if self._renderer is None:
                self._renderer = self.assembly.renderer(self, human=False)
            return self._renderer.frame()
        self._render_human()
        return None

    def _render_human(self) -> None:
        if self._renderer is None:
            self._renderer = self.assembly.renderer(self, human=True)
        self._renderer.show()
        self._last_frame_t = self._t

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
