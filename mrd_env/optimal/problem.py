"""One episode of an environment as an optimisation problem: the data every yardstick solver shares.

The clairvoyant optimum (:mod:`.clairvoyant`) and the active-actuator bound (:mod:`.bound`) both need the same
facts about one seeded episode, taken from the environment itself so that they cannot drift from it:

* the coupled plant ẋ = A x + B_F F + B_w w over x = [q, q̇] (damper inertance included; the last input channel
  is the constant that balances the damper's static preload, so F is the total damper force);
* the whole disturbance W (n_rows × n_w, sample r at t = r·dt) and the initial state x0;
* the reward as quadratic terms: the return of an episode that ends normally is

      R = −Σ_{r=1}^{n_rows−1} Σ_terms Σ_i weight_i · s_i(r)²,   s = G·[x_r, F_r, W_r]

  passed first through the term's causal filter (second-order sections, zero initial conditions, as the
  environment's online ISO 2631 Wk filter) when it has one; ``weight`` already holds dt and the episode's scale
  (e.g. the passive car's mean squares on the same road);
* the limits (|G·[x, F, W]| ≤ bound, else the episode terminates with a penalty).

:meth:`EpisodeProblem.replay` re-simulates a command sequence in a fresh environment: the only return a
yardstick reports is the one the environment gives.

Layering: ``mrd_env`` never imports ``controllers`` or ``experiments``. A solver here takes its warm starts as
command arrays, ``{name: (n_steps, nd)}``; the caller (``experiments.benchmark.yardstick``) gets them from the laws and
agents with :meth:`EpisodeProblem.commands_of` and a factory ``env → controller``.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..dampers import DamperModel


@dataclass(frozen=True)
class CostTerm:
    """Rows ``G`` over [x, F, W] of a reward signal, their weights (dt and the episode scale included) and the
    causal filter the signal passes through first (``sos``, or None)."""

    name: str
    G: np.ndarray
    weight: np.ndarray
    sos: np.ndarray | None = None


@dataclass(frozen=True)
class Limit:
    """|G·[x, F, W]| ≤ bound at every physics step, else the episode terminates."""

    name: str
    G: np.ndarray
    bound: float


@dataclass
class Trajectory:
    """An episode re-simulated in the environment: its return, whether a limit or divergence ended it, the
    commands applied (n_steps, nd), and per physics row r = 0..n_rows−1 the plant state ``X`` (n_rows, nx), the
    full state with the damper's internal states ``Y`` (n_rows, nY), the damper forces ``F`` (n_rows, nd, total,
    preload included) and the effective (lagged) command ``U`` (n_rows, nd). Rows after an early end are NaN."""

    ret: float
    terminated: bool
    reason: str
    commands: np.ndarray
    X: np.ndarray | None = None
    Y: np.ndarray | None = None
    F: np.ndarray | None = None
    U: np.ndarray | None = None
    metrics: dict = field(default_factory=dict)


@dataclass(frozen=True)
class EpisodeProblem:
    """One seeded episode of ``env_id`` with ``options`` (see the module docstring); build it with
    :func:`episode_problem`."""

    env_id: str
    options: dict
    seed: int
    dt: float
    control_dt: float
    n_sub: int
    n_steps: int
    A: np.ndarray
    BF: np.ndarray
    Bw: np.ndarray
    Cx: np.ndarray
    Cv: np.ndarray
    W: np.ndarray
    x0: np.ndarray
    damper: DamperModel
    F_static: float
    terms: tuple[CostTerm, ...]
    limits: tuple[Limit, ...]
    penalty: float
    episode_name: str

    # --- sizes ---------------------------------------------------------------------------------------------------
    @property
    def n_rows(self) -> int:
        return self.n_steps * self.n_sub + 1

    @property
    def nx(self) -> int:
        return self.A.shape[0]

    @property
    def nd(self) -> int:
        return self.BF.shape[1]

    @property
    def nw(self) -> int:
        return self.Bw.shape[1]

    @property
    def v_min(self) -> float:
        return float(self.damper.command.v_min)

    @property
    def v_max(self) -> float:
        return float(self.damper.command.v_max)

    @property
    def duration(self) -> float:
        return self.n_steps * self.control_dt

    # --- the reward ----------------------------------------------------------------------------------------------
    def linear_return(self, X: np.ndarray, F: np.ndarray) -> float:
        """The return of plant states ``X`` (n_rows, nx) and damper forces ``F`` (n_rows, nd) on this episode's
        disturbance, by the reward's quadratic terms (no limits: the return of an episode that ends normally)."""
        import scipy.signal

        X = np.asarray(X, dtype=float)
        F = np.asarray(F, dtype=float).reshape(len(X), self.nd)
        if X.shape != (self.n_rows, self.nx):
            raise ValueError(f"X must have shape {(self.n_rows, self.nx)}, got {X.shape}")
        Z = np.hstack([X, F, self.W])[1:]
        total = 0.0
        for term in self.terms:
            S = Z @ term.G.T
            if term.sos is not None:
                S = scipy.signal.sosfilt(term.sos, S, axis=0)
            total += float(np.sum(S ** 2 @ term.weight))
        return -total

    # --- the environment -----------------------------------------------------------------------------------------
    def make_env(self, control_dt: float | None = None, **overrides):
        """A fresh scalar environment of this episode's set-up (physical commands), not yet reset."""
        import gymnasium as gym

        opts = {**self.options, "control_dt": self.control_dt if control_dt is None else control_dt, **overrides}
        return gym.make(self.env_id, **opts).unwrapped

    def replay(self, commands, states: bool = False) -> Trajectory:
        """Apply ``commands`` (n_steps, nd) (V or A), each held over its control step, in a fresh environment
        reset with this episode's seed: the return the environment gives. ``states``: also record the state
        and force at every physics row (the environment then steps at dt; the physics is the same)."""
        U = self.check_commands(commands)
        if not states:
            env = self.make_env()
            env.reset(seed=self.seed)
            total, info, term = 0.0, {}, False
            for k in range(self.n_steps):
                _, r, term, trunc, info = env.step(U[k])
                total += r
                if term or trunc:
                    break
            return Trajectory(total, bool(term), info.get("termination_reason", ""), U,
                              metrics=info.get("episode_metrics", {}))
        env = self.make_env(control_dt=self.dt)
        env.reset(seed=self.seed)
        drv = env.core.driver
        nY = drv.state("Y").shape[1]
        X = np.full((self.n_rows, self.nx), np.nan)
        Y = np.full((self.n_rows, nY), np.nan)
        F = np.full((self.n_rows, self.nd), np.nan)
        Ue = np.full((self.n_rows, self.nd), np.nan)
        Y[0] = drv.state("Y")[0]
        F[0] = env.damper_force
        Ue[0] = drv.state("U")[0][:self.nd]
        total, info, term = 0.0, {}, False
        for r in range(1, self.n_rows):
            _, rew, term, trunc, info = env.step(U[(r - 1) // self.n_sub])
            total += rew
            Y[r] = drv.state("Y")[0]
            F[r] = env.damper_force
            Ue[r] = drv.state("U")[0][:self.nd]
            if term or trunc:
                break
        X[:] = Y[:, :self.nx]
        return Trajectory(total, bool(term), info.get("termination_reason", ""), U, X, Y, F, Ue,
                          info.get("episode_metrics", {}))

    def commands_of(self, make: Callable, control_dt: float | None = None, **env_overrides) -> np.ndarray:
        """The commands a controller applies on this episode, (n_steps, nd) at this problem's control step.

        ``make(env)`` builds the controller (a law or an agent's ``bind``) on the environment it drives, which
        runs at ``control_dt`` (default this problem's; a multiple of it, e.g. an agent's 10 ms on a 1 ms
        problem, whose commands are then repeated) with ``env_overrides`` (e.g. an agent's observation options).
        """
        cdt = self.control_dt if control_dt is None else float(control_dt)
        ratio = cdt / self.control_dt
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(f"control_dt must be a multiple of the problem's control step {self.control_dt:g} s, "
                             f"got {cdt:g} s")
        m = int(round(ratio))
        opts = {k: v for k, v in env_overrides.items()}
        opts.setdefault("action_mode", self.options.get("action_mode", "physical"))
        env = self.make_env(control_dt=cdt, **opts)
        ctrl = make(env)
        obs, _ = env.reset(seed=self.seed)
        if hasattr(ctrl, "reset"):
            ctrl.reset()
        out = []
        while True:
            a, _ = ctrl.predict(obs, deterministic=True)
            obs, _, term, trunc, _ = env.step(a)
            out.append(env.command.copy())
            if term or trunc:
                break
        C = np.repeat(np.array(out), m, axis=0)[:self.n_steps]
        if len(C) < self.n_steps:  # an episode ended early: hold the last command
            C = np.vstack([C, np.repeat(C[-1:], self.n_steps - len(C), axis=0)])
        return C

    def check_commands(self, commands) -> np.ndarray:
        """``commands`` as a float (n_steps, nd) array within [v_min, v_max], else ValueError."""
        U = np.asarray(commands, dtype=float)
        if U.ndim == 1 and self.nd == 1:
            U = U[:, None]
        if U.shape != (self.n_steps, self.nd):
            raise ValueError(f"commands must have shape ({self.n_steps}, {self.nd}) (one per control step and "
                             f"damper), got {U.shape}")
        if not np.all(np.isfinite(U)):
            raise ValueError("commands must be finite")
        tol = 1e-9 * max(1.0, abs(self.v_max))
        if U.min() < self.v_min - tol or U.max() > self.v_max + tol:
            raise ValueError(f"commands must lie in [{self.v_min:g}, {self.v_max:g}] "
                             f"{self.damper.command.unit}, got [{U.min():g}, {U.max():g}]")
        return np.clip(U, self.v_min, self.v_max)

    def key(self) -> dict:
        """What identifies this episode (for caches): the environment, its options, the seed and steps, and the
        damper's parameters and command channel."""
        d = self.damper
        return {"env_id": self.env_id, "options": _jsonable(self.options), "seed": self.seed, "dt": self.dt,
                "control_dt": self.control_dt, "n_steps": self.n_steps, "damper": d.name,
                "damper_params": _jsonable(vars(d.params) if hasattr(d.params, "__dict__") else d.params),
                "command": _jsonable(vars(d.command)), "episode": self.episode_name}


def sos_state_space(sos: np.ndarray):
    """(A, B, C, D) of a cascade of second-order sections in transposed direct form II, the realisation of
    ``scipy.signal.sosfilt`` and of the environment's online filters (zero initial state = its zero initial
    conditions), ξ_r = A ξ_{r−1} + B u_r, y_r = C ξ_{r−1} + D u_r::

        y = b0 u + s1,   s1' = (b1 − a1 b0) u − a1 s1 + s2,   s2' = (b2 − a2 b0) u − a2 s1
    """
    sos = np.atleast_2d(np.asarray(sos, dtype=float))
    A = np.zeros((0, 0))
    B, C, D = np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))
    for row in sos:
        b, a = row[:3] / row[3], row[3:] / row[3]
        As = np.array([[-a[1], 1.0], [-a[2], 0.0]])
        Bs = np.array([[b[1] - a[1] * b[0]], [b[2] - a[2] * b[0]]])
        Cs, Ds = np.array([[1.0, 0.0]]), np.array([[b[0]]])
        n = A.shape[0]  # the section is fed by the cascade so far: u_s = C x + D u
        A = np.block([[A, np.zeros((n, 2))], [Bs @ C, As]])
        B = np.vstack([B, Bs @ D])
        C = np.hstack([Ds @ C, Cs])
        D = Ds @ D
    return A, B, C, D


def episode_problem(env_id: str, *, seed: int, control_dt: float | None = None, **env_options) -> EpisodeProblem:
    """The episode of ``env_id`` with ``env_options`` reset with ``seed``, as an :class:`EpisodeProblem`.

    ``control_dt`` defaults to the environment's. The action mode is set to physical commands (the problem's
    unknowns are the commands; observation options do not change the physics and are kept for the controllers
    of :meth:`EpisodeProblem.commands_of`). ``ValueError`` for a reward that is not quadratic (a Python callable)
    or that weighs the command.
    """
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an int, got {seed!r}")
    if env_options.get("action_mode", "physical") == "force":
        raise ValueError("action_mode 'force' turns actions into commands through an inverse model; the optimum "
                         "is over commands: use action_mode 'physical' or 'normalized'")
    opts = dict(env_options)
    if control_dt is not None:
        opts["control_dt"] = control_dt
    opts["action_mode"] = "physical"
    env = gym.make(env_id, **opts).unwrapped
    env.reset(seed=int(seed))
    asm, core = env.assembly, env.core
    if core.python_reward:
        raise ValueError("the yardstick needs the environment's quadratic reward; a Python callable reward has no "
                         "known structure to optimise")
    sys_ = asm.coupled.system
    sig = asm.signals
    nq = 2 * asm.linear_plant.n_dof
    nY = sig.nY
    G_all = sig.G

    def rows_over_xfw(col: int) -> np.ndarray:
        g = G_all[col]
        if np.any(g[nq:nY]):
            raise ValueError("a reward or limit signal depends on the damper's internal states; the yardstick needs "
                             "signals linear in the plant state, the forces and the inputs")
        return np.concatenate([g[:nq], g[nY:]])

    filt = {int(sig[o].columns[0]): (int(sig[i].columns[0]), sos) for i, o, sos in asm.filters}
    rcols, _ = asm.reward.bind(sig)
    rscale = np.array(core.driver.state("RSCALE")[0], dtype=float)
    n_sub = asm.n_sub
    by_name = {int(c): name for name, s in sig.signals.items() for c in s.columns}
    terms: list[CostTerm] = []
    for i, col in enumerate(rcols):
        col, name, sos = int(col), by_name.get(int(col), str(col)), None
        if col in filt:
            col, sos = filt[col][0], np.asarray(filt[col][1], dtype=float)
        if col >= G_all.shape[0]:
            raise ValueError(f"the reward weighs {name!r}, which is not a linear output of the plant")
        g, w = rows_over_xfw(col)[None], np.array([rscale[i] / n_sub])
        if terms and terms[-1].name == name and sos is None and terms[-1].sos is None:  # a signal's channels
            g, w = np.vstack([terms[-1].G, g]), np.concatenate([terms[-1].weight, w])
            terms.pop()
        terms.append(CostTerm(name, g, w, sos))
    lcols, lim = asm.limits.bind(sig)
    limits = tuple(Limit(by_name.get(int(c), str(c)), rows_over_xfw(int(c)), float(b)) for c, b in zip(lcols, lim))
    n_steps = int(core._n_steps[0])
    n_rows = n_steps * n_sub + 1
    W = np.array(core.driver.W[0, :n_rows], dtype=float)
    x0 = np.array(core.driver.state("Y")[0, :nq], dtype=float)
    return EpisodeProblem(env_id=env_id, options=opts, seed=int(seed), dt=asm.dt, control_dt=asm.control_dt,
                          n_sub=n_sub, n_steps=n_steps, A=np.array(sys_.A), BF=np.array(sys_.BF),
                          Bw=np.array(sys_.Bw), Cx=np.array(sys_.Cx), Cv=np.array(sys_.Cv), W=W, x0=x0,
                          damper=asm.damper, F_static=float(asm.coupled.F_static), terms=tuple(terms),
                          limits=limits, penalty=float(asm.limits.amount(n_steps * asm.control_dt)),
                          episode_name=str(env.record.name))


def _jsonable(x):
    """Options as JSON-ready values (tuples → lists, numpy → Python, other objects → their repr)."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else repr(float(x))
    if isinstance(x, (int, str, bool)) or x is None:
        return x
    return repr(x)
