"""The machinery shared by the MR-damper environments (:class:`MRDamperEnv`).

A concrete environment defines its plant, its named signals (linear functions of the coupled state, the damper
forces and the exogenous inputs), its disturbance and its reward terms; everything else lives here:

* physics at ``dt`` (1 ms) by the shared stiff-stable routine, all sub-steps of one control period in one call
  of the compiled stepper, the command held (zero-order) over the period;
* a per-step post-processing kernel (compiled) that evaluates every signal at every physics sample into the
  episode history, filters one signal online (ISO 2631 Wk for the quarter car, state kept across steps),
  computes the reward and checks the stroke limit;
* sensors with Gaussian noise (from ``np_random``) and a delay FIFO; actions in physical or normalised units,
  clipped to the Box; termination on the stroke limit or a diverged simulation; truncation at the episode end;
  the field's metrics over the episode in ``info["episode_metrics"]``; rendering (:mod:`.render`).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
import math
from typing import Any, Mapping

import gymnasium as gym
import numba as nb
import numpy as np

from ..dampers import DamperModel, damper_class, make_damper
from ..errors import SimulationDivergedError
from ..plants import CoupledPlant, LinearPlant
from ..validation import check_scalar

_NO_SOS = np.zeros((0, 6))
_NO_ZI = np.zeros((0, 2))


@nb.njit(cache=True)
def _post(Y, F, W, k0, cmd, G, H, sos, zi, fin, fout, rcols, rscale, scols, limit, obs_idx, obs):
    """Signals, online filter, reward, stroke check and observation after one control period.

    Y (1, n_sub, nY) states and F (1, n_sub, nd) forces at the end of each physics sub-step (the stepper's
    buffers), W (1, n_rows, nw) the episode's inputs with the period starting at row k0, cmd (nd,) the held
    command. Row ``k0 + 1 + k`` of the history H receives [G @ (Y[k], F[k], W[k0+k+1]), cmd, filtered column].
    The filter is ``sos`` (scipy layout, a0 = 1) in transposed direct form II, as ``scipy.signal.sosfilt``,
    with its state ``zi`` carried across calls. Returns (reward = −mean_k Σ_i rscale_i H[row_k, rcols_i]²,
    True if any |H[row_k, scols]| > limit), and writes H[last row, obs_idx] into ``obs``.
    """
    n_sub = Y.shape[1]
    nY = Y.shape[2]
    nd = F.shape[2]
    nw = W.shape[2]
    nsig = G.shape[0]
    total = 0.0
    exceeded = False
    for k in range(n_sub):
        r = k0 + 1 + k
        for i in range(nsig):
            acc = 0.0
            for j in range(nY):
                acc += G[i, j] * Y[0, k, j]
            for j in range(nd):
                acc += G[i, nY + j] * F[0, k, j]
            for j in range(nw):
                acc += G[i, nY + nd + j] * W[0, r, j]
            H[r, i] = acc
        for j in range(nd):
            H[r, nsig + j] = cmd[j]
        if fin >= 0:
            x = H[r, fin]
            for s in range(sos.shape[0]):
                y = sos[s, 0] * x + zi[s, 0]
                zi[s, 0] = sos[s, 1] * x - sos[s, 4] * y + zi[s, 1]
                zi[s, 1] = sos[s, 2] * x - sos[s, 5] * y
                x = y
            H[r, fout] = x
        for i in range(rcols.shape[0]):
            v = H[r, rcols[i]]
            total += rscale[i] * v * v
        for i in range(scols.shape[0]):
            if abs(H[r, scols[i]]) > limit:
                exceeded = True
    last = k0 + n_sub
    for i in range(obs_idx.shape[0]):
        obs[i] = H[last, obs_idx[i]]
    return -total / n_sub, exceeded


class _SignalBuilder:
    """Rows of the output map G: signal = G @ [Y, F, W] with Y = [q, q̇, damper states], W = [inputs, 1]."""

    def __init__(self, coupled: CoupledPlant):
        s = coupled.system
        self.n = coupled.plant.n_dof
        self.nq = 2 * self.n
        self.nY = coupled.n
        self.nd = s.nd
        self.nw = s.nw
        self.ncol = self.nY + self.nd + self.nw
        self._A, self._BF, self._Bw = s.A, s.BF, s.Bw

    def _zeros(self, rows: int) -> np.ndarray:
        return np.zeros((rows, self.ncol))

    def disp(self, M) -> np.ndarray:
        """M @ q."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, : self.n] = M
        return G

    def vel(self, M) -> np.ndarray:
        """M @ q̇."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, self.n: self.nq] = M
        return G

    def acc(self, M) -> np.ndarray:
        """M @ q̈ with q̈ from the coupled equations of motion (damper inertance and static balance included)."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, : self.nq] = M @ self._A[self.n:]
        G[:, self.nY: self.nY + self.nd] = M @ self._BF[self.n:]
        G[:, self.nY + self.nd:] = M @ self._Bw[self.n:]
        return G

    def force(self) -> np.ndarray:
        G = self._zeros(self.nd)
        G[:, self.nY: self.nY + self.nd] = np.eye(self.nd)
        return G

    def inp(self, M) -> np.ndarray:
        """M @ w (plant inputs, without the constant channel)."""
        M = np.atleast_2d(np.asarray(M, dtype=float))
        G = self._zeros(M.shape[0])
        G[:, self.nY + self.nd: self.nY + self.nd + M.shape[1]] = M
        return G

    def damper_states(self) -> np.ndarray:
        k = self.nY - self.nq
        G = self._zeros(k)
        G[:, self.nq: self.nY] = np.eye(k)
        return G


def _check_options(name: str, given: Mapping | None, valid) -> dict:
    if given is None:
        return {}
    if not isinstance(given, Mapping):
        raise ValueError(f"{name} must be a dict, got {type(given).__name__}")
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise ValueError(f"{name} has unknown key(s) {unknown}; valid keys: {sorted(valid)}")
    return dict(given)


class MRDamperEnv(gym.Env, ABC):
    """Base of the MR-damper environments: a linear plant with MR dampers, stepped at ``dt``, controlled at
    ``control_dt``.

    Actions: one command per damper, shape ``(nd,)`` (a scalar or a length-1 sequence is accepted when nd = 1).
    ``action_mode="physical"``: Box [v_min, v_max]^nd in the damper's command unit (V or A, see
    ``command_spec``); ``"normalized"``: Box [−1, 1]^nd, mapped linearly onto [v_min, v_max]. An action outside
    the Box is clipped to it element-wise (``np.clip`` semantics, then mapped in normalised mode: −1 → v_min,
    +1 → v_max) and the applied physical command is reported in ``info["command"]`` (and in the ``"command"``
    sensor). A wrongly shaped or non-finite action raises ``ValueError``. The command is held over the control
    period; the damper sees it through its first-order lag u̇ = −η (u − v).

    Observations: float32 vector of the chosen ``sensors`` in the given order; ``sensor_layout`` lists
    ``(name, slice, unit)``. ``sensor_noise`` adds zero-mean Gaussian noise (std in SI units per sensor, scalar or
    one value per channel) drawn from ``np_random``; ``sensor_delay`` = d control steps delays the whole
    measured vector through a FIFO (the observation at step k is the measurement of step k − d; at reset the
    FIFO holds the initial measurement).

    Termination (``terminated=True``) only for real failures: a damper stroke beyond ``stroke_limit``
    (``info["termination_reason"] = "stroke_limit"``) or a :class:`~mrd_env.SimulationDivergedError`
    (``"diverged: <message>"``; the last finite observation is returned). ``truncated=True`` at
    ``episode_seconds`` or at the end of the disturbance record. At the end of an episode either way,
    ``info["episode_metrics"]`` holds the field's metrics computed from the 1 kHz histories. Every step's info
    has ``t`` (s, time at the end of the step), ``damper_force`` (N, (nd,)) and ``command`` (applied, (nd,)).

    A failure step's reward includes −``reward_weights["termination"]`` per control step left in the episode
    (default 1 per step, the order of an uncontrolled/poor step's cost) so that ending an episode early never
    pays; a diverged step has only that term.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 30}

    # --- set by subclasses ---------------------------------------------------------------------------------
    SENSOR_UNITS: dict[str, str] = {}
    DEFAULT_SENSORS: tuple[str, ...] = ()
    DEFAULT_REWARD_WEIGHTS: dict[str, float] = {}
    DEFAULT_DAMPER_PRESET: str = ""
    DEFAULT_STROKE_LIMIT: float = 0.05
    STROKE_SIGNAL: str = ""
    FILTER_SIGNAL: str | None = None

    def __init__(self, *, damper: str | DamperModel = "spencer_dyke", damper_preset: str | None = None,
                 damper_params: Mapping[str, float] | None = None, dt: float = 1e-3, control_dt: float = 1e-3,
                 episode_seconds: float | None = None, sensors=None, sensor_noise: Mapping | None = None,
                 sensor_delay: int = 0, action_mode: str = "physical",
                 reward_weights: Mapping[str, float] | None = None, stroke_limit: float | None = None,
                 render_mode: str | None = None):
        super().__init__()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        self.render_mode = render_mode
        self.dt = check_scalar("dt", dt, 0.0, 0.1, lo_open=True, unit="s")
        self.control_dt = check_scalar("control_dt", control_dt, 0.0, lo_open=True, unit="s")
        n_sub = int(round(self.control_dt / self.dt))
        if n_sub < 1 or abs(n_sub * self.dt - self.control_dt) > 1e-9 * self.control_dt:
            raise ValueError(f"control_dt must be an integer multiple of dt = {self.dt:g} s (e.g. {self.dt:g}, "
                             f"{2 * self.dt:g}, {5 * self.dt:g} s), got {control_dt!r}")
        self.control_dt = n_sub * self.dt
        self._n_sub = n_sub
        if episode_seconds is not None:
            episode_seconds = check_scalar("episode_seconds", episode_seconds, self.control_dt, unit="s")
        self.episode_seconds = episode_seconds
        if action_mode not in ("physical", "normalized"):
            raise ValueError(f"action_mode must be 'physical' or 'normalized', got {action_mode!r}")
        self.action_mode = action_mode
        self.sensor_delay = self._check_delay(sensor_delay)
        self.stroke_limit = check_scalar("stroke_limit", self.DEFAULT_STROKE_LIMIT if stroke_limit is None
                                         else stroke_limit, 0.0, lo_open=True, unit="m")
        self.reward_weights = self._check_weights(reward_weights)

        # damper, plant (subclass), coupled system
        self.damper = self._make_damper(damper, damper_preset, damper_params)
        self.command_spec = self.damper.command
        self.plant_params, self.linear_plant = self._build_plant()
        self.n_dampers = self.linear_plant.n_dampers
        self._coupled = CoupledPlant(self.linear_plant, self.damper, N=1, n_steps=n_sub, dt=self.dt)
        self._stepper = self._coupled.stepper
        # one compiled kernel signature whatever nd: numba compiles read-only arrays separately, and the
        # stepper's parameter array may be a read-only broadcast (older integrator) -- keep it writable
        if not self._stepper.P.flags.writeable:
            self._stepper.P = np.array(self._stepper.P, order="C")
        self.F_static = self._coupled.F_static

        # signals: G rows, then the command columns, then the filtered column
        sb = _SignalBuilder(self._coupled)
        defs = self._signal_defs(sb)
        self._sig_cols: dict[str, np.ndarray] = {}
        rows, col = [], 0
        for name, G in defs.items():
            self._sig_cols[name] = np.arange(col, col + G.shape[0])
            rows.append(G)
            col += G.shape[0]
        self._G = np.ascontiguousarray(np.vstack(rows)) if rows else np.zeros((0, sb.ncol))
        nsig = self._G.shape[0]
        nd = self.n_dampers
        self._sig_cols["command"] = np.arange(nsig, nsig + nd)
        self._nH = nsig + nd
        if self.FILTER_SIGNAL is not None:
            self._sos = np.ascontiguousarray(self._filter_sos())
            self._fin = int(self._sig_cols[self.FILTER_SIGNAL][0])
            self._fout = self._nH
            self._nH += 1
        else:
            self._sos, self._fin, self._fout = _NO_SOS, -1, -1
        self._zi = np.zeros((self._sos.shape[0], 2))
        self._scols = self._sig_cols[self.STROKE_SIGNAL].astype(np.int64)

        # sensors and spaces
        self.sensors = self._check_sensors(sensors)
        idx, layout, labels, start = [], [], [], 0
        for name in self.sensors:
            cols = self._sig_cols[name]
            idx.append(cols)
            layout.append((name, slice(start, start + cols.size), self._sensor_unit(name)))
            labels += [name] if cols.size == 1 else [f"{name}[{i}]" for i in range(cols.size)]
            start += cols.size
        self._obs_idx = np.concatenate(idx).astype(np.int64) if idx else np.zeros(0, np.int64)
        self.sensor_layout = layout
        self.observation_labels = labels
        self._noise_std = self._check_noise(sensor_noise)
        n_obs = self._obs_idx.size
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(n_obs,), dtype=np.float32)
        cs = self.command_spec
        self._v_min, self._v_max = float(cs.v_min), float(cs.v_max)
        if action_mode == "physical":
            self.action_space = gym.spaces.Box(self._v_min, self._v_max, shape=(nd,), dtype=np.float32)
            self._a_lo, self._a_hi = self._v_min, self._v_max
        else:
            self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(nd,), dtype=np.float32)
            self._a_lo, self._a_hi = -1.0, 1.0
        self._half_range = 0.5 * (self._v_max - self._v_min)
        self._normalized = action_mode == "normalized"
        self._plain_obs = self._noise_std is None and self.sensor_delay == 0
        self._human = render_mode == "human"

        # reward terms (subclass; may be refreshed per record at reset)
        self._rcols = np.zeros(0, np.int64)
        self._rscale = np.zeros(0)
        self._setup_reward()

        # preallocated buffers
        self._V = np.full((1, n_sub, nd), self._v_min)
        self._cmd = np.full(nd, self._v_min)
        self._obs_buf = np.zeros(n_obs)
        self._fifo = np.zeros((self.sensor_delay + 1, n_obs))
        self._fifo_pos = 0
        self._k = 0
        self._n_steps = 0
        self._done = True
        self._H = np.zeros((1, self._nH))
        self._W = np.zeros((1, 2, sb.nw))
        self.record = None
        self._last_obs = np.zeros(n_obs, dtype=np.float32)
        self._renderer = None
        self._last_frame_t = -math.inf
        self._setup_disturbance()

    # --- option checks -------------------------------------------------------------------------------------
    def _make_damper(self, damper, preset, params) -> DamperModel:
        if isinstance(damper, DamperModel):
            if preset is not None:
                raise ValueError("damper_preset applies to a damper model name, not to a DamperModel instance")
            return damper.with_params(**params) if params else damper
        if not isinstance(damper, str):
            raise ValueError(f"damper must be a model name (one of the registered models) or a DamperModel, "
                             f"got {damper!r}")
        cls = damper_class(damper)  # ValueError naming the available models
        if preset is None:
            preset = self.DEFAULT_DAMPER_PRESET if self.DEFAULT_DAMPER_PRESET in cls.presets else None
        elif not isinstance(preset, str) or preset not in cls.presets:
            raise ValueError(f"damper_preset {preset!r} is not a preset of damper model {damper!r}; "
                             f"available: {sorted(cls.presets)}")
        if params is not None and not isinstance(params, Mapping):
            raise ValueError(f"damper_params must be a dict of parameter overrides, got {type(params).__name__}")
        return make_damper(damper, preset, **dict(params or {}))

    @staticmethod
    def _check_delay(d) -> int:
        if isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 0:
            raise ValueError(f"sensor_delay must be an int >= 0 (control steps), got {d!r}")
        return int(d)

    def _check_weights(self, weights) -> dict[str, float]:
        w = dict(self.DEFAULT_REWARD_WEIGHTS)
        for k, v in _check_options("reward_weights", weights, self.DEFAULT_REWARD_WEIGHTS).items():
            w[k] = check_scalar(f"reward_weights[{k!r}]", v, 0.0)
        return w

    def _check_sensors(self, sensors) -> tuple[str, ...]:
        if sensors is None:
            sensors = self.DEFAULT_SENSORS
        if isinstance(sensors, str):
            sensors = (sensors,)
        try:
            sensors = tuple(sensors)
        except TypeError:
            raise ValueError(f"sensors must be a sequence of sensor names, got {sensors!r}") from None
        valid = list(self.SENSOR_UNITS)
        if not sensors:
            raise ValueError(f"sensors must name at least one sensor; valid: {valid}")
        for s in sensors:
            if s not in self.SENSOR_UNITS:
                raise ValueError(f"unknown sensor {s!r}; valid sensors: {valid}")
        if len(set(sensors)) != len(sensors):
            raise ValueError(f"sensors must not repeat a name, got {sensors}")
        return sensors

    def _sensor_unit(self, name: str) -> str:
        if name == "command":
            return self.command_spec.unit
        if name == "damper_states":
            return f"model states {self.damper.state_names} per damper"
        return self.SENSOR_UNITS[name]

    def _check_noise(self, noise) -> np.ndarray | None:
        noise = _check_options("sensor_noise", noise, self.SENSOR_UNITS)
        if not noise:
            return None
        std = np.zeros(self._obs_idx.size)
        layout = {name: sl for name, sl, _ in self.sensor_layout}
        for name, v in noise.items():
            if name not in layout:
                raise ValueError(f"sensor_noise names {name!r}, which is not among the chosen sensors {self.sensors}")
            sl = layout[name]
            a = np.asarray(v, dtype=float) if not isinstance(v, str) else None
            width = sl.stop - sl.start
            if a is None or a.shape not in ((), (width,)) or not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ValueError(f"sensor_noise[{name!r}] must be a finite std >= 0 ({self._sensor_unit(name)}), "
                                 f"scalar or {width} values, got {v!r}")
            std[sl] = a
        return std if np.any(std > 0) else None

    # --- subclass hooks --------------------------------------------------------------------------------------
    @abstractmethod
    def _build_plant(self) -> tuple[Any, LinearPlant]:
        """Implemented by each subclass."""

    @abstractmethod
    def _signal_defs(self, sb: _SignalBuilder) -> dict[str, np.ndarray]:
        """Implemented by each subclass."""

    def _filter_sos(self) -> np.ndarray:
        """Second-order sections of the online comfort filter of ``FILTER_SIGNAL`` (none by default)."""
        return _NO_SOS

    @abstractmethod
    def _setup_reward(self) -> None:
        """Implemented by each subclass."""

    @abstractmethod
    def _setup_disturbance(self) -> None:
        """Implemented by each subclass."""

    @abstractmethod
    def _new_episode(self) -> tuple[Any, np.ndarray | None]:
        """(Record on the dt grid with the plant's input channels in order, initial plant state or None)."""

    @abstractmethod
    def _episode_metrics(self, n_rows: int) -> dict[str, float]:
        """Implemented by each subclass."""

    # --- helpers for subclasses -------------------------------------------------------------------------------
    def signal(self, name: str, n_rows: int | None = None) -> np.ndarray:
        """History of a named signal over the episode so far, (n_rows, width) at ``dt`` from t = 0 (a view)."""
        n = self._row if n_rows is None else n_rows
        return self._H[:n, self._sig_cols[name]]

    @property
    def _row(self) -> int:
        """Number of valid rows of the history (rows 0 .. k·n_sub)."""
        return self._k * self._n_sub + 1

    def output_matrices(self) -> dict[str, np.ndarray]:
        """The observation's linear map for controller design (without noise and delay).

        obs = C @ [q, q̇] + D_F @ F + D_w @ w + d0 for every sensor row except ``command`` and
        ``damper_states`` (whose rows are zero here; ``mask`` marks the rows that are plant outputs). q, q̇ are
        the ``linear_plant`` coordinates, F the damper forces, w its inputs (``linear_plant.input_names``);
        accelerations include the damper inertance and the static preload balance (d0).
        """
        sb = _SignalBuilder(self._coupled)
        nsig = self._G.shape[0]
        hidden = set(self._sig_cols["damper_states"].tolist()) if "damper_states" in self._sig_cols else set()
        mask = np.array([c < nsig and c not in hidden for c in self._obs_idx], dtype=bool)
        G = np.zeros((self._obs_idx.size, sb.ncol))
        G[mask] = self._G[self._obs_idx[mask]]
        nY, nd = sb.nY, sb.nd
        return {"C": G[:, : sb.nq], "D_F": G[:, nY: nY + nd], "D_w": G[:, nY + nd: sb.ncol - 1],
                "d0": G[:, sb.ncol - 1], "mask": mask}

    # --- Gymnasium API -----------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        record, q0 = self._new_episode()
        self.record = record
        n_sub = self._n_sub
        n_avail = record.n_samples - 1
        n_phys = n_avail if self.episode_seconds is None else min(n_avail, int(round(self.episode_seconds / self.dt)))
        n_steps = n_phys // n_sub
        if n_steps < 1:
            raise ValueError(f"the disturbance record ({record.duration:g} s) is shorter than one control period "
                             f"({self.control_dt:g} s)")
        n_rows = n_steps * n_sub + 1
        self._n_steps = n_steps
        self._W = np.ascontiguousarray(self._coupled.inputs(np.asarray(record.data[None, :n_rows])))
        self._H = np.zeros((n_rows, self._nH))
        self._coupled.reset(q0)
        self._zi[:] = 0.0
        self._k = 0
        self._done = False
        self._cmd[:] = self._v_min
        self._V[:] = self._v_min
        # row 0: the plant at rest (static equilibrium), damper at rest with its static force
        y0 = np.concatenate([self._stepper.Y[0], np.full(self.n_dampers, self.F_static), self._W[0, 0]])
        H0 = self._H[0]
        H0[: self._G.shape[0]] = self._G @ y0
        H0[self._sig_cols["command"]] = self._v_min
        self._on_reset()
        self._obs_buf[:] = H0[self._obs_idx]
        obs = self._measure(first=True)
        self._last_frame_t = -math.inf
        if self.render_mode == "human":
            self._render_human()
        return obs, {"t": 0.0, "disturbance": record.name}

    def _on_reset(self) -> None:
        """Per-episode setup after the history exists (e.g. reward references of the record)."""

    def _measure(self, first: bool = False) -> np.ndarray:
        buf = self._obs_buf
        if self._noise_std is not None:
            buf += self._noise_std * self.np_random.standard_normal(buf.size)
        if self.sensor_delay:
            fifo = self._fifo
            if first:
                fifo[:] = buf
                self._fifo_pos = 0
                out = buf
            else:
                p = (self._fifo_pos + 1) % fifo.shape[0]
                fifo[p] = buf
                self._fifo_pos = p
                out = fifo[(p + 1) % fifo.shape[0]]
        else:
            out = buf
        obs = out.astype(np.float32)
        self._last_obs = obs
        return obs

    def _command(self, action) -> None:
        """Validate, clip and map ``action`` into the held command buffers."""
        nd = self.n_dampers
        if type(action) is np.ndarray and action.shape == (nd,) and action.dtype.kind in "fiu":
            a = action
        else:
            raw = np.asarray(action)
            if raw.dtype.kind not in "fiu":  # complex, bool, strings, objects: not a command
                raise ValueError(f"action must be numeric (real numbers) with shape ({nd},), got dtype {raw.dtype}")
            a = raw.astype(np.float64)
            if nd == 1 and a.ndim == 0:
                a = a.reshape(1)
            if a.shape != (nd,):
                raise ValueError(f"action must have shape ({nd},) (one command per damper"
                                 f"{'; a scalar is also accepted' if nd == 1 else ''}), got shape {a.shape}")
        if nd == 1:
            x = float(a[0])
            if not math.isfinite(x):
                raise ValueError(f"action must be finite, got {x!r}")
            x = min(max(x, self._a_lo), self._a_hi)
            if self._normalized:
                x = min(max(self._v_min + (x + 1.0) * self._half_range, self._v_min), self._v_max)
            self._cmd[0] = x
            self._V.fill(x)
            return
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a!r}")
        x = np.clip(a.astype(np.float64), self._a_lo, self._a_hi)
        if self._normalized:
            x = np.clip(self._v_min + (x + 1.0) * self._half_range, self._v_min, self._v_max)
        self._cmd[:] = x
        self._V[0] = x

    def step(self, action):
        if self._done:
            raise RuntimeError("the episode is over (or reset() was never called): call reset() first")
        self._command(action)
        n_sub = self._n_sub
        k0 = self._k * n_sub
        try:
            F, Y = self._stepper.step(self._V, self._W[:, k0: k0 + n_sub + 1])
        except SimulationDivergedError as e:
            return self._diverged(e)
        reward, exceeded = _post(Y, F, self._W, k0, self._cmd, self._G, self._H, self._sos, self._zi, self._fin,
                                 self._fout, self._rcols, self._rscale, self._scols, self.stroke_limit,
                                 self._obs_idx, self._obs_buf)
        self._k += 1
        if self._plain_obs:
            obs = self._last_obs = self._obs_buf.astype(np.float32)
        else:
            obs = self._measure()
        t = (k0 + n_sub) * self.dt
        info = {"t": t, "damper_force": F[0, -1].copy(), "command": self._cmd.copy()}
        truncated = self._k >= self._n_steps
        if exceeded:
            reward -= self.reward_weights["termination"] * (self._n_steps - self._k)
            info["termination_reason"] = "stroke_limit"
            self._end(info)
            truncated = False
        elif truncated:
            self._end(info)
        if self._human and t - self._last_frame_t >= 1.0 / self.metadata["render_fps"]:
            self._render_human()
        return obs, reward, exceeded, truncated, info

    def _end(self, info: dict) -> None:
        self._done = True
        info["episode_metrics"] = self._episode_metrics(self._row)

    def _diverged(self, e: Exception):
        force = self._H[self._row - 1, self._sig_cols["damper_force"]].copy()
        info = {"t": self._k * self._n_sub * self.dt, "damper_force": force, "command": self._cmd.copy(),
                "termination_reason": f"diverged: {e}"}
        reward = -self.reward_weights["termination"] * (self._n_steps - self._k)
        self._end(info)
        return self._last_obs.copy(), float(reward), True, False, info

    # --- rendering ---------------------------------------------------------------------------------------------
    @abstractmethod
    def _make_renderer(self, human: bool):
        """Implemented by each subclass."""

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.record is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode == "rgb_array":
            if self._renderer is None:
                self._renderer = self._make_renderer(human=False)
            return self._renderer.frame()
        self._render_human()
        return None

    def _render_human(self) -> None:
        if self._renderer is None:
            self._renderer = self._make_renderer(human=True)
        self._renderer.show()
        self._last_frame_t = self._k * self._n_sub * self.dt

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
