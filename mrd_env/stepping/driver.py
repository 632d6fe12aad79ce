"""The compiled driver: N coupled systems advanced over one period per call, with everything an environment
does per step (see ``_driver_template.py``), and the same call for the rig and identification.

A :class:`Driver` packs a coupled system (:class:`~mrd_env.stepping.matrices.SystemMatrices` and a damper model)
and a :class:`Processing` — the named outputs h = G·[Y, F, W], online filters, reward terms, limits, constraint
costs, statistics and measurements — into four arrays (float and int constants, float and int per-system state),
so that one ``env.step`` is one compiled call with eight arguments (numba's dispatch costs about 30 ns per
argument). Where each thing lives in those arrays is defined once, in :mod:`mrd_env.stepping.layout`, which the
kernel imports.

Per-system state (one row of ``fs`` and ``is_`` per system, plus one scratch row for the kernel): the coupled
state Y, the effective commands U, the forces F, the damper parameters P and command dynamics (η_rise, η_fall,
delay τ; so every system may have its own damper), the queue of past commands the delay reads, the applied
command, the filter states, the reward scales, the statistics, the ring of the running r.m.s., the
delay/history FIFO, the last output row and the last reward, the constraint costs (the last period's and the
episode's) and the control power; the step counters, the status, the noise generator's key and counter, the
position in the command queue.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..command_lag import LAG_DELAY, check_lag, queue_length
from ..validation import check_scalar
from .codegen import kernel_module
from .layout import HIST_NONE, LAYOUT, T_FAIL_STEP, T_REASON, T_STATUS, TRUNCATED, pack
from .matrices import SystemMatrices
from .scheme import ATOL, MAX_SUBSTEPS, RTOL, max_level_of

PARALLEL_FROM = 64  # systems from which a batch runs on numba's threads by default


@dataclass
class Processing:
    """What the driver computes from the physics at every step and period (all optional; the rig uses only the
    outputs and the history).

    * ``G`` (nsig, n + nd + nw): the named outputs h = G·[Y, F, W] (columns nsig..nsig+nd of a row hold the
      applied command, then ``n_extra`` columns written by the filters).
    * ``filters``: (input column, output column, second-order sections (k, 6) in scipy's layout).
    * ``reward_cols`` with per-system ``reward_scales`` (N, len): reward = −mean over the period of
      Σ_i scale_i·h[col_i]²; ``penalty`` (a constant, and an amount per period of the episode's planned length)
      is subtracted when a limit is hit.
    * ``limit_cols``/``limits``: |h[col]| > limit terminates the episode.
    * ``cost_cols`` with ``cost_limits`` and ``cost_sides`` (0: |h| > limit, +1: h > limit, −1: h < −limit),
      grouped into terms by ``cost_terms`` (the first column of each term, then the column count): per step,
      the time (s) of the period's rows at which a constraint of each term is violated, and of those at which
      any is (field COST: [any, term 1..T] of the last period, then their episode totals).
    * ``power_cols``: (force column, velocity column) pairs: the peak over the rows of Σ |h[f]·h[v]| and its
      sum over the episode's rows (field POWER; × dt the energy).
    * ``stat_cols``: running sum of squares and peak of |h|; ``dose_col``: running Σ h⁴ and the maximum of the
      running r.m.s. over ``dose_window`` steps (the ISO 2631 VDV and MTVV of a weighted acceleration).
    * ``meas_cols`` with ``noise_std``: the measured columns; ``delay`` (periods) and ``history`` (periods
      stacked in the observation, oldest first).
    * ``history_mode``: HIST_NONE, HIST_FULL (every row of the episode into H) or HIST_PERIOD (the rows of the
      last period); ``command_input``: a column of W holding the command (the rig), else the action.
    """

    G: np.ndarray
    n_extra: int = 0
    filters: list = field(default_factory=list)
    reward_cols: tuple = ()
    limit_cols: tuple = ()
    limits: tuple = ()
    penalty: tuple = (0.0, 0.0)
    stat_cols: tuple = ()
    dose_col: int = -1
    dose_window: int = 1
    meas_cols: tuple = ()
    noise_std: tuple | None = None
    delay: int = 0
    history: int = 1
    history_mode: int = HIST_NONE
    command_input: int = -1
    normalized: bool = False
    cost_cols: tuple = ()
    cost_limits: tuple = ()
    cost_sides: tuple = ()
    cost_terms: tuple = (0,)
    power_cols: tuple = ()


class Driver:
    """N systems of one damper model on one plant, advanced by the compiled driver (see the module docstring).

    ``P`` (N, nd, n_params) and ``lag`` (N, nd, 3: η_rise, η_fall, delay; :mod:`mrd_env.command_lag`) give
    every system its own damper parameters and command dynamics (default: the damper's). :meth:`reset` starts
    episodes (``mask``), :meth:`step` advances the running systems by ``n_sub`` steps of ``dt`` and returns
    system 0's status.
    """

    def __init__(self, damper, system: SystemMatrices, N: int, processing: Processing, *, dt: float = 1e-3,
                 n_sub: int = 1, v_range: tuple[float, float] | None = None, P=None, lag=None,
                 max_substeps: int = MAX_SUBSTEPS, rtol: float = RTOL, atol: float = ATOL, threads: int | None = None):
        self.damper = damper
        self.system = system
        self.processing = pr = processing
        self.N = N = int(N)
        self.dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
        self.n_sub = int(n_sub)
        self.max_substeps = int(check_scalar("max_substeps", max_substeps, 1, 4096))
        rtol = check_scalar("rtol", rtol, 0.0, lo_open=True)
        atol = check_scalar("atol", atol, 0.0, lo_open=True)
        max_level = max_level_of(self.max_substeps)
        self.kernel = kernel_module(type(damper))
        nd, nw, nq = system.nd, system.nw, system.nq
        ns = damper.n_states
        n = nq + nd * ns
        self.n = n
        G = np.ascontiguousarray(pr.G, dtype=np.float64)
        if G.shape[1] != n + nd + nw:
            raise ValueError(f"G must have {n + nd + nw} columns (states, forces, inputs), got {G.shape}")
        nsig = G.shape[0]
        self.nH = nH = nsig + nd + pr.n_extra
        sos = np.vstack([np.asarray(f[2], dtype=np.float64) for f in pr.filters]) if pr.filters else np.zeros((0, 6))
        filt, k = [], 0
        for col_in, col_out, s in pr.filters:
            filt.append((col_in, col_out, k, len(s)))
            k += len(s)
        cmd = damper.command
        v_min, v_max = v_range if v_range is not None else (cmd.v_min, cmd.v_max)
        scal = {"DT": self.dt, "VMIN": v_min, "VMAX": v_max, "RTOL": rtol, "ATOL": atol,
                "PEN_CONST": pr.penalty[0], "PEN_STEP": pr.penalty[1]}
        n_meas = len(pr.meas_cols)
        noise = np.zeros(n_meas) if pr.noise_std is None else np.asarray(pr.noise_std, dtype=np.float64)
        floats = {"C": system.C, "D": system.D, **dict(zip(("AINV", "BBAR", "MQ", "PP"),
                                                             system.levels(self.dt, max_level))),
                  "G": G, "SOS": sos, "SCAL": np.array([scal[s] for s in LAYOUT["scalars"]]), "NOISE": noise,
                  "LIMITS": np.asarray(pr.limits, dtype=np.float64),
                  "CLIMITS": np.asarray(pr.cost_limits, dtype=np.float64)}
        ints = {"MEAS": pr.meas_cols, "RCOLS": pr.reward_cols, "LCOLS": pr.limit_cols, "STAT_COLS": pr.stat_cols,
                "FILTERS": np.asarray(filt, dtype=np.int64).reshape(-1, 4), "CCOLS": pr.cost_cols,
                "CSIDES": pr.cost_sides, "CTERMS": pr.cost_terms,
                "PCOLS": np.asarray(pr.power_cols, dtype=np.int64).reshape(-1, 2)}
        self.n_cost_terms = n_terms = _check_costs(pr, nsig + nd + pr.n_extra)
        npar = damper.params.as_array().size
        self.threads = self._threads(threads)
        dims = {"N": n, "NH": nH, "NPAR": npar, "NSUB": self.n_sub, "MAX_LEVEL": max_level,
                "HIST_MODE": pr.history_mode, "CMD_INPUT": pr.command_input, "DOSE_COL": pr.dose_col,
                "NORMALIZED": int(pr.normalized), "DELAY": int(pr.delay), "HISTORY": int(pr.history),
                "SCRATCH": self.threads}
        depth = pr.delay + pr.history
        lag = np.broadcast_to(cmd.lag_vector() if lag is None else np.asarray(lag, dtype=np.float64), (N, nd, 3))
        check_lag(lag)
        self.queue_length = queue_length(lag[..., LAG_DELAY], self.dt)
        sizes = {"Y": n, "U": nd, "F": nd, "P": nd * npar, "LAG": 3 * nd, "CMDQ": self.queue_length * nd, "CMD": nd,
                 "ZI": 2 * len(sos),
                 "RSCALE": len(pr.reward_cols), "STATS": 2 * len(pr.stat_cols), "DOSE": 3,
                 "RING": max(int(pr.dose_window), 1), "FIFO": depth * n_meas, "ROW": nH, "REWARD": 1,
                 "COST": 2 * (n_terms + 1), "POWER": 2}
        self.fc, self.ic, self._fields = pack(floats, ints, dims, sizes)
        wf, wi = self.kernel.workspace_len(nq, nd, n, nw)
        width = max(sum(sizes.values()), int(wf))
        # the last rows are the kernel's scratch, one per thread
        self.fs = np.zeros((N + self.threads, width))
        self.is_ = np.zeros((N + self.threads, max(len(LAYOUT["int_state"]), int(wi))), dtype=np.int64)
        self.obs = np.zeros((N, pr.history * n_meas), dtype=np.float32)
        self.n_obs = pr.history * n_meas
        p = damper.params.as_array()
        self.state("P")[:] = (np.broadcast_to(p, (N, nd, npar)) if P is None else np.asarray(P, float)).reshape(N, -1)
        self.state("LAG")[:] = lag.reshape(N, 3 * nd)
        self.W = np.zeros((N, 2, nw))
        self.H = np.zeros((N, 0, nH))
        self.is_[:N, T_STATUS] = TRUNCATED  # nothing runs before a reset

    # --- named views --------------------------------------------------------------------------------------------
    def state(self, name: str) -> np.ndarray:
        """The per-system float field ``name`` (N, length), a view."""
        o, k = self._fields[name]
        return self.fs[:self.N, o:o + k]

    def int_state(self, name: str) -> np.ndarray:
        """The per-system int field ``name`` (N,), a view."""
        return self.is_[:self.N, LAYOUT["int_state"].index(name)]

    # --- episodes -------------------------------------------------------------------------------------------------
    def set_inputs(self, W: np.ndarray, n_steps, history_rows: int = 0) -> None:
        """The input records W (N, rows, nw) of the next episodes, their lengths in periods and the rows of the
        history buffer (HIST_FULL: the episode's rows; HIST_PERIOD: n_sub)."""
        self.W = np.ascontiguousarray(W, dtype=np.float64)
        self.int_state("NSTEPS")[:] = n_steps
        if self.H.shape[1] != history_rows:
            self.H = np.zeros((self.N, history_rows, self.nH))

    def reset(self, mask=None, *, Y0=None, U0=None, keys=None) -> None:
        """Start episodes for the systems in ``mask`` (default: all) from the states ``Y0`` (N, n) and effective
        commands ``U0`` (N, nd; default v_min), zero filter states, with noise generator ``keys`` (N,)."""
        mask = np.ones(self.N, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        Y = self.state("Y")
        Y[mask] = 0.0 if Y0 is None else np.asarray(Y0, dtype=np.float64)[mask]
        self.state("U")[mask] = self.damper.command.v_min if U0 is None else np.asarray(U0, dtype=np.float64)[mask]
        self.state("ZI")[mask] = 0.0
        if keys is not None:
            self.int_state("KEY")[mask] = np.asarray(keys, dtype=np.int64)[mask]
        self.kernel.core_reset(self.fc, self.ic, self.fs, self.is_, self.W, self.H, self.obs, mask)

    def step(self, action: np.ndarray) -> int:
        """Advance the running systems by one period with ``action`` (N·nd,) float64; system 0's status."""
        if self.threads > 1:
            return self.kernel.core_step_parallel(self.fc, self.ic, self.fs, self.is_, self.W, self.H, action,
                                                  self.obs)
        return self.kernel.run_systems(self.fc, self.ic, self.fs, self.is_, self.W, self.H, action, self.obs,
                                       self.N, 0, self.N)

    def _threads(self, threads) -> int:
        """Threads of the parallel step: the given count, else numba's threads for batches of 64 systems or
        more (below that, starting threads costs more than it saves), never more than the systems."""
        import numba

        if threads is None:
            threads = numba.get_num_threads() if self.N >= PARALLEL_FROM else 1
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise ValueError(f"threads must be an int >= 1, got {threads!r}")
        return int(min(threads, self.N))

    def failure(self, b: int) -> tuple[int, float]:
        """(status code of the integrator, time in s) of system b's divergence."""
        return int(self.is_[b, T_REASON]), (int(self.is_[b, T_FAIL_STEP]) + 1) * self.dt


def _check_costs(pr: Processing, width: int) -> int:
    """The number of cost terms of ``pr``, after a ``ValueError`` for an inconsistent description."""
    n = len(pr.cost_cols)
    terms = [int(k) for k in pr.cost_terms]
    if len(pr.cost_limits) != n or len(pr.cost_sides) != n:
        raise ValueError(f"cost_limits and cost_sides must have one entry per cost column ({n}), got "
                         f"{len(pr.cost_limits)} and {len(pr.cost_sides)}")
    if not terms or terms[0] != 0 or terms[-1] != n or any(b < a for a, b in zip(terms, terms[1:])):
        raise ValueError(f"cost_terms must rise from 0 to the number of cost columns ({n}), got {pr.cost_terms}")
    if any(s not in (-1, 0, 1) for s in pr.cost_sides):
        raise ValueError(f"cost_sides must be -1, 0 or 1, got {pr.cost_sides}")
    cols = [int(c) for c in pr.cost_cols] + [int(c) for pair in pr.power_cols for c in pair]
    if any(not 0 <= c < width for c in cols) or any(len(pair) != 2 for pair in pr.power_cols):
        raise ValueError(f"cost and power columns must be columns of the output row (0..{width - 1}), and power "
                         f"columns (force, velocity) pairs")
    return len(terms) - 1


def noise_keys(rngs) -> np.ndarray:
    """One 63-bit key per generator (the noise of each system's episode, drawn from its own generator)."""
    return np.array([int(r.integers(0, 2 ** 63 - 1)) for r in rngs], dtype=np.int64)
