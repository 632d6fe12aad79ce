"""Linear model-predictive control of the damper force, clipped to what a semi-active damper can do.

At every control step k the law solves, from the Kalman estimate x̂[k] (:class:`~.model_based.ObserverLaw`),
the finite-horizon problem over H control periods T = ``control_dt``::

    min_{f_0..f_{H−1}}  Σ_{j<H} ∫_{jT}^{(j+1)T} zᵀz + fᵀR₀f dt  +  (x_H − x_ss)ᵀ P (x_H − x_ss),     |f_j| ≤ f_max
    ẋ = A x + B_f f + B_w w,   z = C_z x + D_z f,   x(0) = x̂[k]

— ClippedOptimal's LQ cost (the environment's ``objective`` weights, or with ``weights="reward"`` the reward's own
terms over fixed nominal scales, :func:`~.model_based.reward_weights`; R₀ = 1/force_ref²; z may depend on w too,
z = C_z x + D_z f + D_zw w, the car's tyre load) integrated exactly over
each period with the force held (Van Loan 1978; :func:`~.model_based.van_loan`), P the discrete Riccati
solution of the same sampled-data problem (so that without active bounds and known inputs the law is the
infinite-horizon sampled-data LQR for any H; Rawlings, Mayne & Diehl, Model Predictive Control, 2nd ed., §2.5),
x_ss the equilibrium under the last known input (the road height at the end of the horizon; 0 without preview
and in the road frame),
the disturbance w known over the horizon (a road preview) or zero. The QP is condensed onto the forces (Maciejowski,
Predictive Control with Constraints, §3.1), solved by OSQP (Stellato et al. 2020) warm-started from the last
step, one problem per batch row; f_0 is the desired force f_c, turned into the command by the clipped on–off law
u = u_max·H((f_c − f)·f) as :class:`~.model_based.ClippedOptimal` (or by its ``inverse``).

OSQP is imported the first time a bound binds (or options for it are given): ``import controllers`` does not need
it.
"""
from __future__ import annotations

import numpy as np

from .model_based import ClippedOptimal, dlqr, road_inputs, van_loan

#: The representative stroke velocity amplitude (m/s) of the default force bound (see :func:`damper_force_limit`).
F_MAX_VELOCITY = 0.1


def damper_force_limit(env, velocity: float = F_MAX_VELOCITY) -> float:
    """A damper's force capacity beyond its static preload (N): the peak |F − F_static| over a steady cycle of
    a sinusoidal stroke at the maximum command, with velocity amplitude ``velocity`` at the plant's lowest
    undamped natural frequency (:func:`mrd_env.rig.sinusoidal_test`). At 0.1 m/s: 857 N for the quarter car's
    automotive Spencer–Dyke damper (1.25 Hz), 1260 N for the building's prototype (5.46 Hz)."""
    from scipy.linalg import eigh

    from mrd_env.rig import sinusoidal_test
    from mrd_env.validation import check_scalar

    base = getattr(env, "unwrapped", env)
    velocity = check_scalar("velocity", velocity, 0.0, lo_open=True, unit="m/s")
    lp = base.linear_plant
    omega = float(np.sqrt(eigh(lp.K, lp.M, eigvals_only=True)[0]))
    freq = omega / (2.0 * np.pi)
    d = base.damper
    res = sinusoidal_test(d, velocity / omega, freq, commands=(d.command.v_max,), cycles=3.0, dt=base.dt)[0]
    return float(np.max(np.abs(res.force[res.steady_cycles(freq)] - base.F_static)))


class MPC(ClippedOptimal):
    """Linear MPC of the damper forces (see the module docstring), clipped on–off.

    Options: ``horizon`` H (control periods, 1..500, default 10); ``f_max`` (N, the bound on |f_j| beyond the
    preload; default :func:`damper_force_limit`, the damper's force at the maximum command at a stroke velocity
    of 0.1 m/s); ``preview``: use the sensors of the road ahead for w over the horizon, each wheel's road inputs
    (z_r, ż_r) of its own readings (:meth:`_road_readings`: ``road_preview``, the road heights at
    ``env.preview_times`` ahead of every wheel; the full car's ``wheelbase_preview`` of the rear wheels, the front
    wheels' past) — None (default) when one is measured, True (required), False (w = 0); ``terminal``:
    "riccati" (default, P above) or "zero" (no terminal cost: the finite-horizon LQR, for checks);
    ``osqp``: OSQP settings overriding the defaults. ``weights`` (None: the environment's objective; "reward":
    the reward's own terms, see :class:`~.model_based.ClippedOptimal`), ``force_ref``, ``frame``, ``inverse`` and
    the observer's options as :class:`~.model_based.ClippedOptimal`.

    ``weights="reward"`` on the car, tuned on the validation roads (``experiments.common.scenarios.validation``): the
    road frame, ``f_max=1e5`` (a bound that never binds: the default 857 N cuts the desired force below what the damper
    gives, and the on–off law then releases the damper), ``force_ref`` 1000 N at a 1 ms control step and 200 N at 10 ms,
    with preview a horizon that spans it (1 ms: H = 100; 10 ms: H = 10). On the held-out ISO C/D roads at 20 m/s: at
    1 ms −9.11/−9.04 without preview (skyhook_continuous −9.13/−9.06, the objective's MPC −9.34/−9.76) and −7.97/−7.80
    with it (objective, H = 100: −9.25/−9.27); at 10 ms −9.20/−9.12 with preview (objective −9.87/−9.89), but
    −10.50/−10.23 without (objective −10.29/−10.15, skyhook −9.27/−9.23): at a 10 ms step no force_ref beats the
    objective's weights both on validation and on test, so the default stays the objective.

    With preview the road (the samples of this and the earlier readings, linearly interpolated to the horizon's
    period boundaries: :meth:`road_ahead`) is a known input, first-order hold between period boundaries, both in
    the prediction and in the Kalman filter's time update. The horizon spans H·control_dt: at 1 ms and H = 10 it sees
    10 ms of a preview that may reach further.
    """

    name = "mpc"

    def __init__(self, env, horizon: int = 10, f_max: float | None = None, preview: bool | None = None,
                 terminal: str = "riccati", osqp: dict | None = None, **options):
        if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or not 1 <= horizon <= 500:
            raise ValueError(f"horizon must be an integer number of control periods in [1, 500], got {horizon!r}")
        if terminal not in ("riccati", "zero"):
            raise ValueError(f"terminal must be 'riccati' or 'zero', got {terminal!r}")
        if preview not in (None, True, False):
            raise ValueError(f"preview must be None (use it if measured), True or False, got {preview!r}")
        if "design" in options:
            raise ValueError("MPC always designs on the sampled-data model (design='sampled'); do not pass design")
        if osqp is not None and not isinstance(osqp, dict):
            raise ValueError(f"osqp must be a dict of OSQP settings, got {type(osqp).__name__}")
        super().__init__(env, design="sampled", **options)
        from mrd_env.validation import check_scalar

        self.horizon = H = int(horizon)
        self.f_max = damper_force_limit(self.env) if f_max is None else \
            check_scalar("f_max", f_max, 0.0, lo_open=True, unit="N")
        self.terminal = terminal
        self._init_preview(preview)
        d, n, nd = self.design, self.design.n, self.design.nd
        # the inputs that act: the leading channels up to the last one that drives the plant or the cost (the
        # car's preview channels ride along in the input record and act on neither: dropping them keeps the
        # condensed problem small)
        Cz, Dz, Dzw = self.cost
        acts = np.flatnonzero(np.any(d.Bw != 0.0, axis=0) | np.any(Dzw != 0.0, axis=0))
        nw = int(acts[-1]) + 1 if acts.size else 1
        if self.preview:
            nw = max(nw, 1 + max(max(pair) for pair in self._pairs))  # the roads (z_r, ż_r) the preview fills
        Bw, Dzw = d.Bw[:, :nw], Dzw[:, :nw]
        nv = 2 * nw  # per period: w at its start and its slope ẇ (first-order hold)
        # the augmented continuous system ξ = [x, f, w, ẇ] and its cost, integrated exactly over one period
        Ac = np.zeros((n + nd + nv, n + nd + nv))
        Ac[:n, :n], Ac[:n, n:n + nd], Ac[:n, n + nd:n + nd + nw] = d.A, d.Bf, Bw
        Ac[n + nd:n + nd + nw, n + nd + nw:] = np.eye(nw)
        # the cost rate over [x, f, w]: zᵀz + fᵀR₀f, z = C_z x + D_z f + D_zw w (the w-terms matter with preview)
        Q, R, N = self.lq
        Mz = np.hstack([Cz, Dz, Dzw])
        Qc = np.zeros_like(Ac)
        Qc[:n + nd + nw, :n + nd + nw] = Mz.T @ Mz
        Qc[n:n + nd, n:n + nd] = R
        E, Qd = van_loan(Ac, Qc, self.control_dt)
        Phi, Gf, Gv = E[:n, :n], E[:n, n:n + nd], E[:n, n + nd:]
        self.Phi, self.Gamma, self.Gamma_v = Phi, Gf, Gv
        P = dlqr(Phi, Gf, Qd[:n, :n], Qd[n:n + nd, n:n + nd], Qd[:n, n:n + nd])[1] if terminal == "riccati" \
            else np.zeros((n, n))
        self.P_terminal = P
        # condensed: θ = [x0, F, V] ↦ ξ_j = L_j θ, J = θᵀ Hθ θ (+ terms free of F)
        nF, nV = H * nd, H * nv
        nth = n + nF + nV
        X = np.zeros((n, nth))
        X[:, :n] = np.eye(n)
        Hth = np.zeros((nth, nth))
        for j in range(H):
            L = np.zeros((n + nd + nv, nth))
            L[:n] = X
            L[n:n + nd, n + j * nd:n + (j + 1) * nd] = np.eye(nd)
            L[n + nd:, n + nF + j * nv:n + nF + (j + 1) * nv] = np.eye(nv)
            Hth += L.T @ Qd @ L
            X = Phi @ X + Gf @ L[n:n + nd] + Gv @ L[n + nd:]
        # the terminal cost is the cost-to-go of the deviation from the steady state the plant settles to if the
        # known input stays at its last value w_H = w_{H−1} + T ẇ_{H−1} (zero without preview)
        wH = np.zeros((nw, nth))
        wH[:, n + nF + (H - 1) * nv:n + nF + (H - 1) * nv + nw] = np.eye(nw)
        wH[:, n + nF + (H - 1) * nv + nw:n + nF + H * nv] = self.control_dt * np.eye(nw)
        self.steady_state = self._steady_state(Qc[:n + nd + nw, :n + nd + nw], Bw)
        if d.frame == "road":
            # beyond the horizon the road is held at its last height (as road_ahead holds it beyond the preview),
            # ż_r = 0, and relative to it the plant settles at rest: x_ss = 0 (with the last period's ż_r the target
            # would keep climbing with the road, and the terminal cost pull the car after it)
            self.steady_state[:] = 0.0
        Xe = X - self.steady_state @ wH
        Hth += Xe.T @ P @ Xe
        Hth = 0.5 * (Hth + Hth.T)
        iF = slice(n, n + nF)
        H_ff, self._H_fx, self._H_fv = Hth[iF, iF], Hth[iF, :n], Hth[iF, n + nF:]
        self._nv, self._nw = nv, nw
        # decision variables in units of force_ref: an O(1) problem for the solver's absolute tolerances
        s = self.force_ref
        self._qp_P = 2.0 * s * s * H_ff
        self._qx_T = np.ascontiguousarray((2.0 * s * self._H_fx).T)   # q = x0 @ qx_T + V @ qv_T
        self._qv_T = np.ascontiguousarray((2.0 * s * self._H_fv).T)
        self._u_max = self.f_max / s
        self._unconstrained_T = np.ascontiguousarray(-np.linalg.inv(self._qp_P).T)  # u* = −P⁻¹q, as rows
        # the unconstrained law f_0 = −K_H x0 (equals the sampled-data LQR gain with the Riccati terminal cost)
        self.K_horizon = np.linalg.solve(H_ff, self._H_fx)[:nd]
        self._settings = {"eps_abs": 1e-8, "eps_rel": 1e-8, "polishing": True, "max_iter": 20000,
                          "verbose": False, "warm_starting": True, **(osqp or {})}
        self._solvers: dict = {}
        self.last_plan = np.zeros((0, H, nd))
        if osqp:
            try:  # bad settings fail now, not at the first step whose bounds bind
                self._solver(-1)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"osqp: invalid OSQP settings {osqp}: {exc}") from None
            self._solvers.clear()

    def _steady_state(self, Qxfw, Bw) -> np.ndarray:
        """S (n × nw): the cheapest equilibrium x_ss = S w̄ under a constant input w̄ — min over (x, f) of the
        cost rate [x, f, w̄]ᵀ Q_xfw [x, f, w̄] s.t. A x + B_f f + B_w w̄ = 0 (the target calculation of Rawlings,
        Mayne & Diehl 2017, §1.5); for the car on a road at constant height z̄, both masses at z̄ with no force."""
        d = self.design
        n, nd = d.n, d.nd
        m = n + nd
        K = np.block([[Qxfw[:m, :m], np.vstack([d.A.T, d.Bf.T])], [d.A, d.Bf, np.zeros((n, n))]])
        rhs = np.vstack([-Qxfw[:m, m:], -Bw])
        return np.linalg.lstsq(K, rhs, rcond=None)[0][:n]

    # --- preview ----------------------------------------------------------------------------------------------
    def _init_preview(self, preview):
        readings = self._road_readings()
        measured = any(tau > 0.0 for _, _, tau in readings)
        if preview is True and not measured:
            raise ValueError("preview=True needs a sensor of the road ahead ('road_preview', the road heights at "
                             "env.preview_times ahead of each wheel; on the full car 'wheelbase_preview' too); the "
                             f"environment measures {list(self.layout)}; create it with sensors=(..., "
                             "'road_preview') and preview=(times ahead, s)")
        self.preview = measured if preview is None else bool(preview)
        if not self.preview:
            return
        # per wheel: the road memory's points ahead. A sample τ_i read m steps ago is the road τ_i − m·T ahead now;
        # of the samples of one point ahead the newest is kept (and of two channels reading it, the later one)
        T = self.control_dt
        self._src = np.array([i for i, _, _ in readings])
        m_max = int(np.floor(max(tau for _, _, tau in readings) / T + 1e-9))
        self._ahead = []  # per wheel: (s ahead (increasing), steps ago it was read, which reading)
        for wheel in range(len(self._pairs)):
            ahead = {}
            for m in range(m_max, -1, -1):
                for i, (_, w, t) in enumerate(readings):
                    rel = round(t - m * T, 12)
                    if w == wheel and rel >= 0.0:
                        ahead[rel] = (m, i)
            rel = np.array(sorted(ahead))
            self._ahead.append((rel, np.array([ahead[r][0] for r in rel], dtype=np.int64),
                                np.array([ahead[r][1] for r in rel], dtype=np.int64)))
        self._memory = np.zeros((0, m_max + 1, len(readings)))  # per row: the last m_max + 1 readings, newest first
        self._age = np.zeros(0, dtype=np.int64)                   # readings since the episode started
        self._grid = np.arange(self.horizon + 1) * T              # the periods' boundaries ahead

    def _road_readings(self) -> list[tuple[int, int, float]]:
        """(observation index, wheel, s ahead) of every sensor channel that reads a wheel's road height: the road
        under a wheel (``road``, 0 s ahead, used beside a preview that does not start at 0 s) and the road ahead
        (``road_preview``; the full car's ``wheelbase_preview`` of the rear wheels), the newest of a stacked
        history. Found from the signals' maps: a channel that selects one input ``z_r<wheel>`` (now) or
        ``z_r<wheel>(t+τs...)`` (τ ahead) of the plant's :func:`~.model_based.road_inputs`."""
        names = tuple(self.design.plant.input_names)
        self._pairs = road_inputs(names)
        wheel_of = {names[iz][3:]: j for j, (iz, _) in enumerate(self._pairs)}
        out, now = [], []
        for sensor in ("road_preview", "wheelbase_preview", "road"):
            if sensor not in self.layout or not self._pairs:
                continue
            try:
                Dw = np.asarray(self.env.signal_matrices(sensor)["D_w"], dtype=float)
            except (AttributeError, ValueError):
                continue
            sl = self.layout[sensor]
            first = sl.stop - Dw.shape[0]  # the newest frame of a stacked history
            rows = [self._reading(row, names, wheel_of) for row in Dw]
            if any(r is None for r in rows):
                continue  # not a road sensor
            for r, (wheel, tau) in enumerate(rows):
                (now if tau is None else out).append((first + r, wheel, 0.0 if tau is None else tau))
        # the road under the wheel: a preview 0 s ahead, for a wheel whose preview does not start at 0 s
        for i, wheel, _ in now:
            taus = [t for _, w, t in out if w == wheel]
            if taus and min(taus) > 0.0:
                out.insert(0, (i, wheel, 0.0))
        return sorted(out, key=lambda r: r[1])  # wheel by wheel, each wheel's readings in the sensors' order

    def _reading(self, row, names, wheel_of):
        """(wheel, s ahead or None for the road under it) of a sensor channel whose map ``row`` selects one road
        height input, else None. The time ahead is read from the channel's name, on the dt grid (as
        :func:`mrd_env.envs.options.preview_times` makes it)."""
        import re

        col = int(np.argmax(np.abs(row)))
        if row[col] != 1.0 or np.count_nonzero(row) != 1:
            return None
        name = names[col]
        if name[3:] in wheel_of and name.startswith("z_r"):
            return wheel_of[name[3:]], None
        found = re.fullmatch(r"z_r(\w*)\(t\+([0-9.eE+-]+)s.*\)", name)
        if found is None or found.group(1) not in wheel_of:
            return None
        dt = self.env.dt
        return wheel_of[found.group(1)], int(round(float(found.group(2)) / dt)) * dt

    def road_ahead(self, obs: np.ndarray) -> np.ndarray:
        """Read the road preview of ``obs`` (N, n_obs) into the road memory and return w = [z_r, ż_r] of each wheel
        at the horizon's period boundaries t + jT, j = 0..H, per row: (N, H + 1, 2 × wheels), the wheels' pairs in
        the order of the plant's road inputs. Call once per control step.

        The points ahead come from this and the earlier readings (a sample τ ahead read m steps ago is τ − m·T
        ahead now: at a 1 ms control step and samples 10 ms apart the memory fills the gaps to 1 ms, and holds the
        road under the wheel). z_r: linearly interpolated between the points, held before the first and beyond the
        last (ż_r = 0 there) — a random road is close to a random walk (ISO 8608: PSD ∝ n⁻²), whose best guess
        outside its samples is the nearest one. ż_r: finite differences (``numpy.gradient``), interpolated alike. A
        wheel no sensor reads (the full car's front wheels under a wheelbase preview alone): zeros, as without
        preview."""
        n = obs.shape[0]
        self._memory = np.roll(self._memory, 1, axis=1)
        self._memory[:, 0] = obs[:, self._src]
        self._age += 1
        g = self._grid
        out = np.zeros((n, g.size, 2 * len(self._pairs)))
        for wheel, (ahead, ahead_m, ahead_i) in enumerate(self._ahead):
            if ahead.size == 0:
                continue
            for b in range(n):
                known = ahead_m < self._age[b]
                tau = ahead[known]
                z = self._memory[b, ahead_m[known], ahead_i[known]]
                out[b, :, 2 * wheel] = np.interp(g, tau, z)
                if tau.size > 1:
                    out[b, :, 2 * wheel + 1] = np.interp(g, tau, np.gradient(z, tau))
                    out[b, (g < tau[0]) | (g > tau[-1]), 2 * wheel + 1] = 0.0
        return out

    def _known_inputs(self, obs):
        """V (N, H·nv): [w_j, ẇ_j] per period (w first-order hold between boundaries), or None without preview."""
        if not self.preview:
            return None
        w = self.last_road = self.road_ahead(obs)                 # (N, H+1, 2 × wheels)
        full = np.zeros((obs.shape[0], self.horizon + 1, self._nw))
        for j, (iz, izd) in enumerate(self._pairs):
            full[:, :, iz], full[:, :, izd] = w[:, :, 2 * j], w[:, :, 2 * j + 1]
        slope = np.diff(full, axis=1) / self.control_dt           # (N, H, nw)
        if self.design.frame == "road":
            # the road enters through ż_r alone: the derivative of the held heights, Δz_r/T over each period, so
            # that the prediction moves the road by exactly the previewed heights (not by a finite difference)
            for iz, izd in self._pairs:
                full[:, :-1, izd] = slope[:, :, iz]
                slope[:, :, izd] = 0.0
        return np.concatenate([full[:, :-1], slope], axis=2).reshape(obs.shape[0], -1)

    # --- the law ----------------------------------------------------------------------------------------------
    def allocate(self, n_rows):
        super().allocate(n_rows)
        self._solvers = {}  # row → its OSQP problem, set up the first time that row's bounds bind
        self.last_plan = np.zeros((n_rows, self.horizon, self.design.nd))
        if self.preview:
            self._memory = np.zeros((n_rows,) + self._memory.shape[1:])
            self._age = np.zeros(n_rows, dtype=np.int64)

    def _solver(self, row: int):
        solver = self._solvers.get(row)
        if solver is None:
            import osqp
            import scipy.sparse as sp

            m = self._qp_P.shape[0]
            solver = self._solvers[row] = osqp.OSQP()
            solver.setup(sp.triu(sp.csc_matrix(self._qp_P), format="csc"), np.zeros(m), sp.identity(m, format="csc"),
                         np.full(m, -self._u_max), np.full(m, self._u_max), **self._settings)
        return solver

    def reset_rows(self, mask):
        super().reset_rows(mask)
        if self.preview:
            self._age[mask] = 0  # a new road: forget the old one
        for b in np.flatnonzero(mask):
            # a new episode starts from a cold solver: results do not depend on what came before
            self._solvers.pop(int(b), None)
            self.last_plan[b] = 0.0

    def plan(self, x_hat: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
        """The optimal forces f_0..f_{H−1} (N, beyond the preload) per row from the estimates x̂ (N, n) and the
        known inputs V (N, H·nv) or None: (N, H, nd).

        A row whose unconstrained optimum −P⁻¹q already satisfies the bounds has it as its solution (the KKT
        conditions hold with zero multipliers) and skips the solver; the others are solved by OSQP, each from its
        own last solution."""
        q = x_hat @ self._qx_T
        if V is not None:
            q = q + V @ self._qv_T
        out = q @ self._unconstrained_T
        for b in np.flatnonzero(np.any(np.abs(out) > self._u_max, axis=1)):
            solver = self._solver(int(b))
            solver.update(q=q[b])
            res = solver.solve(raise_error=False)
            if res.info.status_val in (1, 2):  # solved, solved inaccurate
                out[b] = np.clip(res.x, -self._u_max, self._u_max)
            elif np.isfinite(q[b]).all():  # an estimate so far out (1e16 and beyond) that OSQP stops: the clipped
                out[b] = np.clip(out[b], -self._u_max, self._u_max)  # unconstrained optimum, a feasible command
            else:
                raise RuntimeError(f"MPC: OSQP failed on row {b}: {res.info.status} (the estimate is not finite)")
        return (out * self.force_ref).reshape(x_hat.shape[0], self.horizon, self.design.nd)

    def command(self, obs):
        V = self._known_inputs(obs)
        x_hat, f = self.estimate(obs)
        if V is not None:
            # the road is known now: the Kalman time update takes it as an input (first-order hold over the period)
            self.kf.x += V[:, :self._nv] @ self.Gamma_v.T
        plan = self.plan(x_hat, V)
        self.last_plan[:] = plan
        fc = self.last_desired = plan[:, 0]
        return self.actuate(fc, f, obs)
