"""Nonlinear model-predictive control on the damper model (CasADi).

At every control step k the law optimises the commands v_0..v_{H−1} ∈ [v_min, v_max] of the next H control
periods through the environment's own nonlinear model — the linear plant coupled to the symbolic damper
(:mod:`mrd_env.optimal.casadi_model`: Spencer–Dyke or Bouc–Wen, the command lag exact, the stepping routine's SDIRK
step at the physics step with a fixed number of Newton iterations, |·| smoothed) — and applies v_0::

    min_v  Σ_{rows r of the horizon} dt · Σ_signals w_s · s(r)²,    s = C x + D_F F + D_w w + d0

with the environment's declared ``objective`` weights w_s (those of :class:`~.model_based.ClippedOptimal` and
:class:`~.mpc.MPC`; building: the drifts; car: sprung acceleration and travel), single shooting from the current
estimate, the exact gradient by reverse-mode AD compiled to C once per set-up
(:class:`mrd_env.optimal.full_knowledge.ShootingModel`, cached on disk), solved by L-BFGS-B (``solver="lbfgsb"``) or IPOPT
with a limited-memory Hessian (``solver="ipopt"``), warm-started from the previous step's solution shifted by one
period.

**The estimate.** The plant state is the Kalman estimate of :class:`~.model_based.ObserverLaw` (the same measured
responses and damper force as the model-based laws), taken as the filtered estimate x̂[k|k] (the predictor's
x̂[k|k−1] corrected with this step's measurements, M = Φ⁻¹L). The damper's internal states (y, z) are not measured:
they are estimated by running the symbolic damper model on the measured stroke and stroke rate (the sensors of the
``damper_stroke`` and ``damper_velocity`` roles, linear between samples) under the commands this controller sent,
then moved — the least change, along the force's gradient, z kept within ±z_s — so that the model's force equals
the load cell's (``force_feedback``; without it the open-loop estimate of z drifts by ~16 % r.m.s. at 10 ms on the
car). The future disturbance is unknown: ``disturbance="hold"`` (default) takes its current value, by least squares
from the sensors that see it directly (the car's wheel accelerometer gives the road height under the tyre, the
building's ground accelerometer the ground acceleration), and holds it over the horizon; "zero" takes it as zero. A
command delay τ > 0 is approximated by the current effective command for the commands sent before the horizon.

**Horizon and cost.** Certainty equivalence with a held disturbance is a short-horizon design: on the quarter car
(class C, 1.5 s, 10 ms) the return is best at 50 ms (−1.518; passive-off −1.559, skyhook-continuous −1.411) and
falls as the horizon grows (−1.524 at 100 ms, −1.698 at 200 ms, −1.779 at 300 ms): the held road is the wrong
future. Hence the default :data:`DEFAULT_HORIZON` = 50 ms. One ``predict`` solves an NLP of H unknowns through
H·control_dt/dt physics steps: 1.7 ms median, 3.3 ms mean at 1 ms (H = 50, 50 physics steps; 10 L-BFGS-B iterations),
against a control period of 1 ms — not real time on this machine (2 cores, shared). One solve per batch row: not
for vector environments of many rows. Road preview (the ``road_preview`` sensor of :class:`~.mpc.MPC`) is not used.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .model_based import ObserverLaw

#: Default horizon (s): measured on the quarter car (class C road, 1.5 s, 10 ms control step), the return falls as the
#: horizon grows beyond it — the disturbance held over the horizon is the wrong future (README).
DEFAULT_HORIZON = 0.05


class NonlinearMPC(ObserverLaw):
    """Nonlinear MPC of the damper commands (see the module docstring).

    Options: ``horizon`` H (control periods, 1..200; default 50 ms worth); ``weights`` {signal: weight on its square}
    (default ``env.objective``); ``solver``: "lbfgsb" (default) or "ipopt" (builds IPOPT anew at every step: slower);
    ``max_iter`` per step (default 30); ``newton_iterations`` per SDIRK stage of the model (default 3);
    ``disturbance``: "hold" or "zero"; ``force_feedback``: correct the damper states with the load cell (default
    True); ``eps_v``, ``eps_z``, ``eps_u``: the model's smoothing (:class:`mrd_env.optimal.casadi_model.Smoothing`); the
    observer's options as :class:`~.model_based.ClippedOptimal` (``measurements``, ``process_noise``,
    ``measurement_noise``). ``solve_stats``: (seconds, iterations, evaluations) of every solve since the last
    ``allocate``.
    """

    name = "nmpc"
    needs_roles = ("damper_stroke", "damper_velocity")

    def __init__(self, env, horizon: int | None = None, weights: dict | None = None, solver: str = "lbfgsb",
                 max_iter: int = 30, newton_iterations: int = 3, eps_v: float | None = None,
                 eps_z: float | None = None, eps_u: float | None = None, disturbance: str = "hold",
                 force_feedback: bool = True, **observer):
        from mrd_env.optimal.casadi_model import Smoothing, check_supported

        base = getattr(env, "unwrapped", env)
        if horizon is None:
            horizon = max(1, int(round(DEFAULT_HORIZON / base.control_dt)))
        if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or not 1 <= horizon <= 200:
            raise ValueError(f"horizon must be an integer number of control periods in [1, 200], got {horizon!r}")
        if solver not in ("lbfgsb", "ipopt"):
            raise ValueError(f"solver must be 'lbfgsb' or 'ipopt', got {solver!r}")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise ValueError(f"max_iter must be an int >= 1, got {max_iter!r}")
        if disturbance not in ("hold", "zero"):
            raise ValueError(f"disturbance must be 'hold' or 'zero', got {disturbance!r}")
        super().__init__(env, **observer)
        check_supported(self.env.damper)
        eps = {k: v for k, v in dict(eps_v=eps_v, eps_z=eps_z, eps_u=eps_u).items() if v is not None}
        self.smoothing = Smoothing(**eps)
        self.horizon, self.solver, self.max_iter = int(horizon), solver, int(max_iter)
        self.weights = dict(self.env.objective) if weights is None else dict(weights)
        base = self.env
        sys_ = base.assembly.coupled.system
        self.dt = float(base.dt)
        self.n_sub = int(round(self.control_dt / self.dt))
        lp = base.linear_plant
        nq = 2 * lp.n_dof
        # the cost's rows over [x, F, W] (W = plant inputs and the constant channel, as the environment's)
        rows, wts = [], []
        for name, w in self.weights.items():
            try:
                m = base.signal_matrices(name)
            except ValueError as e:
                raise ValueError(f"NonlinearMPC cannot weigh {name!r}: {e}") from None
            rows.append(np.hstack([m["C"], m["D_F"], m["D_w"], m["d0"][:, None]]))
            wts.append(np.full(m["C"].shape[0], float(w) * self.dt))
        G = np.vstack(rows)
        terms = (SimpleNamespace(name="objective", G=G, weight=np.concatenate(wts), sos=None),)
        n_steps = self.horizon
        self.problem = SimpleNamespace(
            damper=base.damper, A=sys_.A, BF=sys_.BF, Bw=sys_.Bw, Cx=sys_.Cx, Cv=sys_.Cv, dt=self.dt,
            n_sub=self.n_sub, n_steps=n_steps, n_rows=n_steps * self.n_sub + 1, terms=terms, limits=(),
            F_static=float(base.F_static), v_min=self.v_min, v_max=self.v_max, control_dt=self.control_dt)
        self.nq, self.nd = nq, self.n_dampers
        self.input_names = tuple(lp.input_names)
        self.disturbance = disturbance
        self.force_feedback = bool(force_feedback)
        # the filtered estimate x̂[k|k] = x̂[k|k−1] + M (y − C x̂ − D f), M = Φ⁻¹L (L = Φ P Cᵀ(C P Cᵀ + R)⁻¹)
        self.M = np.linalg.solve(self.kf.Phi, self.kf.L)
        # the sensors that see the disturbance directly (D_w ≠ 0): its current value by least squares
        rows = []
        for name in self.layout:
            if name in ("command", "damper_states"):
                continue
            try:
                m = base.signal_matrices(name)
            except ValueError:
                continue
            if np.max(np.abs(m["D_w"]), initial=0.0) > 0:
                rows.append((self.layout[name], m))
        self._w_sensors = rows
        self._build(newton_iterations)

    # --- the models --------------------------------------------------------------------------------------------
    def _build(self, newton_iterations: int) -> None:
        import casadi as ca

        from mrd_env.optimal.casadi_model import CoupledModel, symbolic_damper
        from mrd_env.optimal.full_knowledge import ShootingModel

        self.model = ShootingModel(self.problem, self.smoothing, newton_iterations)
        sd = symbolic_damper(self.env.damper, smoothing=self.smoothing)
        self.sd = sd
        # the damper observer: the rig model driven by the measured stroke over one control period
        rig = CoupledModel.rig(sd)
        step = rig.newton_step(self.dt, 0.0, newton_iterations, project="exact")
        S = ca.SX
        ns = sd.ns
        s, F, u = S.sym("s", ns), S.sym("F"), S.sym("u")
        x0, v0, x1, v1, cmd = S.sym("x0"), S.sym("v0"), S.sym("x1"), S.sym("v1"), S.sym("cmd")
        y, f = s, F
        uu = u
        for k in range(self.n_sub):
            a, b = k / self.n_sub, (k + 1) / self.n_sub
            wa = ca.vertcat(x0 + (x1 - x0) * a, v0 + (v1 - v0) * a)
            wb = ca.vertcat(x0 + (x1 - x0) * b, v0 + (v1 - v0) * b)
            y, f, uu = step(y, f, wa, wb, uu, cmd, cmd)
        self._observe = ca.Function("damper_observer", [s, F, u, x0, v0, x1, v1, cmd], [y, f, uu])
        self._force = sd.function()
        s_, x_, v_, u_ = S.sym("s", ns), S.sym("x"), S.sym("v"), S.sym("u")
        Fx = sd.force(s_, x_, v_, u_)
        self._force_grad = ca.Function("force_grad", [s_, x_, v_, u_], [Fx, ca.gradient(Fx, s_)])

    def allocate(self, n_rows):
        super().allocate(n_rows)
        nd = self.nd
        self.s_hat = np.tile(self.sd.initial_state(), (n_rows, nd, 1))
        self.F_hat = np.full((n_rows, nd), float(self.env.F_static))
        self.u_hat = np.full((n_rows, nd), self.v_min)
        self.last_cmd = np.full((n_rows, nd), self.v_min)
        self.last_stroke = np.full((n_rows, nd, 2), np.nan)
        self.V_prev = np.full((n_rows, self.horizon, nd), self.v_min)
        self.solve_stats = []

    def reset_rows(self, mask):
        super().reset_rows(mask)
        if not hasattr(self, "s_hat"):
            return
        self.s_hat[mask] = self.sd.initial_state()
        self.F_hat[mask] = float(self.env.F_static)
        self.u_hat[mask] = self.v_min
        self.last_cmd[mask] = self.v_min
        self.last_stroke[mask] = np.nan
        self.V_prev[mask] = self.v_min

    # --- the law ----------------------------------------------------------------------------------------------
    def _observe_damper(self, b: int, stroke: np.ndarray, rate: np.ndarray) -> None:
        """Advance row b's damper-state estimate from the last measured stroke to this one."""
        for j in range(self.nd):
            if np.isnan(self.last_stroke[b, j, 0]):  # first sample of the episode: the damper is at rest
                s = self.sd.initial_state()
                self.F_hat[b, j] = float(self._force(s, stroke[j], rate[j], self.u_hat[b, j])[1])
            else:
                x0, v0 = self.last_stroke[b, j]
                s, F, u = self._observe(self.s_hat[b, j], self.F_hat[b, j], self.u_hat[b, j], x0, v0, stroke[j],
                                        rate[j], self.last_cmd[b, j])
                s = np.asarray(s).ravel()
                self.F_hat[b, j], self.u_hat[b, j] = float(F), float(u)
            self.s_hat[b, j] = s
            self.last_stroke[b, j] = (stroke[j], rate[j])

    def _inputs(self, x_hat: np.ndarray, obs_row: np.ndarray) -> np.ndarray:
        """The plant inputs over the horizon (with the constant channel): "hold" — the current disturbance, by least
        squares from the sensors that see it (D_w ≠ 0) given x̂ and the measured force, held; "zero" — zero."""
        nw = len(self.input_names)
        w = np.zeros(nw)
        if self.disturbance == "hold" and self._w_sensors:
            F = obs_row[self.layout["damper_force"]]
            Ds, rs = [], []
            for sl, m in self._w_sensors:
                Ds.append(m["D_w"])
                rs.append(obs_row[sl] - m["C"] @ x_hat - m["D_F"] @ F - m["d0"])
            w = np.linalg.lstsq(np.vstack(Ds), np.concatenate(rs), rcond=1e-9)[0]
        return np.tile(np.append(w, 1.0), (self.problem.n_rows, 1))

    def _correct_damper(self, b: int, x_hat: np.ndarray, F_meas: np.ndarray) -> None:
        """Move row b's damper states, in the direction of the force's gradient (scaled by z_s), so that the model
        force matches the load cell's (the least change that does), z kept within ±z_s."""
        sd, nx = self.sd, self.nq
        Cx, Cv = self.problem.Cx, self.problem.Cv
        for j in range(self.nd):
            x, v = float(Cx[j] @ x_hat[:nx]), float(Cv[j] @ x_hat[:nx])
            s = self.s_hat[b, j]
            F, dF = (np.asarray(a).ravel() for a in self._force_grad(s, x, v, self.u_hat[b, j]))
            scale = np.full(sd.ns, sd.z_s)
            g = dF * scale
            if g @ g > 0:
                s = s + scale * g * (F_meas[j] - F[0]) / (g @ g)
            s[-1] = np.clip(s[-1], -sd.z_s, sd.z_s)
            self.s_hat[b, j] = s

    def command(self, obs):
        import time

        from mrd_env.optimal.full_knowledge import minimize_ipopt, minimize_lbfgsb

        x_pred, f = self.estimate(obs)
        y = obs[:, self._y_index]
        x_hat = x_pred + (y - x_pred @ self.kf.C.T - f @ self.kf.D.T) @ self.M.T
        stroke = self.role(obs, "damper_stroke")
        rate = self.role(obs, "damper_velocity")
        F_meas = obs[:, self.layout["damper_force"]]
        out = np.empty((obs.shape[0], self.nd))
        for b in range(obs.shape[0]):
            self._observe_damper(b, stroke[b], rate[b])
            if self.force_feedback:
                self._correct_damper(b, x_hat[b], F_meas[b])
            Y0 = np.concatenate([x_hat[b], self.s_hat[b].ravel()])
            W = self._inputs(x_hat[b], obs[b])
            data = {"W": np.ascontiguousarray(W.T), "x0": np.concatenate([Y0, self.F_hat[b], self.u_hat[b]]),
                    "wts": self.problem.terms[0].weight}

            def fun(V, data=data):
                ret, pen, g = self.model.evaluate(V, data)
                return -ret + pen, g

            V0 = np.vstack([self.V_prev[b, 1:], self.V_prev[b, -1:]])
            t0 = time.perf_counter()
            if self.solver == "lbfgsb":
                V, status, _, nit, nev = minimize_lbfgsb(fun, V0, self.v_min, self.v_max, self.max_iter, 1e-9, 5, None)
            else:
                V, status, _, nit, nev = minimize_ipopt(fun, V0, self.v_min, self.v_max, self.max_iter, 1e-8, False)
            self.solve_stats.append((time.perf_counter() - t0, nit, nev))
            V = np.clip(V, self.v_min, self.v_max)
            self.V_prev[b] = V
            out[b] = V[0]
        self.last_cmd = out.copy()
        return out
