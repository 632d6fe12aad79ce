"""The environment core shared by the scalar and the vector environments: an :class:`Assembly` of parts turned
into one compiled :class:`~mrd_env.stepping.Driver` of N systems.

An assembly is what a plant's environment module builds from the user's options (see
:mod:`.quarter_car`, :mod:`.shear_building`): the damper, the linear plant and their coupling, the named
signals, the parts — disturbance source, sensors, reward, limits, constraint costs — and the plant's own
knowledge: the initial state of an episode, the episode metrics, the roles of its signals for the classical control
laws (``roles``) and the default control objective (``objective``).
"""
from __future__ import annotations

import copy
import os
import reprlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium.envs.registration import EnvSpec
from gymnasium.vector import VectorEnv

from ..dampers import DamperModel
from ..disturbances import Record
from ..mechanics import CoupledPlant, LinearPlant
from ..resources import FLOAT, check as check_memory, episode_parts, format_bytes, plant_parts
from ..stepping import HIST_FULL, HIST_NONE, HIST_PERIOD, Driver, Processing, noise_keys
from ..stepping.scheme import MAX_SUBSTEPS, max_level_of
from .costs import Costs
from .disturbance import Disturbance
from .reward import CallableReward, QuadraticReward
from .sensors import Sensors
from .signals import SignalMap
from .termination import Limits


@dataclass
class Episode:
    """One episode's data: the input record, the plant's initial state [q, q̇] (None: at rest) and anything
    the reward scales and the metrics need (``extras``, e.g. the uncontrolled building's response)."""

    record: Record
    q0: np.ndarray | None = None
    extras: dict = field(default_factory=dict)


@dataclass
class EpisodeStats:
    """What the driver accumulated over an episode: r.m.s. and peak of every statistics signal (per channel),
    the fourth-power dose and the maximum running r.m.s. of the dose signal, the number of rows and dt; the
    constraint costs' totals (``cost``: {"cost": time in violation of any constraint, "cost_<term>": of each
    term}, s) and the control power (``power_peak``: max over the rows of Σ|F_i·v_i|, W; ``energy``: its sum
    over the rows after row 0 times dt, J) where the assembly has them."""

    rms: dict[str, np.ndarray]
    peak: dict[str, np.ndarray]
    dose4: float
    max_running_rms: float
    n_rows: int
    dt: float
    cost: dict[str, float] = field(default_factory=dict)
    power_peak: float = 0.0
    energy: float = 0.0


@dataclass
class Assembly:
    """Everything an MR-damper environment is made of (see the module docstring)."""

    kind: str
    damper: DamperModel
    plant_params: Any
    linear_plant: LinearPlant
    coupled: CoupledPlant
    signals: SignalMap
    sensor_names: tuple[str, ...]
    sensors: Sensors
    disturbance: Disturbance
    reward: QuadraticReward | CallableReward
    limits: Limits
    new_episode: Callable[[Record], Episode]
    metrics: Callable[[EpisodeStats, Episode], dict]
    roles: Mapping[str, str]
    objective: Mapping[str, float]
    dt: float = 1e-3
    control_dt: float = 1e-3
    episode_seconds: float | None = None
    action_mode: str = "physical"
    inverse: Any = None                                # action_mode "force": the inverse (name, dict or Inverse)
    force_range: float | None = None                   # action_mode "force": the action Box ±force_range (N)
    filters: list = field(default_factory=list)       # (input signal, output signal, sos)
    stat_signals: tuple[str, ...] = ()
    dose_signal: str | None = None
    dose_window: float = 1.0                           # s (ISO 2631 running r.m.s.)
    renderer: Callable | None = None
    options: dict = field(default_factory=dict)        # the user's options, as given (for records and agents)
    preview_times: tuple[float, ...] = ()              # s ahead of the disturbance a preview sensor reads
    episode_floats: int = 0                            # floats per record sample an episode's extras keep
    reset_floats: int = 0                              # floats per record sample new_episode computes and drops
    #: {reward signal: mean square} on the plant's nominal disturbance, what weights="reward" of the model-based
    #: laws divides by (None: the plant declares none)
    nominal_reference: Callable[[], dict] | None = None
    #: the constraints whose violation is the per-step cost ``info["cost"]`` (:mod:`.costs`; None: none)
    costs: Costs | None = None
    #: (force signal, velocity signal) of the control power Σ_i |F_i·v_i| (channel by channel; None: none)
    power_signals: tuple[str, str] | None = None

    def __post_init__(self) -> None:
        # parameters that make the physics meaningless (a mass of 1e-300 kg) are refused, naming the parameter
        self.linear_plant.check_resolved(self.dt)

    @property
    def n_sub(self) -> int:
        return int(round(self.control_dt / self.dt))

    def episode_steps(self, n_samples: int) -> int:
        """Control steps of an episode on a record of ``n_samples`` samples (cut at ``episode_seconds``)."""
        n_phys = n_samples - 1
        if self.episode_seconds is not None:
            n_phys = min(n_phys, int(round(self.episode_seconds / self.dt)))
        return n_phys // self.n_sub

    @property
    def max_episode_steps(self) -> int | None:
        """The most control steps an episode has (None: the disturbance's records are of unknown length and no
        ``episode_seconds`` bounds them)."""
        n = self.disturbance.max_samples
        if n is None:
            return None if self.episode_seconds is None else int(round(self.episode_seconds / self.dt)) // self.n_sub
        return self.episode_steps(n)


def assemble(cls, options: dict, own: tuple[str, ...]) -> Assembly:
    """The assembly of environment class ``cls`` (its ``build``, the plant's ``assembly(**options)``), after a
    ``ValueError`` for an option it does not take, naming the valid ones (``own``: the class's own keywords)."""
    from .build import check_options

    check_options(cls.env_id or cls.__name__, options, cls.build, also=own)
    return cls.build(**options)


class PlantDeclarations:
    """What an environment declares about its plant, for controllers and users (shared by the scalar and vector
    environments, which set ``self.assembly``): the plant kind, linear model, damper, signal roles and default
    control objective, and the linear map of every signal."""

    assembly: Assembly

    @property
    def plant_kind(self) -> str:
        return self.assembly.kind

    @property
    def linear_plant(self) -> LinearPlant:
        return self.assembly.linear_plant

    @property
    def plant_params(self):
        return self.assembly.plant_params

    @property
    def damper(self) -> DamperModel:
        return self.assembly.damper

    @property
    def command_spec(self):
        return self.assembly.damper.command

    @property
    def n_dampers(self) -> int:
        return self.assembly.coupled.system.nd

    @property
    def F_static(self) -> float:
        """The damper force at rest (e.g. the accumulator preload k1·x0), balanced by the plant (N)."""
        return self.assembly.coupled.F_static

    @property
    def roles(self) -> dict[str, str]:
        """Which signal plays which part in the classical laws: body_velocity (ż_s, an absolute velocity: the cars
        have it, the building does not), wheel_velocity (ż_u), damper_velocity, damper_stroke, damper_force."""
        return dict(self.assembly.roles)

    @property
    def objective(self) -> dict[str, float]:
        """Default weights {signal: weight} on the squared regulated outputs of a linear-quadratic design."""
        return dict(self.assembly.objective)

    @property
    def dt(self) -> float:
        return self.assembly.dt

    @property
    def control_dt(self) -> float:
        return self.assembly.control_dt

    @property
    def action_mode(self) -> str:
        return self.assembly.action_mode

    @property
    def preview_times(self) -> tuple[float, ...]:
        """The times ahead (s) at which the ``road_preview`` sensor reads the road (empty: no preview)."""
        return self.assembly.preview_times

    @property
    def max_episode_steps(self) -> int | None:
        """The most control steps an episode of this environment has (None if unknown: a disturbance whose records
        are of unknown length, without ``episode_seconds``)."""
        return self.core.max_episode_steps

    # The episode length in the spec (issue 37). No max_episode_steps is registered (it depends on the options).
    # A scalar environment's spec is left as gym.make sets it (max_episode_steps None on the unwrapped
    # environment): the entry point's TimeLimit at the environment's own length states it in env.spec, as
    # Gymnasium's environments do (mrd_env.envs.entry). The native vector environment states it in
    # its spec and, as the step cap make_vec(spec) passes back, in the spec's keywords (unless the keywords already
    # cap the episodes): gym.make_vec(envs.spec) then re-creates an equal spec, a fixed point, and the cap, being
    # the environment's own length, changes no episode. This is the form Gymnasium gives CartPole's vector env.
    @property
    def spec(self) -> EnvSpec | None:
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        n = self.max_episode_steps
        if value is not None and isinstance(self, VectorEnv) and n is not None:
            value = copy.copy(value)
            value.max_episode_steps = n
            if "max_episode_steps" not in value.kwargs:
                value.kwargs = {**value.kwargs, "max_episode_steps": n}
        self.__dict__["_spec"] = value

    def signal_matrices(self, name: str) -> dict[str, np.ndarray]:
        """The linear map of signal ``name``: s = C·[q, q̇] + D_F·F + D_w·w + d0 (q, q̇ the ``linear_plant``
        coordinates, F the damper forces, w its inputs). ``ValueError`` for a signal that is not a linear output
        (the command, a filter output, the damper's internal states)."""
        sig = self.assembly.signals
        if name not in sig:
            raise ValueError(f"unknown signal {name!r}; signals: {sorted(sig.signals)}")
        G = sig.output_rows(name)
        if name == "damper_states" or not np.any(G):
            raise ValueError(f"signal {name!r} is not a linear function of the plant state, forces and inputs")
        nq = 2 * self.linear_plant.n_dof
        nY, nd = sig.nY, sig.nd
        return {"C": G[:, :nq], "D_F": G[:, nY:nY + nd], "D_w": G[:, nY + nd:sig.ncol - 1], "d0": G[:, sig.ncol - 1]}


    def output_matrices(self) -> dict[str, np.ndarray]:
        """The observation's linear map for controller design (without noise, delay and history).

        obs = C @ [q, q̇] + D_F @ F + D_w @ w + d0 for every sensor row except ``command``, filter outputs and
        ``damper_states`` (whose rows are zero here; ``mask`` marks the rows that are plant outputs). q, q̇ are the
        ``linear_plant`` coordinates, F the damper forces, w its inputs (``linear_plant.input_names``);
        accelerations include the damper inertance and the static preload balance (d0).
        """
        sig = self.assembly.signals
        nq = 2 * self.linear_plant.n_dof
        nY, nd = sig.nY, sig.nd
        rows, mask = [], []
        for name, _, _ in self.sensor_layout:
            G = sig.output_rows(name)
            linear = name != "damper_states" and bool(np.any(G))
            rows.append(G if linear else np.zeros_like(G))
            mask += [linear] * G.shape[0]
        G = np.vstack(rows)
        return {"C": G[:, :nq], "D_F": G[:, nY:nY + nd], "D_w": G[:, nY + nd:sig.ncol - 1], "d0": G[:, sig.ncol - 1],
                "mask": np.array(mask, dtype=bool)}


class EnvCore:
    """N environments of one assembly in one compiled driver.

    ``history``: HIST_FULL keeps every 1 kHz row of the episode (the scalar environment: rendering and
    ``signal()``), HIST_PERIOD the rows of the last control period (a Python reward), HIST_NONE nothing.
    ``threads``: the driver's (:class:`~mrd_env.stepping.driver.Driver`).
    """

    def __init__(self, asm: Assembly, N: int, history: int = HIST_NONE, step_cap: int | None = None,
                 threads: int | None = None):
        self.asm = asm
        self.N = N
        self.step_cap = step_cap  # at most this many control steps per episode (a vector env's max_episode_steps)
        sig = asm.signals
        self.meas_cols, noise, self.layout, self.labels = asm.sensors.bind(sig, asm.sensor_names)
        self.python_reward = isinstance(asm.reward, CallableReward)
        if self.python_reward:
            rcols, self.rweights = np.zeros(0, np.int64), np.zeros(0)
            if history == HIST_NONE:
                history = HIST_PERIOD
        else:
            rcols, w = asm.reward.bind(sig)
            # the kernel averages over the period's n_sub rows: × control_dt makes the reward the integral of
            # the cost over the period, so that returns do not depend on the control rate
            self.rweights = w * asm.control_dt
        lcols, limits = asm.limits.bind(sig)
        costs = asm.costs if asm.costs is not None else Costs()
        self.cost_names = costs.names
        ccols, climits, csides, cterms = costs.bind(sig)
        pcols = ()
        if asm.power_signals is not None:
            f_sig, v_sig = (sig[s] for s in asm.power_signals)
            if f_sig.width != v_sig.width:
                raise ValueError(f"power_signals {asm.power_signals} must have as many channels each")
            pcols = tuple((int(f), int(v)) for f, v in zip(f_sig.columns, v_sig.columns))
        filters = [(int(sig[i].columns[0]), int(sig[o].columns[0]), sos) for i, o, sos in asm.filters]
        stat_cols = np.concatenate([sig[s].columns for s in asm.stat_signals]).astype(np.int64) \
            if asm.stat_signals else np.zeros(0, np.int64)
        self._stat_slices, k = {}, 0
        for s in asm.stat_signals:
            self._stat_slices[s] = slice(k, k + sig[s].width)
            k += sig[s].width
        self.history_mode = history
        self._check_memory(self.max_episode_steps, None)
        pr = Processing(G=sig.G, n_extra=sig.width - sig.G.shape[0] - asm.coupled.system.nd, filters=filters,
                        reward_cols=tuple(rcols), limit_cols=tuple(lcols), limits=tuple(limits),
                        penalty=(asm.limits.penalty, asm.limits.penalty_rate * asm.control_dt), stat_cols=tuple(stat_cols),
                        dose_col=int(sig[asm.dose_signal].columns[0]) if asm.dose_signal else -1,
                        dose_window=max(1, int(round(asm.dose_window / asm.dt))), meas_cols=tuple(self.meas_cols),
                        noise_std=tuple(noise), delay=asm.sensors.delay, history=asm.sensors.history,
                        history_mode=history, normalized=asm.action_mode == "normalized", cost_cols=ccols,
                        cost_limits=climits, cost_sides=csides, cost_terms=cterms, power_cols=pcols)
        cmd = asm.damper.command
        self.driver = Driver(asm.damper, asm.coupled.system, N, pr, dt=asm.dt, n_sub=asm.n_sub,
                             v_range=(cmd.v_min, cmd.v_max), threads=threads)
        self.nd = asm.coupled.system.nd
        self.episodes: list[Episode | None] = [None] * N
        self._bind_views()

    def _bind_views(self) -> None:
        """Views of the driver's state (re-derived on a copy, which would make them separate arrays)."""
        d = self.driver
        self._status = d.int_state("STATUS")
        self._k = d.int_state("K")
        self._reward = d.state("REWARD")[:, 0]
        self._rscale = d.state("RSCALE")
        self._n_steps = d.int_state("NSTEPS")
        self._cost = d.state("COST")

    # --- copies (pickle, deepcopy, cloudpickle) ---------------------------------------------------------------
    _VIEWS = ("_status", "_k", "_reward", "_rscale", "_n_steps", "_cost")
    _CODE = ("kernel",)  # the driver's compiled module: loaded again from the damper's class

    def __getstate__(self) -> dict:
        state = {k: v for k, v in self.__dict__.items() if k not in self._VIEWS}
        d = self.driver
        state["driver"] = (type(d), {k: v for k, v in vars(d).items() if k not in self._CODE})
        return state

    def __setstate__(self, state: dict) -> None:
        from ..stepping import kernel_module

        cls, dstate = state.pop("driver")
        d = cls.__new__(cls)
        d.__dict__.update(dstate)
        d.kernel = kernel_module(type(d.damper))
        self.__dict__.update(state)
        self.driver = d
        self._bind_views()

    @property
    def max_episode_steps(self) -> int | None:
        n = self.asm.max_episode_steps
        return self.step_cap if n is None else (n if self.step_cap is None else min(n, self.step_cap))

    # --- episodes -------------------------------------------------------------------------------------------
    def start(self, rngs, mask=None) -> None:
        """New episodes for the environments in ``mask`` (all by default), each drawing its record and noise
        key from its own generator ``rngs[b]``."""
        asm = self.asm
        mask = np.ones(self.N, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        idx = np.flatnonzero(mask)
        n_sub = asm.n_sub
        samples = {b: asm.disturbance.sample(rngs[b], asm.dt) for b in idx}
        rows = {}
        for b, rec in samples.items():  # checked before anything changes: a refused reset leaves the env as it was
            n_steps = asm.episode_steps(rec.n_samples)
            if self.step_cap is not None:
                n_steps = min(n_steps, self.step_cap)
            if n_steps < 1:
                raise ValueError(f"the disturbance record ({rec.duration:g} s) is shorter than one control period "
                                 f"({asm.control_dt:g} s)")
            rows[b] = n_steps * n_sub + 1
        if asm.max_episode_steps is None:  # records of a length unknown at construction
            self._check_memory((max(rows.values()) - 1) // n_sub, max(r.n_samples for r in samples.values()))
        recs = {}
        for b in idx:
            ep = asm.new_episode(samples[b])
            self.episodes[b] = ep
            recs[b] = ep.record
        d = self.driver
        need = max(rows.values())
        if d.W.shape[1] < need or d.W.shape[0] != self.N:
            W = np.zeros((self.N, max(need, d.W.shape[1] if d.W.shape[0] == self.N else 0), d.W.shape[2]
                          if d.W.shape[0] == self.N else asm.coupled.system.nw))
            if d.W.shape[0] == self.N:
                W[:, :d.W.shape[1]] = d.W
            d.W = W
        n_in = asm.coupled.system.nw - 1
        Y0 = np.zeros((self.N, d.n))
        for b, rec in recs.items():
            r = rows[b]
            d.W[b, :r, :n_in] = rec.data[:r]
            d.W[b, :r, n_in] = 1.0  # the constant channel that balances the static preload
            d.W[b, r:] = d.W[b, r - 1]
            self._n_steps[b] = (r - 1) // n_sub
            if not self.python_reward:
                self._rscale[b] = asm.reward.scales(self.episodes[b], self.rweights)
            q0 = self.episodes[b].q0
            n2 = 2 * asm.linear_plant.n_dof
            if q0 is not None:
                Y0[b, :n2] = q0
            # the dampers' internal states at rest at the start's strokes (y = x_d of a Spencer–Dyke damper)
            Y0[b, n2:] = asm.damper.rest_states(asm.coupled.system.Cx @ Y0[b, :n2])
        hist_rows = {HIST_NONE: 0, HIST_FULL: d.W.shape[1], HIST_PERIOD: n_sub}[self.history_mode]
        if d.H.shape[1] != hist_rows:
            d.H = np.zeros((self.N, hist_rows, d.nH))
        keys = np.zeros(self.N, dtype=np.int64)
        keys[idx] = noise_keys([rngs[b] for b in idx])
        d.reset(mask, Y0=Y0, keys=keys)

    def _check_memory(self, steps: int | None, record_samples: int | None) -> None:
        """``ValueError`` naming the options if :meth:`memory_parts` exceed the memory limit
        (:mod:`mrd_env.resources`); called before anything is allocated."""
        check_memory(self.memory_parts(steps, record_samples), self._memory_cause(steps))

    def memory_parts(self, steps: int | None, record_samples: int | None = None) -> dict[str, float]:
        """The estimate {what: bytes} of N environments' state and of their episodes of ``steps`` control steps
        (None: the state alone) on records of ``record_samples`` (default: the disturbance's longest)."""
        asm, N = self.asm, self.N
        sig = asm.signals
        nw, nd = asm.coupled.system.nw, asm.coupled.system.nd
        n_meas = len(self.meas_cols)
        depth = asm.sensors.delay + asm.sensors.history
        # per environment: the dose ring buffer, the sensor FIFO, the observation, one row, the damper's state, the
        # costs and the power
        state = FLOAT * (max(1, int(round(asm.dose_window / asm.dt))) + depth * n_meas + asm.sensors.history * n_meas
                         + 2 * sig.width + 64 * nd + 4 * sig.G.shape[1] + 2 * len(self.cost_names) + 4)
        parts = {f"the state of {N} environments ({format_bytes(state)} each)": N * state}
        # what grows with the number of dampers and storeys: the signal map, the step matrices, the Newton scratch
        parts.update(plant_parts(nq=asm.coupled.system.nq, nd=nd, n_states=asm.damper.n_states, nw=nw,
                                 n_signals=sig.G.shape[0], levels=max_level_of(MAX_SUBSTEPS) + 1,
                                 scratch_rows=N + min(N, os.cpu_count() or 1)))
        if steps is not None:
            rows = steps * asm.n_sub + 1
            n_rec = max(rows, record_samples or asm.disturbance.max_samples or rows)
            parts.update(episode_parts(
                rows=rows, record_samples=n_rec, num_envs=N, inputs=nw, record_channels=nw - 1,
                history_width=sig.width if self.history_mode == HIST_FULL else 0, plant_floats=asm.episode_floats,
                reset_floats=asm.reset_floats, per_env_records=asm.disturbance.random or bool(asm.preview_times),
                generated_channels=len(asm.disturbance.channels) if asm.disturbance.random else 0, dt=asm.dt))
        return parts

    def _memory_cause(self, steps: int | None) -> str:
        """The options that set the memory an episode takes, as the refusal names them."""
        asm, N = self.asm, self.N
        opts = asm.options
        named = []
        if steps is not None:
            if opts.get("episode_seconds") is not None:
                named.append(f"episode_seconds={asm.episode_seconds:g}")
            else:
                named.append(f"an episode of {steps * asm.control_dt:g} s (the length of "
                             f"{asm.disturbance.describe()}, without episode_seconds)")
            for k in ("ground_motion_params", "road_params", "ground_motion", "road"):
                v = opts.get(k)
                if isinstance(v, Mapping) and v:
                    named.append(f"{k}={reprlib.repr(v)}")
            if asm.dt != 1e-3:
                named.append(f"dt={asm.dt:g}")
            if asm.preview_times:
                named.append(f"preview ({len(asm.preview_times)} times ahead)")
        if N > 1 or steps is None:
            named.append(f"num_envs={N}")
        return ", ".join(named)

    def step(self, action: np.ndarray) -> int:
        """Advance the running environments by one control period (``action`` float64 (N·nd,)); env 0's status."""
        return self.driver.step(action)

    # --- results ------------------------------------------------------------------------------------------------
    @property
    def obs(self) -> np.ndarray:
        return self.driver.obs

    def period(self, b: int) -> dict[str, np.ndarray]:
        """The signals of env b over the last control period {name: (n_sub, width)} (Python rewards)."""
        H = self.driver.H
        n_sub = self.asm.n_sub
        rows = H[b, :n_sub] if self.history_mode == HIST_PERIOD else \
            H[b, (self._k[b] - 1) * n_sub + 1:self._k[b] * n_sub + 1]
        return {name: rows[:, s.columns] for name, s in self.asm.signals.signals.items()}

    def stats(self, b: int) -> EpisodeStats:
        d = self.driver
        n_rows = int(d.int_state("ROWS")[b])
        st = d.state("STATS")[b]
        dose = d.state("DOSE")[b]
        rms = {name: np.sqrt(st[2 * sl.start:2 * sl.stop:2] / n_rows) for name, sl in self._stat_slices.items()}
        peak = {name: st[2 * sl.start + 1:2 * sl.stop:2].copy() for name, sl in self._stat_slices.items()}
        power = d.state("POWER")[b]
        return EpisodeStats(rms, peak, float(dose[0]), float(dose[2]), n_rows, self.asm.dt,
                            cost=self.episode_cost(b), power_peak=float(power[0]),
                            energy=float(power[1]) * self.asm.dt)

    def episode_metrics(self, b: int) -> dict[str, float]:
        """The plant's episode metrics, then the costs' totals (``cost``, ``cost_<term>``, s)."""
        st = self.stats(b)
        return {**self.asm.metrics(st, self.episodes[b]), **st.cost}

    # --- constraint costs --------------------------------------------------------------------------------------
    @property
    def n_cost_terms(self) -> int:
        return len(self.cost_names)

    def episode_cost(self, b: int) -> dict[str, float]:
        """Env b's costs summed over its episode so far: {"cost": s, "cost_<term>": s}."""
        n = self.n_cost_terms + 1
        c = self._cost[b, n:2 * n].tolist()
        return {"cost": c[0], **{f"cost_{name}": v for name, v in zip(self.cost_names, c[1:])}}

    def zero_cost_info(self) -> dict:
        """The cost entries of a reset's info: no step yet, no cost."""
        return {"cost": 0.0, "cost_terms": dict.fromkeys(self.cost_names, 0.0)}

    def failure_message(self, b: int) -> str:
        from ..stepping import diverged_error

        reason, t = self.driver.failure(b)
        return str(diverged_error(self.asm.damper.name, reason, t, b, self.driver.max_substeps))

    def time(self, b: int) -> float:
        return float(self._k[b] * self.asm.control_dt)

    def signal(self, name: str, b: int) -> np.ndarray:
        """History of signal ``name`` of env b over its episode so far, (rows, width) at ``dt`` (HIST_FULL)."""
        sig = self.asm.signals[name]
        rows = int(self.driver.int_state("ROWS")[b])
        return self.driver.H[b, :rows][:, sig.columns]
