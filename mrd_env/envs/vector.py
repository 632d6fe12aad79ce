"""The native vector environment: N environments of one assembly advanced in one compiled call.

Gymnasium 1.x conventions, those of ``SyncVectorEnv`` over the scalar environments (a test checks that the two
agree, infos included): ``reset(seed=s)`` seeds environment i with s + i (or a list of seeds; ``None`` keeps
each environment's generator), each environment draws its own disturbance records and sensor noise from its own
generator, so that environment i equals a scalar environment reset with the same seed, bit for bit.
``reset(options={"reset_mask": mask})`` resets only the environments where ``mask`` (bool (N,)) is true.

Autoreset (``autoreset_mode``): ``NEXT_STEP`` (Gymnasium's default): the step after an episode ends resets that
environment and returns its first observation with reward 0 and both flags false; ``SAME_STEP`` (used by the
Stable-Baselines3 bridge): the ending step already returns the next episode's first observation, with the last
one in ``info["final_obs"]`` and the ending step's info in ``info["final_info"]``; ``DISABLED``: an environment
whose episode ended waits for ``reset(options={"reset_mask": ...})``.

``infos`` are batched as Gymnasium batches the scalar environments' infos: every key has its mask ``_key``
(nested dicts too). ``t`` (s) and the constraint costs ``cost`` (N,) and ``cost_terms`` {constraint: (N,)} (s in
violation over the last step, :mod:`.costs`; 0 for an environment that (re)started, as its reset info says) for
every environment, every step; ``disturbance`` (the record's name) for those that (re)start; ``episode_metrics``
and ``termination_reason`` for those whose episode ended (in ``final_info`` in SAME_STEP mode, with that step's
costs). :func:`env_info` takes environment i's info out of a batch.

A batch of actions is checked whole before any environment steps: a refused call changes nothing.

Threads (``threads``): an int fixes the count. The default (``None``) is one thread below 64 environments and,
from 64 (with more than one numba thread), a :class:`ThreadTuner`: it steps on one thread, tries every numba
thread for about 0.25 s of steps every 10 s (sooner when the chosen count slows down) and keeps the faster
(threads only when they save 10 %), so that a process that starts or stops beside it (a test suite, a second
training) moves it within seconds. On an idle machine threads pay; on a shared one numba's default OpenMP layer
spins in its waits and one thread is faster (issue 36, docs/speed.md). The results do not depend on the count,
bit for bit.
"""
from __future__ import annotations

import math

import time
from collections.abc import Callable

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..stepping import BAD_ACTION, DIVERGED, HIST_FULL, HIST_NONE, RUNNING, TERMINATED, TRUNCATED
from ..stepping.driver import PARALLEL_FROM
from .base import action_space, as_action, force_actuation, render_fps
from .core import Assembly, EnvCore, PlantDeclarations, assemble
from .termination import non_finite_reason


def reset_mask(options, num_envs: int, started: bool) -> np.ndarray:
    """The environments a vector reset starts again: all, or ``options["reset_mask"]`` (a numpy bool array of shape
    (num_envs,), selecting one or more; every one at the first reset), else ``ValueError`` naming the option."""
    unknown = sorted(set(options or {}) - {"reset_mask"})
    if unknown:  # a misspelt mask would otherwise reset every environment
        raise ValueError(f"reset options {unknown} are not known; valid: ['reset_mask']")
    if options is None or "reset_mask" not in options:
        return np.ones(num_envs, dtype=bool)
    mask = options["reset_mask"]
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (num_envs,):
        raise ValueError(f"options['reset_mask'] must be a numpy bool array of shape ({num_envs},), got "
                         f"{type(mask).__name__} {getattr(mask, 'dtype', '')} {getattr(mask, 'shape', '')}")
    if not mask.any():
        raise ValueError("options['reset_mask'] must select at least one environment")
    if not started and not mask.all():
        raise ValueError("the first reset must start every environment (reset_mask all true, or no mask)")
    return mask.copy()


class MRDamperVectorEnv(PlantDeclarations, VectorEnv):
    """N environments of one plant in one compiled call (see the module docstring); options as the plant's scalar
    class, plus ``num_envs``, ``autoreset_mode``, ``render_mode`` ("rgb_array": ``render()`` returns one frame per
    environment, as Gymnasium's vector environments do; each environment then keeps its episode's history),
    ``max_episode_steps`` (episodes end, truncated, after at most that many steps, as ``gym.make``'s TimeLimit)
    and ``threads`` (numba threads of the step; default: one below 64 environments, from 64 the faster of one
    and every numba thread, timed while stepping (:class:`ThreadTuner`); the results are the same for any count,
    see docs/speed.md)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1000, "autoreset_mode": AutoresetMode.NEXT_STEP}
    env_id = ""
    build: Callable[..., Assembly] | None = None
    _OWN = ("num_envs", "render_mode", "autoreset_mode", "max_episode_steps", "threads")

    def __init__(self, num_envs: int = 1, *, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, max_episode_steps: int | None = None,
                 threads: int | None = None, assembly: Assembly | None = None, **options):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']} (a window: render "
                             f"a scalar environment with render_mode='human'), got {render_mode!r}")
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in AutoresetMode]}, "
                             f"got {autoreset_mode!r}") from None
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or an int >= 1, got {max_episode_steps!r}")
        if assembly is None:
            assembly = assemble(type(self), options, own=self._OWN)
        elif options:
            raise ValueError(f"options {sorted(options)} apply when the environment builds its assembly, not beside "
                             f"an assembly")
        self.assembly = asm = assembly
        self.num_envs = N = int(num_envs)
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "autoreset_mode": mode, "render_fps": render_fps(asm.control_dt)}
        tuned = threads is None  # the default: one thread, or timed against every thread (from 64 envs)
        self.core = core = EnvCore(asm, N, history=HIST_FULL if render_mode else HIST_NONE,
                                   step_cap=None if max_episode_steps is None else int(max_episode_steps),
                                   threads=default_threads(N) if tuned else threads)
        self.thread_tuner = ThreadTuner(core.driver.threads) if tuned and core.driver.threads > 1 else None
        self.single_observation_space = _box(core.driver.n_obs)
        self.single_action_space = action_space(asm)
        self.observation_space = batch_space(self.single_observation_space, N)
        self.action_space = batch_space(self.single_action_space, N)
        self.nd = asm.coupled.system.nd
        self.sensors = asm.sensors.names
        self.sensor_layout = core.layout
        self.observation_labels = core.labels
        self.actuation = force_actuation(self)
        self._rngs: list = [None] * N
        self._seeds: list = [None] * N
        self._ended = np.zeros(N, dtype=bool)  # episodes over: NEXT_STEP restarts them at the next step
        self._cost_names = core.cost_names
        # each term's row in the step's costs, its key and its mask's key in infos["cost_terms"]
        self._cost_keys = [(i, name, f"_{name}") for i, name in enumerate(core.cost_names, 1)]
        self._all = np.ones(N, dtype=bool)  # copied for the masks of every step (np.ones costs 4 times as much)
        self._ashape = (N, self.nd)
        self._non_finite = np.zeros(N, dtype=bool)  # ended by a NaN or infinite observation or reward
        self._started = False
        self._renderer = None
        self._bind()

    def _bind(self) -> None:
        self._status = self.core.driver.int_state("STATUS")
        self._reward = self.core.driver.state("REWARD")[:, 0]
        # (1 + T, N): each environment's cost over its last step, then per term (a view of the driver's state)
        self._step_costs = self.core._cost[:, :self.core.n_cost_terms + 1].T

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items()
                if k not in ("_status", "_reward", "_step_costs", "_renderer", "_view")}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._renderer = None
        self._bind()

    # --- Gymnasium API -----------------------------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        N = self.num_envs
        if seed is None:
            seeds = [None] * N
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(N)]
        else:
            try:
                seeds = list(seed)
            except TypeError:
                raise ValueError(f"seed must be None, an int >= 0 or a sequence of {N} of them, got {seed!r}") from None
            if len(seeds) != N:
                raise ValueError(f"seed must be None, an int or {N} seeds, got {len(seeds)}")
        if not all(s is None or (isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 0)
                   for s in seeds):
            raise ValueError(f"seeds must be None or ints >= 0, got {seed!r}")
        mask = reset_mask(options, self.num_envs, self._started)
        for b in np.flatnonzero(mask):  # None keeps an environment's generator, as a scalar env's reset does
            if seeds[b] is not None or self._rngs[b] is None:
                self._rngs[b], self._seeds[b] = seeding.np_random(seeds[b])
        self.core.start(self._rngs, mask)
        if self.actuation is not None:
            self.actuation.reset(mask)
        self._ended[mask] = False
        self._non_finite[mask] = False
        self._started = True
        infos = {"t": np.zeros(N), "_t": mask.copy()}
        self._add_disturbance(infos, mask)
        self._add_costs(infos, mask)
        return self.core.obs.copy(), infos

    @property
    def np_random(self) -> tuple:
        """Each environment's generator (its records and noise are drawn from it), as SyncVectorEnv gives them."""
        return tuple(self._rngs)

    @property
    def np_random_seed(self) -> tuple:
        """Each environment's seed (the last reset's, or the one drawn for it), as SyncVectorEnv gives them."""
        return tuple(self._seeds)


    def _add_costs(self, infos: dict, mask: np.ndarray | None = None) -> np.ndarray:
        """Every environment's cost over its last step and per term (0 for those that (re)started and did not
        step), batched with their masks (``mask``: the environments that have them, default all; one array shared
        by the cost keys): ``cost``, ``cost_terms`` {term: (N,)}. Returns the (1 + T, N) array whose rows are those
        values."""
        C = self._step_costs.copy()
        if mask is None:
            m = self._all.copy()
        else:
            C[:, ~mask] = 0.0
            m = mask.copy()
        # one mask array for the cost keys: they are present for the same environments, always (a numpy call
        # fewer per term: the vector step's Python part is a few microseconds)
        infos["cost"], infos["_cost"] = C[0], m
        terms = {}
        for i, name, masked in self._cost_keys:
            terms[name], terms[masked] = C[i], m
        infos["cost_terms"], infos["_cost_terms"] = terms, m
        return C

    def _add_disturbance(self, infos: dict, mask: np.ndarray) -> None:
        """The names of the new episodes' records, for the environments in ``mask``."""
        names = np.full(self.num_envs, None, dtype=object)
        for b in np.flatnonzero(mask):
            names[b] = self.core.episodes[b].record.name
        infos["disturbance"], infos["_disturbance"] = names, mask.copy()

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        core = self.core
        N = self.num_envs
        if type(actions) is np.ndarray and actions.dtype == np.float64 and actions.shape == self._ashape:
            a = actions.reshape(-1)
        else:
            a = as_action(actions, self.nd, N)
        if not np.isfinite(a).all():  # the whole batch, before any environment steps
            raise ValueError("actions must be finite (no NaN or infinity)")
        mode = self.metadata["autoreset_mode"]
        restart = self._ended if mode == AutoresetMode.NEXT_STEP and self._ended.any() else None
        if mode == AutoresetMode.DISABLED and self._ended.any():
            raise RuntimeError(f"the episodes of environments {np.flatnonzero(self._ended).tolist()} are over: "
                               "reset them with reset(options={'reset_mask': mask}) (autoreset_mode DISABLED)")
        if self.actuation is not None:
            a = self.actuation.step_commands(a, core.obs, self.assembly.force_range)
            if restart is not None:  # these restart and do not step: their inverse starts at their next step
                self.actuation.reset(restart)
        if restart is not None:  # NEXT_STEP: the environments that ended last step start again, and do not step
            core.start(self._rngs, restart)
            self._status[restart] = TRUNCATED
        if self.thread_tuner is None:
            core.step(a)
        else:
            self.thread_tuner.step(core, a)
        if restart is not None:
            self._status[restart] = RUNNING
        rewards = self._reward.copy()
        if core.python_reward:  # a callable reward, on the period each environment ran (as the scalar env adds it)
            ran = self._status != DIVERGED
            if restart is not None:
                ran &= ~restart
            for b in np.flatnonzero(ran):
                rewards[b] += self.assembly.reward(core.period(int(b)))
        infos = {"t": core._k * self.assembly.control_dt, "_t": self._all.copy()}
        costs = self._add_costs(infos)  # those that restarted did not step: theirs are 0, as their reset infos say
        if restart is not None:
            rewards[restart] = 0.0
            self._add_disturbance(infos, restart)
            self._ended = np.zeros(N, dtype=bool)
        # one sum filters the common step (a NaN or inf makes it non-finite; a finite overflow only takes the exact
        # check below, which finds nothing): half the cost of two isfinite passes at small N
        if not math.isfinite(float(rewards.sum()) + float(core.obs.sum())):
            # a NaN or infinite value is never handed on as a step that went well: that episode ends
            bad = ~(np.isfinite(rewards) & np.isfinite(core.obs).all(axis=1)) & (self._status == RUNNING)
            if restart is not None:
                bad &= ~restart
            self._status[bad] = DIVERGED
            self._non_finite[bad] = True
        # every environment running (RUNNING = 0): the common step (count_nonzero takes a quarter of .any()'s time)
        if not np.count_nonzero(self._status):
            return core.obs.copy(), rewards, np.zeros(N, dtype=bool), np.zeros(N, dtype=bool), infos
        return self._end_step(restart, rewards, infos, costs)

    def _end_step(self, restart, rewards, infos, costs):
        """The step at which some episodes ended."""
        core = self.core
        asm = self.assembly
        N = self.num_envs
        status = self._status.copy()
        if np.any(status == BAD_ACTION):  # a non-finite command from the force mode's inverse
            self._status[status == BAD_ACTION] = RUNNING
            raise ValueError("the inverse model returned a non-finite command")
        ran = np.ones(N, dtype=bool) if restart is None else ~restart
        terminated = ran & ((status == TERMINATED) | (status == DIVERGED))
        truncated = ran & (status == TRUNCATED)
        done = terminated | truncated
        obs = core.obs.copy()
        ended = {}  # each ended environment's info, as its scalar environment gives it
        names = self._cost_names
        for b in np.flatnonzero(done):
            c = costs[:, b].tolist()
            info = {"t": float(infos["t"][b]), "cost": c[0], "cost_terms": dict(zip(names, c[1:]))}
            if status[b] == DIVERGED:
                rewards[b] = -asm.limits.amount(core._n_steps[b] * asm.control_dt)
                info["termination_reason"] = non_finite_reason(info["t"]) if self._non_finite[b] else \
                    f"diverged: {core.failure_message(b)}"
                self._non_finite[b] = False
            elif status[b] == TERMINATED:
                info["termination_reason"] = "stroke_limit"
            info["episode_metrics"] = core.episode_metrics(int(b))
            ended[b] = info
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            for b, info in ended.items():
                self._add_info(infos, {"final_obs": obs[b].copy(), "final_info": info}, b)
            core.start(self._rngs, done)
            if self.actuation is not None:
                self.actuation.reset(done)
            obs[done] = core.obs[done]
            infos["t"][done] = 0.0  # the new episodes' reset info
            costs[:, done] = 0.0
            self._add_disturbance(infos, done)
        else:
            for b, info in ended.items():
                self._add_info(infos, info, b)
            self._ended = done
        return obs, rewards, terminated, truncated, infos

    # --- rendering ---------------------------------------------------------------------------------------------
    def render(self) -> tuple[np.ndarray, ...] | None:
        """One frame per environment (``render_mode="rgb_array"``)."""
        if self.render_mode is None:
            from gymnasium import logger

            logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        if not self._started:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._view = _SubEnv(self, 0)
            self._renderer = self.assembly.renderer(self._view, human=False)
        frames = []
        for b in range(self.num_envs):  # one figure drawn for each environment in turn
            self._view.b = b
            frames.append(self._renderer.frame())
        return tuple(frames)

    def close_extras(self, **kwargs):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def default_threads(num_envs: int) -> int:
    """The threads a vector environment of ``num_envs`` environments is built with when ``threads`` is not given:
    every numba thread (``numba.get_num_threads()``) from 64 environments, else 1; with more than one, the
    :class:`ThreadTuner` then chooses at each step between them and one."""
    import numba

    return numba.get_num_threads() if num_envs >= PARALLEL_FROM else 1


class ThreadTuner:
    """The default thread count of a vector environment's step, chosen by timing it while it steps.

    It starts on one thread and keeps a running mean of the step time of the count it runs (time constant
    ``memory`` seconds). Every ``interval`` seconds (wall clock) — or sooner, ``soonest`` seconds after the last
    trial at the earliest, once the running mean says the other count would win — it tries the other count for
    about ``trial`` seconds of steps at the chosen count's pace (at least ``probe`` steps), after an untimed step
    (the first step after a switch wakes or parks the threads). Every thread (``many``, the count the driver was
    built with) wins if its mean step time is below ``margin`` × one thread's (threads burn more CPU time than they
    save wall time). A trial stops as soon as the other count can no longer win, so that trying a count that spins
    on a busy machine costs at most ``trial`` seconds; long enough that OpenMP's occasional step stalled behind a
    descheduled thread is seen. The counts only move the work between numba's threads: every environment's results
    are the same, bit for bit.

    ``threads``: the count chosen; ``choices``: how many trials ended on (one thread, ``many``)."""

    interval = 10.0  # s between trials
    soonest = 1.0  # s after a trial before the next, when the chosen count slows down
    trial = 0.25  # s of steps (at the chosen count's pace) timed in a trial
    probe = 5  # timed steps of a trial at least
    memory = 1.0  # s: time constant of the running mean step time
    margin = 0.9  # every thread must take less than 0.9 × one thread's step time

    def __init__(self, many: int, clock=time.perf_counter):
        self.many = int(many)
        self.clock = clock
        self.choices = [0, 0]
        self._restart()

    def _restart(self) -> None:
        self.threads = 1
        self._mean: float | None = None  # running mean step time (s) of the chosen count
        self._seen = 0  # steps timed on it since it was chosen
        self._other: float | None = None  # the other count's mean step time at its last trial
        self._trial: list[float] | None = None  # step times of the other count while it is tried
        self._length = self.probe  # timed steps of the trial
        self._skip = True  # the next step is the first after a switch: not timed
        self._last = -np.inf  # clock at the end of the last trial

    def __setstate__(self, state: dict) -> None:  # a copy (another process, another clock) starts again
        self.__dict__.update(state)
        self._restart()

    def _many_wins(self, one: float, many: float) -> bool:
        return many < self.margin * one

    def _wins(self, t_other: float) -> bool:
        """Whether the other count, at ``t_other`` s a step, beats the chosen one at its running mean."""
        if self.threads == 1:
            return self._many_wins(self._mean, t_other)
        return not self._many_wins(t_other, self._mean)

    def step(self, core, action) -> int:
        """``core.step(action)`` on the chosen count, or on the other during a trial (``core.driver.threads``)."""
        if self._trial is None and self._seen >= self.probe:
            since = self.clock() - self._last
            if since >= self.interval or (since >= self.soonest and self._other is not None
                                          and self._wins(self._other)):
                self._trial, self._skip = [], True
                self._length = int(min(10_000, max(self.probe, np.ceil(self.trial / self._mean))))
        n = self.threads if self._trial is None else (1 if self.threads > 1 else self.many)
        core.driver.threads = n
        t0 = self.clock()
        status = core.step(action)
        elapsed = self.clock() - t0
        if self._skip:
            self._skip = False
        elif self._trial is None:
            self._seen += 1  # the first steps: their plain mean; then a mean over the last ``memory`` seconds
            w = max(1.0 / self._seen, min(1.0, elapsed / self.memory))
            self._mean = elapsed if self._mean is None else self._mean + w * (elapsed - self._mean)
        else:
            self._trial.append(elapsed)
            self._judge(n)
        return status

    def _judge(self, n: int) -> None:
        """End the trial of count ``n`` once it is complete or can no longer win."""
        times = self._trial
        if len(times) < self._length and self._wins(sum(times) / self._length):  # it may still win: go on
            return
        t_other = sum(times) / len(times)
        if len(times) == self._length and self._wins(t_other):
            self._other, self._mean, self.threads, self._seen = self._mean, t_other, n, len(times)
        else:
            self._other = t_other
        self.choices[self.threads > 1] += 1
        self._trial, self._skip, self._last = None, True, self.clock()


class _SubEnv:
    """Environment ``b`` of a vector environment as a renderer sees a scalar one."""

    def __init__(self, venv: MRDamperVectorEnv, b: int):
        self.venv, self.b = venv, b

    def signal(self, name: str) -> np.ndarray:
        return self.venv.core.signal(name, self.b)

    @property
    def episode(self):
        return self.venv.core.episodes[self.b]

    @property
    def title(self) -> str:
        return f"{type(self.venv).__name__}[{self.b}]"

    def __getattr__(self, name):  # dt, n_dampers, command_spec, plant_params: the vector env's
        if name.startswith("__") or name == "venv":
            raise AttributeError(name)
        return getattr(self.venv, name)


def env_info(infos: dict, i: int) -> dict:
    """Environment ``i``'s info out of a batched info dict (the inverse of Gymnasium's batching): every key whose
    mask ``_key`` is set for i, nested dicts included."""
    out = {}
    for key, value in infos.items():
        mask = infos.get(f"_{key}")
        if mask is None or not mask[i]:
            continue
        v = env_info(value, i) if isinstance(value, dict) else value[i]
        out[key] = v.item() if isinstance(v, np.generic) else v
    return out


def _box(n: int):
    import gymnasium as gym

    return gym.spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)
