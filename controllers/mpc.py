"""Linear model-predictive control of the damper force, clipped to what a semi-active damper can do.

At every control step k the law solves, from the Kalman estimate x̂[k] (:class:`~.model_based._ObserverLaw`),
the finite-horizon problem over H control periods T = ``control_dt``::

    min_{f_0..f_{H−1}}  Σ_{j<H} ∫_{jT}^{(j+1)T} zᵀz + fᵀR₀f dt  +  x_Hᵀ P x_H,     |f_j| ≤ f_max
    ẋ = A x + B_f f + B_w w,   z = C_z x + D_z f,   x(0) = x̂[k]

— ClippedOptimal's LQ cost (the environment's ``objective`` weights, R₀ = 1/force_ref²) integrated exactly over
each period with the force held (Van Loan 1978; :func:`~.model_based.van_loan`), P the discrete Riccati
solution of the same sampled-data problem (so that without active bounds the law is the infinite-horizon
sampled-data LQR for any H; Rawlings, Mayne & Diehl, Model Predictive Control, 2nd ed., §2.5), the disturbance
w known over the horizon (a road preview) or zero. The QP is condensed onto the forces (Maciejowski,
Predictive Control with Constraints, §3.1), solved by OSQP (Stellato et al. 2020) warm-started from the last
step, one problem per batch row; f_0 is the desired force f_c, turned into the command by the clipped on–off law
u = u_max·H((f_c − f)·f) as :class:`~.model_based.ClippedOptimal` (or by its ``inverse``).

OSQP is imported when the first controller is built: ``import controllers`` does not need it.
"""
from __future__ import annotations

import numpy as np

from .model_based import ClippedOptimal, dlqr, van_loan

#: The representative stroke velocity amplitude (m/s) of the default force bound (see :func:`damper_force_limit`).
F_MAX_VELOCITY = 0.1


def damper_force_limit(env, velocity: float = F_MAX_VELOCITY) -> float:
    """A damper's force capacity beyond its static preload (N): the peak |F − F_static| over a steady cycle of
    a sinusoidal stroke at the maximum command, with velocity amplitude ``velocity`` at the plant's lowest
    undamped natural frequency (:func:`mrd_env.rig.sinusoidal_test`). At 0.1 m/s: 859 N for the quarter car's
    automotive Spencer–Dyke damper (1.25 Hz), 1265 N for the building's prototype (5.46 Hz)."""
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
    of 0.1 m/s); ``preview``: use the ``road_preview`` sensor (the road heights at ``env.preview_times`` ahead)
    for w over the horizon — None (default) when it is measured, True (required), False (w = 0); ``terminal``:
    "riccati" (default, P above) or "zero" (no terminal cost: the finite-horizon LQR, for checks);
    ``osqp``: OSQP settings overriding the defaults. ``weights``, ``force_ref``, ``inverse`` and the observer's
    options as :class:`~.model_based.ClippedOptimal`.

    With preview the road (z_r from the samples, linearly interpolated to the horizon's period boundaries, held
    at the last previewed height beyond the preview; ż_r by finite differences) is a known input held first-order
    between period boundaries, both in the prediction and in the Kalman filter's time update.
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
        nw = d.Bw.shape[1]
        nv = 2 * nw  # per period: w at its start and its slope ẇ (first-order hold)
        # the augmented continuous system ξ = [x, f, w, ẇ] and its cost, integrated exactly over one period
        Ac = np.zeros((n + nd + nv, n + nd + nv))
        Ac[:n, :n], Ac[:n, n:n + nd], Ac[:n, n + nd:n + nd + nw] = d.A, d.Bf, d.Bw
        Ac[n + nd:n + nd + nw, n + nd + nw:] = np.eye(nw)
        Q, R, N = self.lq
        Qc = np.zeros_like(Ac)
        Qc[:n + nd, :n + nd] = np.block([[Q, N], [N.T, R]])
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
        Hth += X.T @ P @ X
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
        self._solvers: list = []
        self.last_plan = np.zeros((0, H, nd))

    # --- preview ----------------------------------------------------------------------------------------------
    def _init_preview(self, preview):
        measured = "road_preview" in self.layout and hasattr(self.env, "preview_times")
        if preview is True and not measured:
            raise ValueError("preview=True needs the 'road_preview' sensor (the quarter car's road heights ahead); "
                             f"the environment measures {list(self.layout)}; create it with "
                             "sensors=(..., 'road_preview')")
        self.preview = measured if preview is None else bool(preview)
        if not self.preview:
            return
        names = self.design.plant.input_names
        if tuple(names[:2]) != ("z_r", "zdot_r"):
            raise ValueError(f"the road preview drives the inputs (z_r, zdot_r); this plant's inputs are {names}")
        tau = np.asarray(self.env.preview_times, dtype=float).ravel()
        if tau.size < 1 or np.any(np.diff(tau) <= 0) or tau[0] < 0:
            raise ValueError(f"env.preview_times must be increasing and >= 0 s, got {tau}")
        sl = self.layout["road_preview"]
        self._preview_index = np.arange(sl.start, sl.stop)[-tau.size:]  # the newest, with a stacked history
        # the current height: the preview's first sample if it is at 0 s, else the road sensor if measured
        self._road_index = None
        if tau[0] > 0.0 and "road" in self.layout:
            self._road_index = self.layout["road"].stop - 1
            tau = np.concatenate([[0.0], tau])
        self._tau = tau
        self._grid = np.arange(self.horizon + 1) * self.control_dt  # the periods' boundaries ahead

    def road_ahead(self, obs: np.ndarray) -> np.ndarray:
        """w = [z_r, ż_r] at the horizon's period boundaries t + jT, j = 0..H, per row: (N, H + 1, 2)."""
        Z = obs[:, self._preview_index]
        if self._road_index is not None:
            Z = np.hstack([obs[:, [self._road_index]], Z])
        tau, g = self._tau, self._grid
        dZ = np.gradient(Z, tau, axis=1) if tau.size > 1 else np.zeros_like(Z)
        out = np.empty((obs.shape[0], g.size, 2))
        beyond = g > tau[-1]
        for b in range(obs.shape[0]):
            out[b, :, 0] = np.interp(g, tau, Z[b])
            out[b, :, 1] = np.where(beyond, 0.0, np.interp(g, tau, dZ[b]))
        return out

    def _known_inputs(self, obs):
        """V (N, H·nv): [w_j, ẇ_j] per period (w first-order hold between boundaries), or None without preview."""
        if not self.preview:
            return None
        w = self.road_ahead(obs)                                  # (N, H+1, 2)
        nw = self._nw
        full = np.zeros((obs.shape[0], self.horizon + 1, nw))
        full[:, :, :2] = w
        slope = np.diff(full, axis=1) / self.control_dt           # (N, H, nw)
        return np.concatenate([full[:, :-1], slope], axis=2).reshape(obs.shape[0], -1)

    # --- the law ----------------------------------------------------------------------------------------------
    def allocate(self, n_rows):
        super().allocate(n_rows)
        import osqp
        import scipy.sparse as sp

        P = sp.triu(sp.csc_matrix(self._qp_P), format="csc")
        m = self._qp_P.shape[0]
        A = sp.identity(m, format="csc")
        lo, hi = np.full(m, -self._u_max), np.full(m, self._u_max)
        self._solvers = []
        for _ in range(n_rows):
            solver = osqp.OSQP()
            solver.setup(P, np.zeros(m), A, lo, hi, **self._settings)
            self._solvers.append(solver)
        self.last_plan = np.zeros((n_rows, self.horizon, self.design.nd))

    def reset_rows(self, mask):
        super().reset_rows(mask)
        m = self._qp_P.shape[0]
        for b in np.flatnonzero(mask):
            # a new episode starts from a cold solver: results do not depend on what came before
            self._solvers[b].warm_start(x=np.zeros(m), y=np.zeros(m))
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
            solver = self._solvers[b]
            solver.update(q=q[b])
            res = solver.solve(raise_error=False)
            if res.info.status_val not in (1, 2):  # solved, solved inaccurate
                raise RuntimeError(f"MPC: OSQP failed on row {b}: {res.info.status} (a box-constrained, strictly "
                                   "convex QP is always solvable: check the estimate for NaN)")
            out[b] = np.clip(res.x, -self._u_max, self._u_max)
        return (out * self.force_ref).reshape(x_hat.shape[0], self.horizon, self.design.nd)

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        plan = self.plan(x_hat, self._known_inputs(obs))
        self.last_plan[:] = plan
        fc = self.last_desired = plan[:, 0]
        return self.actuate(fc, f, obs)

    def estimate(self, obs):
        if not self.preview:
            return super().estimate(obs)
        # the road is known now: the Kalman time update takes it as an input (first-order hold over the period)
        y = obs[:, self._y_index]
        f = self.dynamic_force(obs)
        V = self._known_inputs(obs)[:, :self._nv]
        x = self.kf.update(y, f)
        self.kf.x += V @ self.Gamma_v.T
        return x, f
