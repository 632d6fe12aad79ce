"""The scalar MR-damper environment: an :class:`~.core.Assembly` of parts stepped by the compiled core.

A plant's module builds the assembly from the user's options and the class is a thin subclass (see
:class:`~.quarter_car.QuarterCarEnv`); everything below is shared.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import gymnasium as gym
import numpy as np

from ..stepping import BAD_ACTION, DIVERGED, HIST_FULL, RUNNING, TERMINATED
from .core import Assembly, EnvCore, PlantDeclarations, assemble
from .render import HUMAN_FPS
from .termination import non_finite_reason

#: The step's status when the kernel ran but an observation or the reward is NaN or infinite (not a kernel code).
_NON_FINITE = -1


def action_space(asm: Assembly) -> gym.spaces.Box:
    """One command per damper: [v_min, v_max] (V or A) in the physical mode, [−1, 1] in the normalised one; one
    desired force (N) per damper in [−force_range, force_range] in the force mode."""
    nd = asm.coupled.system.nd
    cs = asm.damper.command
    if asm.action_mode == "physical":
        return gym.spaces.Box(float(cs.v_min), float(cs.v_max), shape=(nd,), dtype=np.float32)
    if asm.action_mode == "force":
        return gym.spaces.Box(-asm.force_range, asm.force_range, shape=(nd,), dtype=np.float32)
    return gym.spaces.Box(-1.0, 1.0, shape=(nd,), dtype=np.float32)


def force_actuation(env):
    """The :class:`~.actuation.ForceActuation` of an environment in ``action_mode="force"`` (None otherwise)."""
    if env.assembly.action_mode != "force":
        return None
    from .actuation import ForceActuation

    return ForceActuation(env, env.assembly.inverse)


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


def render_fps(control_dt: float) -> float:
    """Frames per second of simulated time: one frame per control step, so that a video plays in real time."""
    fps = round(1.0 / control_dt, 9)
    return int(fps) if fps == int(fps) else fps


class MRDamperEnv(PlantDeclarations, gym.Env):
    """An MR-damper environment (see the plant's class docstring for its specification).

    Actions: one command per damper, shape ``(nd,)`` (a scalar is accepted when nd = 1), clipped to the Box
    (``np.clip`` semantics, then mapped onto [v_min, v_max] in normalised mode); the command is held over the
    control period and reaches the damper through its lag u̇ = −η (u − v). In force mode the action is the
    desired damper force beyond the static preload (N), clipped to the Box and turned into the command by the
    inverse model (``actuation``, reset with every episode). A wrongly shaped, non-numeric or non-finite action
    raises ``ValueError`` and changes nothing.

    Observations: float32, the chosen sensors in order (``sensor_layout`` lists ``(name, slice, unit)``;
    ``observation_labels`` names every entry), with noise, delay and history as configured.

    Episode end: ``terminated`` when a limit is exceeded (``info["termination_reason"] = "stroke_limit"``) or
    the simulation diverges (``"diverged: <message>"``, the last observation returned); ``truncated`` at the end
    of the episode, after ``max_episode_steps`` steps (the environment truncates itself; ``gym.make`` wraps it in
    a TimeLimit at that length, which states it in ``env.spec.max_episode_steps`` and changes no step: see
    :mod:`mrd_env.envs.entry`). The last step's info holds ``episode_metrics``. Every step's info has ``t`` (s),
    ``cost`` (s ≥ 0: the time during the step's control period at which a constraint of the plant is violated,
    counted on the physics rows; :mod:`mrd_env.envs.costs`) and ``cost_terms`` ({constraint: s}); reset's has
    ``disturbance`` (the record's name) and a zero ``cost`` and ``cost_terms``; ``episode_metrics`` ends with the
    costs' totals ``cost`` and ``cost_<constraint>`` (s). ``damper_force`` and ``command`` (the last step's, (nd,))
    are attributes of the environment.

    Rendering: ``render_mode="rgb_array"`` (a frame of the plant) or ``"human"`` (a window); ``render_fps`` in
    ``metadata`` is 1/control_dt, so that a video of one frame per step plays in simulated time.

    Copies (``pickle``, ``copy.deepcopy``, cloudpickle) step exactly as the original from where it was copied.

    Options: the plant's (see its class); an unknown option raises ``ValueError`` listing the valid ones. A plant's
    class sets ``env_id`` and ``build`` (its assembly from the options).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 1000}  # per instance: 1/control_dt
    env_id = ""
    build: Callable[..., Assembly] | None = None

    def __init__(self, *, render_mode: str | None = None, assembly: Assembly | None = None, **options):
        super().__init__()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        if assembly is None:
            assembly = assemble(type(self), options, own=("render_mode",))
        elif options:
            raise ValueError(f"options {sorted(options)} apply when the environment builds its assembly, not beside "
                             f"an assembly")
        self.render_mode = render_mode
        self.assembly = asm = assembly
        self.metadata = {**type(self).metadata, "render_fps": render_fps(asm.control_dt)}
        self.core = core = EnvCore(asm, 1, history=HIST_FULL)
        self.episode_seconds = asm.episode_seconds
        self.sensors = asm.sensors.names
        self.sensor_layout = core.layout
        self.observation_labels = core.labels
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(core.driver.n_obs,), dtype=np.float32)
        self.action_space = action_space(asm)
        self.actuation = force_actuation(self)
        self.record = None
        self._done = True
        self._renderer = None
        self._last_frame_t = -math.inf
        self._ashape = (self.n_dampers,)
        self._control_dt = asm.control_dt
        self._bind()

    def _bind(self) -> None:
        """Views of the driver's arrays the step reads (W and H may have been reallocated by a new episode; a copy
        of the environment makes views separate arrays, so it binds them again)."""
        d = self.core.driver
        self._args = (d.fc, d.ic, d.fs, d.is_, d.W, d.H)
        self._kstep = d.kernel.run_systems
        self._systems = (d.N, 0, d.N)  # the serial call over the one system
        self._obs0 = self.core.obs[0]
        self._reward0 = d.state("REWARD")[0]
        self._force0 = d.state("F")[0]
        self._cmd0 = d.state("CMD")[0]
        self._k0 = d.int_state("K")
        # the last step's costs [any, term 1..T] (a memoryview: a float read costs half of numpy's .item)
        self._cost0 = memoryview(d.state("COST")[0, :self.core.n_cost_terms + 1])
        self._cost_names = self.core.cost_names
        self._no_cost = dict.fromkeys(self._cost_names, 0.0)

    _DERIVED = ("_args", "_kstep", "_obs0", "_reward0", "_force0", "_cmd0", "_k0", "_cost0", "_cost_names", "_no_cost",
                "_renderer")

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in self._DERIVED}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._renderer = None  # a figure is not copied: the copy draws its own
        self._bind()

    # --- Gymnasium API -----------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options:  # none are known (a vector env's reset_mask is the vector env's): refused before any change
            raise ValueError(f"reset options {sorted(options)} are not known: these environments take none")
        super().reset(seed=seed)
        core = self.core
        core.start([self.np_random])
        self.record = core.episodes[0].record
        if self.actuation is not None:
            self.actuation.reset()
        self._done = False
        self._bind()
        self._last_frame_t = -math.inf
        if self.render_mode == "human":
            self._render_human()
        return self._obs0.copy(), {"t": 0.0, "disturbance": self.record.name, **core.zero_cost_info()}

    def step(self, action):
        if self._done:
            raise RuntimeError("the episode is over (or reset() was never called): call reset() first")
        if type(action) is np.ndarray and action.dtype == np.float64 and action.shape == self._ashape:
            a = action
        else:
            a = as_action(action, self.n_dampers)
        if self.actuation is not None:  # force mode: the desired forces (checked there) through the inverse
            a = self.actuation.step_commands(a, self._obs0, self.assembly.force_range)
        status = self._kstep(*self._args, a, self.core.obs, *self._systems)
        if status == BAD_ACTION:  # refused by the kernel before it wrote anything
            self.core.driver.int_state("STATUS")[0] = RUNNING
            raise ValueError("action must be finite (no NaN or infinity)" if self.actuation is None
                             else "the inverse model returned a non-finite command")
        obs = self._obs0.copy()
        reward = float(self._reward0[0])
        if self.core.python_reward and status != DIVERGED:
            reward += self.assembly.reward(self.core.period(0))
        t = self._k0.item(0) * self._control_dt  # as the vector env's k·control_dt, bit for bit
        cost = self._cost0[0]  # no constraint violated (the common step): every term's cost is 0 too
        info = {"t": t, "cost": cost, "cost_terms": self._no_cost.copy() if cost == 0.0 else
                dict(zip(self._cost_names, self._cost0.tolist()[1:]))}
        # a sum of Python floats is not finite iff a value is not (float64: float32 values cannot overflow it); 6x
        # cheaper than np.isfinite(obs).all() on the 1 kHz scalar step
        if status != DIVERGED and not (math.isfinite(reward) and math.isfinite(sum(obs.ravel().tolist()))):
            status = _NON_FINITE  # never handed on as a step that went well
        if status == RUNNING:
            if self.render_mode == "human" and t - self._last_frame_t >= 1.0 / HUMAN_FPS:
                self._render_human()
            return obs, reward, False, False, info
        return self._end(status, obs, reward, info)

    def _end(self, status: int, obs, reward, info: dict):
        core = self.core
        self._done = True
        if status == DIVERGED:
            asm = self.assembly
            reward = -asm.limits.amount(core._n_steps[0] * asm.control_dt)
            info["termination_reason"] = f"diverged: {core.failure_message(0)}"
        elif status == _NON_FINITE:
            asm = self.assembly
            reward = -asm.limits.amount(core._n_steps[0] * asm.control_dt)
            info["termination_reason"] = non_finite_reason(info["t"])
        elif status == TERMINATED:
            info["termination_reason"] = "stroke_limit"
        info["episode_metrics"] = core.episode_metrics(0)
        terminated = status in (TERMINATED, DIVERGED, _NON_FINITE)
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

    @property
    def episode(self):
        """The current episode (:class:`~.core.Episode`: its record, initial state and the plant's extras)."""
        return self.core.episodes[0]

    def signal(self, name: str) -> np.ndarray:
        """History of a named signal over the episode so far, (rows, width) at ``dt`` from t = 0 (a copy)."""
        return self.core.signal(name, 0)

    @property
    def title(self) -> str:
        return type(self).__name__

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
        self._last_frame_t = self.core.time(0)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
