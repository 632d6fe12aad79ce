"""Symbolic (CasADi) versions of the damper models, the command lag and the coupled plant, for optimisers.

The clairvoyant optimum (:mod:`mrd_env.optimal.full_knowledge`) and nonlinear MPC (``controllers/nmpc.py``) need
the environment's own equations as CasADi expressions: this module writes them from the project's
:class:`~mrd_env.dampers.DamperModel` (its parameter dataclass, SI) and :class:`~mrd_env.dampers.CommandSpec`.

Supported damper models: ``spencer_dyke`` (review eq. (12); presets ``automotive``, ``spencer1997``) and
``bouc_wen`` (review eqs. (7)–(9)). Any other model raises ``ValueError`` naming these
(:data:`SUPPORTED_MODELS`).

**Smoothing (inside the optimiser only).** The Bouc–Wen hysteresis has |ẋ| and z|z|^(n−1); IPOPT needs
twice-differentiable functions, so

* |v| ≈ sqrt(v² + ε_v²) with ``eps_v`` in m/s (default 1e-4 m/s: the stroke rates of the benchmark are
  1e-2…1 m/s, where the relative error ε_v²/(2v²) is below 5e-5);
* |z| ≈ sqrt(z² + ε_z²) with ε_z = ``eps_z``·z_s, z_s = (A/(β+γ))^(1/n) the saturation (default 1e-3); for the
  presets' n = 2, |z|^n = z² is exact and only z|z| is smoothed;
* the asymmetric command lag's rate switch η = η_rise if v > u else η_fall becomes
  η_fall + (η_rise − η_fall)·(1 + sg(v − u))/2 with sg(a) = a/sqrt(a² + ε_u²), ``eps_u`` in command units
  (default 1e-3; no switch at all when the lag is symmetric).

With every ε → 0 the expressions are the project's own functions (``tests/optimal/test_casadi_model.py`` checks the
states' derivatives, the force and their Jacobians against ``rhs``/``force_law``/``partials`` at random states, and
the discretised model against the rig). The environment itself never smooths anything: every figure the
optimiser reports is re-simulated there.

**Command lag.** u̇ = −η (u − v(t − τ)) is integrated exactly over each physics step, as the stepping routine
does (:func:`mrd_env.command_lag.lag_value`): with the command held over the step, u(t_r + τ') is a closed form
of u(t_r) and the delayed commands. A pure delay τ = m·dt + s is a shift of the command sequence by m physics
steps plus a switch s into the step (:meth:`SymbolicDamper.delayed_commands`); nothing is refused.

**Discretisation.** :class:`CoupledModel` is a linear plant q̇ = A q + B_F F + B_w w (x = [q, q̇], damper stroke
C_x x + D_x w, rate C_v x + D_v w) with ``nd`` copies of a symbolic damper, and its step is the environment's
scheme: the two-stage, L-stable, stiffly accurate SDIRK of Alexander (γ = 1 − 1/√2) over each physics step, the
input linear inside the step, the command lag exact (:meth:`CoupledModel.sdirk_residual`). An optimiser that
imposes these residuals as equality constraints follows the environment's trajectory (up to its error control,
which rarely splits a 1 ms step, and the projection of z onto ±z_s, which an exact solution never needs).

CasADi is imported inside the functions, so importing this module (and running any environment) never needs it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..command_lag import delay_split
from ..dampers import DamperModel
from ..stepping import GAMMA

#: Damper models this module writes symbolically.
SUPPORTED_MODELS = ("spencer_dyke", "bouc_wen")

EPS_V = 1e-4   # m/s
EPS_Z = 1e-3   # fraction of the saturation z_s
EPS_U = 1e-3   # command units


def _casadi():
    try:
        import casadi
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError("the optimal-control tools need CasADi: pip install casadi") from e
    return casadi


def check_supported(damper: DamperModel) -> None:
    """``ValueError`` unless ``damper`` is a model this module writes symbolically."""
    if not isinstance(damper, DamperModel):
        raise ValueError(f"damper must be a DamperModel, got {type(damper).__name__}")
    if damper.name not in SUPPORTED_MODELS:
        raise ValueError(f"the optimiser supports the damper models {', '.join(map(repr, SUPPORTED_MODELS))}, "
                         f"not {damper.name!r} (choose damper='spencer_dyke' or 'bouc_wen')")
    if damper.inertance() != 0.0:  # pragma: no cover - neither supported model has one
        raise ValueError(f"damper {damper.name!r} has an inertance term, which the optimiser does not model")


def smooth_abs(a, eps: float):
    """|a| ≈ sqrt(a² + ε²) (exact |a| for ε = 0, where it is not differentiable at 0)."""
    ca = _casadi()
    return ca.sqrt(a * a + eps * eps) if eps > 0 else ca.fabs(a)


def smooth_sign(a, eps: float):
    """sgn(a) ≈ a / sqrt(a² + ε²)."""
    ca = _casadi()
    return a / ca.sqrt(a * a + eps * eps) if eps > 0 else ca.sign(a)


@dataclass(frozen=True)
class Smoothing:
    """Smoothing scales of the non-smooth terms (see the module docstring): ``eps_v`` (m/s), ``eps_z`` (fraction of
    the saturation z_s), ``eps_u`` (command units)."""

    eps_v: float = EPS_V
    eps_z: float = EPS_Z
    eps_u: float = EPS_U

    def __post_init__(self):
        for name in ("eps_v", "eps_z", "eps_u"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"smoothing {name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))


class SymbolicDamper:
    """A configured damper written in CasADi: ``rhs(s, x, ẋ, u)`` → ṡ, ``force(s, x, ẋ, u)`` → F, the command lag
    (:meth:`lag`, :meth:`lag_rate`), with the smoothing of the module docstring. Works on SX, MX and DM
    arguments (``s`` a column of ``ns`` entries)."""

    def __init__(self, damper: DamperModel, smoothing: Smoothing | None = None, **eps):
        check_supported(damper)
        self.damper = damper
        self.name = damper.name
        self.smoothing = smoothing if smoothing is not None else Smoothing(**eps)
        if smoothing is not None and eps:
            raise ValueError("give either smoothing= or eps_v/eps_z/eps_u, not both")
        self.p = damper.params.to_dict()
        self.ns = damper.n_states
        self.command = damper.command
        p = self.p
        self.z_s = float((p["A"] / (p["beta"] + p["gamma"])) ** (1.0 / p["n"]))
        self._ez = self.smoothing.eps_z * self.z_s

    # --- the hysteresis -------------------------------------------------------------------------------------
    def bouc_wen_zdot(self, z, v):
        """ż = −γ |v| z |z|^(n−1) − β v |z|^n + A v (review eq. (8)), smoothed."""
        p = self.p
        n = p["n"]
        av = smooth_abs(v, self.smoothing.eps_v)
        if n == 2.0:
            z_azn1, azn = z * smooth_abs(z, self._ez), z * z
        elif n == 1.0:
            z_azn1, azn = z, smooth_abs(z, self._ez)
        else:
            az = smooth_abs(z, self._ez)
            z_azn1, azn = z * az ** (n - 1.0), az ** n
        return -p["gamma"] * av * z_azn1 - p["beta"] * v * azn + p["A"] * v

    def _coefficients(self, u):
        p = self.p
        if self.name == "spencer_dyke":
            return {"c0": p["c0a"] + p["c0b"] * u, "c1": p["c1a"] + p["c1b"] * u,
                    "alpha": p["alpha_a"] + p["alpha_b"] * u}
        return {"c0": p["c0a"] + p["c0b"] * u, "k0": p["k0a"] + p["k0b"] * u, "alpha": p["alpha_a"] + p["alpha_b"] * u}

    def _ydot(self, s, x, xd, u):
        c = self._coefficients(u)
        return (c["alpha"] * s[1] + c["c0"] * xd + self.p["k0"] * (x - s[0])) / (c["c0"] + c["c1"])

    def rhs(self, s, x, xd, u):
        """ṡ, a column of ``ns`` expressions."""
        ca = _casadi()
        if self.name == "spencer_dyke":
            yd = self._ydot(s, x, xd, u)
            return ca.vertcat(yd, self.bouc_wen_zdot(s[1], xd - yd))
        return ca.vertcat(self.bouc_wen_zdot(s[0], xd))

    def force(self, s, x, xd, u):
        """F (N, positive when resisting extension), static preload included."""
        p = self.p
        if self.name == "spencer_dyke":
            c1 = p["c1a"] + p["c1b"] * u
            return c1 * self._ydot(s, x, xd, u) + p["k1"] * (x - p["x0"])
        c = self._coefficients(u)
        return c["c0"] * xd + c["k0"] * (x - p["x0"]) + c["alpha"] * s[0]

    def function(self, sym: str = "SX"):
        """``casadi.Function('damper', [s, x, xd, u], [sdot, F])``."""
        ca = _casadi()
        S = getattr(ca, sym)
        s, x, xd, u = S.sym("s", self.ns), S.sym("x"), S.sym("xd"), S.sym("u")
        return ca.Function("damper", [s, x, xd, u], [self.rhs(s, x, xd, u), self.force(s, x, xd, u)],
                           ["s", "x", "xd", "u"], ["sdot", "F"])

    def initial_state(self) -> np.ndarray:
        return np.asarray(self.damper.initial_state(), dtype=float)

    # --- the command lag ----------------------------------------------------------------------------------------
    @property
    def symmetric_lag(self) -> bool:
        return self.command.eta_down == self.command.eta

    def eta(self, v, u):
        """The lag rate η (1/s) towards command v from u: η_rise above, η_fall below (smoothed switch)."""
        c = self.command
        if self.symmetric_lag:
            return c.eta
        return c.eta_down + (c.eta - c.eta_down) * 0.5 * (1.0 + smooth_sign(v - u, self.smoothing.eps_u))

    def lag_rate(self, u, v):
        """u̇ = −η (u − v)."""
        return -self.eta(v, u) * (u - v)

    def lag(self, u0, va, vb, ts: float, tau: float):
        """u at ``tau`` (s) after a step's start from u0 there, the (delayed) command va until ``ts`` and vb after:
        :func:`mrd_env.command_lag.lag_value` in CasADi (``ts``, ``tau`` numbers)."""
        ca = _casadi()
        if tau <= ts:
            return va + (u0 - va) * ca.exp(-self.eta(va, u0) * tau)
        us = u0
        if ts > 0.0:
            us = va + (u0 - va) * ca.exp(-self.eta(va, u0) * ts)
        return vb + (us - vb) * ca.exp(-self.eta(vb, us) * (tau - ts))

    def delay_indices(self, n_steps: int, dt: float):
        """(ia, ib, ts): through the delay τ = m·dt + s, physics step r holds the command of step ``ia[r] = r − m − 1``
        until t_r + ``ts`` (= s) and that of step ``ib[r] = r − m`` after it (a negative index: the command before
        the episode, the initial effective command, as the stepping routine's queue)."""
        m, s = delay_split(self.command.delay, dt)
        r = np.arange(int(n_steps))
        return r - m - 1, r - m, float(s)

    def delayed(self, V: np.ndarray, dt: float, u_before) -> tuple[np.ndarray, np.ndarray, float]:
        """(Va, Vb, ts) for held commands V (n_steps, nd) per physics step (:meth:`delay_indices`), numerically."""
        V = np.asarray(V, dtype=float).reshape(len(V), -1)
        ia, ib, ts = self.delay_indices(len(V), dt)
        before = np.broadcast_to(np.asarray(u_before, dtype=float), V.shape[1:])
        Va = np.where((ia >= 0)[:, None], V[np.maximum(ia, 0)], before)
        Vb = np.where((ib >= 0)[:, None], V[np.maximum(ib, 0)], before)
        return Va, Vb, ts


def symbolic_damper(damper: DamperModel, **eps) -> SymbolicDamper:
    """The CasADi version of ``damper`` (``ValueError`` for a model outside :data:`SUPPORTED_MODELS`);
    ``eps_v``, ``eps_z``, ``eps_u``: the smoothing (module docstring)."""
    return SymbolicDamper(damper, **eps)


class CoupledModel:
    """A linear plant with ``nd`` copies of a symbolic damper, in CasADi.

    State Y = [x (nx), s_1 (ns), ..., s_nd (ns)]; inputs w (nw); effective commands u (nd). The damper strokes
    are C_x x + D_x w and their rates C_v x + D_v w (D_x, D_v default zero, as in the environments).
    """

    def __init__(self, damper: SymbolicDamper, A, BF, Bw, Cx, Cv, Dx=None, Dv=None):
        self.damper = damper
        self.A = np.asarray(A, dtype=float)
        self.BF = np.asarray(BF, dtype=float)
        self.Bw = np.asarray(Bw, dtype=float)
        self.Cx = np.asarray(Cx, dtype=float)
        self.Cv = np.asarray(Cv, dtype=float)
        self.nx = self.A.shape[0]
        self.nd = self.Cx.shape[0]
        self.nw = self.Bw.shape[1]
        self.Dx = np.zeros((self.nd, self.nw)) if Dx is None else np.asarray(Dx, dtype=float)
        self.Dv = np.zeros((self.nd, self.nw)) if Dv is None else np.asarray(Dv, dtype=float)
        self.ns = damper.ns
        self.ny = self.nx + self.nd * self.ns
        shapes = {"A": (self.nx, self.nx), "BF": (self.nx, self.nd), "Bw": (self.nx, self.nw),
                  "Cx": (self.nd, self.nx), "Cv": (self.nd, self.nx), "Dx": (self.nd, self.nw),
                  "Dv": (self.nd, self.nw)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, expected {shape}")

    @classmethod
    def rig(cls, damper: SymbolicDamper) -> "CoupledModel":
        """No plant: one damper whose stroke and rate are the inputs w = (x, ẋ) (the virtual rig)."""
        e = np.eye(2)
        return cls(damper, np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((0, 2)), np.zeros((1, 0)),
                   np.zeros((1, 0)), Dx=e[0:1], Dv=e[1:2])

    def initial_state(self, x0=None, w0=None) -> np.ndarray:
        """Y at plant state ``x0`` (default zero) and inputs ``w0`` (default zero), the dampers' internal states at
        rest at their strokes there, as the environments reset them (:meth:`~mrd_env.dampers.DamperModel.rest_state`)."""
        Y = np.zeros(self.ny)
        if x0 is not None:
            Y[:self.nx] = x0
        strokes = self.Cx @ Y[:self.nx]
        if w0 is not None:
            strokes = strokes + self.Dx @ np.asarray(w0, dtype=float)
        Y[self.nx:] = self.damper.damper.rest_states(strokes)
        return Y

    def split(self, Y):
        """(x, [s_1, ..., s_nd])."""
        x = Y[:self.nx]
        ss = [Y[self.nx + j * self.ns:self.nx + (j + 1) * self.ns] for j in range(self.nd)]
        return x, ss

    def kinematics(self, Y, w):
        """(strokes, rates): two columns of nd."""
        ca = _casadi()
        xs = ca.mtimes(ca.DM(self.Dx), w)
        vs = ca.mtimes(ca.DM(self.Dv), w)
        if self.nx:
            x = Y[:self.nx]
            xs = xs + ca.mtimes(ca.DM(self.Cx), x)
            vs = vs + ca.mtimes(ca.DM(self.Cv), x)
        return xs, vs

    def forces(self, Y, w, u):
        """The damper forces F (column of nd)."""
        ca = _casadi()
        _, ss = self.split(Y)
        xs, vs = self.kinematics(Y, w)
        return ca.vertcat(*[self.damper.force(ss[j], xs[j], vs[j], u[j]) for j in range(self.nd)])

    def f(self, Y, w, u):
        """(Ẏ, F): the state derivative and the damper forces."""
        ca = _casadi()
        x, ss = self.split(Y)
        xs, vs = self.kinematics(Y, w)
        F = ca.vertcat(*[self.damper.force(ss[j], xs[j], vs[j], u[j]) for j in range(self.nd)])
        sd = [self.damper.rhs(ss[j], xs[j], vs[j], u[j]) for j in range(self.nd)]
        parts = []
        if self.nx:
            parts.append(ca.mtimes(ca.DM(self.A), x) + ca.mtimes(ca.DM(self.BF), F) + ca.mtimes(ca.DM(self.Bw), w))
        return ca.vertcat(*parts, *sd), F

    def stage_commands(self, u0, va, vb, ts: float, h: float):
        """The effective commands at the two SDIRK stages (t + γh, t + h), exact (lists over the dampers)."""
        d = self.damper
        u1 = [d.lag(u0[j], va[j], vb[j], ts, GAMMA * h) for j in range(self.nd)]
        u2 = [d.lag(u0[j], va[j], vb[j], ts, h) for j in range(self.nd)]
        ca = _casadi()
        return ca.vertcat(*u1), ca.vertcat(*u2)

    def sdirk_residual(self, Y0, Z1, Y1, w0, w1, u0, va, vb, ts: float, h: float):
        """The residuals (2·ny) of one SDIRK2 step of length h from Y0 with stage value Z1 and result Y1 — the
        stepping routine's scheme (:mod:`mrd_env.stepping`):

            Z1 = Y0 + hγ f(t + γh, Z1),     Y1 = Y0 + (1 − γ)/γ (Z1 − Y0) + hγ f(t + h, Y1)

        with w linear inside the step and the commands at the stages exact from u0 and the delayed commands va
        (until ``ts``), vb (after). Returns (residual, effective command at the step's end)."""
        ca = _casadi()
        g = GAMMA
        u1, u2 = self.stage_commands(u0, va, vb, ts, h)
        f1, _ = self.f(Z1, w0 + (w1 - w0) * g, u1)
        f2, _ = self.f(Y1, w1, u2)
        r1 = Z1 - Y0 - h * g * f1
        r2 = Y1 - Y0 - (1.0 - g) / g * (Z1 - Y0) - h * g * f2
        return ca.vertcat(r1, r2), u2

    def step_function(self, h: float, ts: float = 0.0, sym: str = "SX"):
        """``Function('step', [Y0, Z1, Y1, w0, w1, u0, va, vb], [residual, u_end])`` of :meth:`sdirk_residual`."""
        ca = _casadi()
        S = getattr(ca, sym)
        Y0, Z1, Y1 = S.sym("Y0", self.ny), S.sym("Z1", self.ny), S.sym("Y1", self.ny)
        w0, w1 = S.sym("w0", self.nw), S.sym("w1", self.nw)
        u0, va, vb = S.sym("u0", self.nd), S.sym("va", self.nd), S.sym("vb", self.nd)
        res, u_end = self.sdirk_residual(Y0, Z1, Y1, w0, w1, u0, va, vb, ts, h)
        return ca.Function("step", [Y0, Z1, Y1, w0, w1, u0, va, vb], [res, u_end],
                           ["Y0", "Z1", "Y1", "w0", "w1", "u0", "va", "vb"], ["res", "u_end"])

    def smooth_project(self, Y, width: float | None = None):
        """:meth:`project` with the clip smoothed over ``width`` (m; default ε_z·z_s): z − sp(z − z_s) + sp(−z − z_s),
        sp(a) = w·log(1 + exp(a/w)) — for optimisers, which need a smooth step."""
        ca = _casadi()
        d = self.damper
        if d.p["gamma"] < 0.0:
            return Y
        w = d.smoothing.eps_z * d.z_s if width is None else width
        if w <= 0:
            return self.project(Y)

        def sp(a):
            return ca.fmax(a, 0) + w * ca.log1p(ca.exp(-ca.fabs(a) / w))

        iz = d.ns - 1
        parts = [Y[i] for i in range(self.ny)]
        for j in range(self.nd):
            k = self.nx + j * d.ns + iz
            z = parts[k]
            parts[k] = z - sp(z - d.z_s) + sp(-z - d.z_s)
        return ca.vertcat(*parts)

    def newton_step(self, h: float, ts: float = 0.0, iterations: int = 4, project: str = "smooth"):
        """One step of the stepping routine as an explicit expression: ``Function('step', [Y0, F0, w0, w1, u0, va, vb],
        [Y1, F1, u1])``.

        Each SDIRK stage Z = R + hγ f(Z) is solved as the stepping routine solves it — the linear plant eliminated,
        x = (I − hγA)⁻¹(R_x + hγ B_w w) + hγ(I − hγA)⁻¹B_F F, Newton's method on each damper's internal states and
        force only — but with a fixed number of Newton ``iterations`` (from the previous force F0 and state Y0, as
        the stepping routine starts), so that the step is one differentiable expression (no branches), cheap to
        evaluate and to differentiate in reverse mode over a whole episode. Four iterations reach rounding error on
        the benchmark episodes (three: 1e-8 relative; a test checks the step against :meth:`simulate`'s converged
        stages). ``project``: "smooth" (:meth:`smooth_project`, for optimisers), "exact" (:meth:`project`, as the
        stepping routine) or "none". F1 is the force at the step's end state and command (the routine's
        ``end_forces``)."""
        ca = _casadi()
        if project not in ("smooth", "exact", "none"):
            raise ValueError(f"project must be 'smooth', 'exact' or 'none', got {project!r}")
        g = GAMMA
        hg = h * g
        nx, nd, ns, ny = self.nx, self.nd, self.ns, self.ny
        S = ca.SX
        # the stage solve: unknowns q = [s_1..s_nd, F] given R, w, u
        q, R, w, u = S.sym("q", nd * ns + nd), S.sym("R", ny), S.sym("w", self.nw), S.sym("u", nd)
        s_all, F = q[:nd * ns], q[nd * ns:]
        if nx:
            Minv = np.linalg.inv(np.eye(nx) - hg * self.A)
            x = ca.mtimes(ca.DM(Minv), R[:nx] + hg * ca.mtimes(ca.DM(self.Bw), w)) + \
                ca.mtimes(ca.DM(hg * Minv @ self.BF), F)
        else:
            x = S(0, 1)
        Yq = ca.vertcat(x, s_all)
        _, ss = self.split(Yq)
        xs, vs = self.kinematics(Yq, w)
        rs, rF = [], []
        for j in range(nd):
            Rj = R[nx + j * ns:nx + (j + 1) * ns]
            rs.append(ss[j] - Rj - hg * self.damper.rhs(ss[j], xs[j], vs[j], u[j]))
            rF.append(F[j] - self.damper.force(ss[j], xs[j], vs[j], u[j]))
        res = ca.vertcat(*rs, *rF)
        newton = ca.Function("newton", [q, R, w, u], [q - ca.solve(ca.jacobian(res, q), res)])

        def solve_stage(R_, w_, u_, q0):
            qk = q0
            for _ in range(iterations):
                qk = newton(qk, R_, w_, u_)
            return qk

        xfun = ca.Function("x_of_q", [q, R, w], [x])
        Y0, F0 = S.sym("Y0", ny), S.sym("F0", nd)
        w0, w1 = S.sym("w0", self.nw), S.sym("w1", self.nw)
        u0, va, vb = S.sym("u0", nd), S.sym("va", nd), S.sym("vb", nd)
        u1, u2 = self.stage_commands(u0, va, vb, ts, h)
        wg = w0 + (w1 - w0) * g
        q1 = solve_stage(Y0, wg, u1, ca.vertcat(Y0[nx:], F0))
        Z1 = ca.vertcat(xfun(q1, Y0, wg), q1[:nd * ns])
        R2 = Y0 + (1.0 - g) / g * (Z1 - Y0)
        q2 = solve_stage(R2, w1, u2, q1)
        Y1 = ca.vertcat(xfun(q2, R2, w1), q2[:nd * ns])
        if project == "smooth":
            Y1 = self.smooth_project(Y1)
        elif project == "exact":
            Y1 = self.project(Y1)
        F1 = self.forces(Y1, w1, u2)
        return ca.Function("step", [Y0, F0, w0, w1, u0, va, vb], [Y1, F1, u2],
                           ["Y0", "F0", "w0", "w1", "u0", "va", "vb"], ["Y1", "F1", "u1"])

    def project(self, Y):
        """Y with every damper's z clipped to its saturation ±z_s (the stepping routine's projection after each
        step: an implicit step may overshoot the bound, which the exact solution never crosses). Not smooth: for
        simulations, never inside an optimiser."""
        ca = _casadi()
        d = self.damper
        if d.p["gamma"] < 0.0:  # ±z_s is invariant only for γ >= 0 (as clip_to_saturation)
            return Y
        iz = d.ns - 1  # z is the last internal state of both supported models
        parts = [Y[i] for i in range(self.ny)]
        for j in range(self.nd):
            k = self.nx + j * d.ns + iz
            parts[k] = ca.fmin(ca.fmax(parts[k], -d.z_s), d.z_s)
        return ca.vertcat(*parts)

    def simulator(self, h: float, ts: float = 0.0, project: bool = True):
        """``Function('sim_step', [Y0, w0, w1, u0, va, vb], [Z1, Y1, u_end])``: one step, the stage equations solved
        by Newton's method (CasADi ``rootfinder``, started from Y0), the result projected as the stepping routine
        does (:meth:`project`) unless ``project`` is False. ``mapaccum`` it for a trajectory."""
        ca = _casadi()
        S = ca.SX
        Y0, Z1, Y1 = S.sym("Y0", self.ny), S.sym("Z1", self.ny), S.sym("Y1", self.ny)
        w0, w1 = S.sym("w0", self.nw), S.sym("w1", self.nw)
        u0, va, vb = S.sym("u0", self.nd), S.sym("va", self.nd), S.sym("vb", self.nd)
        res, u_end = self.sdirk_residual(Y0, Z1, Y1, w0, w1, u0, va, vb, ts, h)
        # the two stages one after the other (the first does not depend on Y1)
        n = self.ny
        p = ca.vertcat(Y0, w0, w1, u0, va, vb)
        g1 = ca.Function("g1", [Z1, p], [res[:n]])
        g2 = ca.Function("g2", [Y1, ca.vertcat(p, Z1)], [res[n:]])
        opts = {"abstol": 1e-12, "max_iter": 50, "error_on_fail": False}
        rf1 = ca.rootfinder("rf1", "newton", g1, opts)
        rf2 = ca.rootfinder("rf2", "newton", g2, opts)
        z1 = rf1(Y0, p)
        y1 = rf2(z1, ca.vertcat(p, z1))
        if project:
            y1 = self.project(y1)
        u_fun = ca.Function("u_end", [u0, va, vb], [u_end])
        return ca.Function("sim_step", [Y0, w0, w1, u0, va, vb], [z1, y1, u_fun(u0, va, vb)],
                           ["Y0", "w0", "w1", "u0", "va", "vb"], ["Z1", "Y1", "u_end"])

    def simulate(self, Y0, W, U0, Va, Vb, h: float, ts: float = 0.0, project: bool = True):
        """Trajectory of the discretised model: W (n_steps + 1, nw) inputs at the step ends, Va/Vb (n_steps, nd) the
        (delayed) commands of each step, U0 (nd) the initial effective command. Returns (Y (n_steps + 1, ny),
        Z1 (n_steps, ny), U (n_steps + 1, nd), F (n_steps + 1, nd))."""
        ca = _casadi()
        W = np.asarray(W, dtype=float)
        Va = np.asarray(Va, dtype=float).reshape(-1, self.nd)
        Vb = np.asarray(Vb, dtype=float).reshape(-1, self.nd)
        n = Va.shape[0]
        step = self.simulator(h, ts, project)
        # accumulate (Y, u) through the steps; the stage values ride along as a non-accumulated output
        Yc, uc = ca.SX.sym("Y", self.ny), ca.SX.sym("u", self.nd)
        w0, w1, va, vb = (ca.SX.sym(k, m) for k, m in (("w0", self.nw), ("w1", self.nw), ("va", self.nd),
                                                      ("vb", self.nd)))
        z1, y1, u1 = step(Yc, w0, w1, uc, va, vb)
        acc = ca.Function("acc", [ca.vertcat(Yc, uc), ca.vertcat(w0, w1, va, vb)],
                          [ca.vertcat(y1, u1), z1])
        sim = acc.mapaccum("sim", n)
        inputs = np.hstack([W[:-1], W[1:], Va, Vb]).T
        X, Z = sim(np.concatenate([np.asarray(Y0, float), np.asarray(U0, float).ravel()]), inputs)
        X = np.asarray(X).T
        Y = np.vstack([np.asarray(Y0, float)[None], X[:, :self.ny]])
        U = np.vstack([np.asarray(U0, float).ravel()[None], X[:, self.ny:]])
        Ffun = ca.Function("F", [Yc, w0, uc], [self.forces(Yc, w0, uc)]).map(n + 1)
        F = np.asarray(Ffun(Y.T, W.T, U.T)).T
        return Y, np.asarray(Z).T, U, F
