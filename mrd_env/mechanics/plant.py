"""Linear mechanical plants coupled to MR dampers.

A plant with n degrees of freedom q, n_d dampers and exogenous inputs w (road or ground motion)::

    M q̈ + C q̇ + K q = −Sᵀ F + E w + Sᵀ F_static          (F: damper forces, positive resisting extension)
    x_d = S q,  ẋ_d = S q̇                                  (damper strokes)

``S`` (n_d × n) maps the coordinates to the damper strokes, so −Sᵀ F is the damper's generalised force
(virtual work). Coordinates are measured from static equilibrium with the dampers at rest at their
minimum command: the damper's static force at rest F_static (an accumulator preload such as k1·x0) is
balanced by a constant term, so a plant at rest stays at rest. A plant held at rest off that point (a car's
four wheels on a warped road) has its dampers' internal states at rest at their strokes and their static
stiffness (k1·x_d) in its equilibrium (:meth:`LinearPlant.static_deflection`). A damper's inertance m_d (a force term
m_d·ẍ_d) is added to the mass matrix as m_d Sᵀ S. The coupled first-order system is handed to the shared
stepping routine (:mod:`mrd_env.stepping`), which advances plant and damper states together.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dampers import DamperModel
from ..stepping import Stepper, SystemMatrices, kernel_module
from ..validation import check_array


@dataclass(frozen=True)
class LinearPlant:
    """Second-order plant matrices (SI). ``input_names`` label the columns of E (the channels of w)."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    S: np.ndarray
    E: np.ndarray
    input_names: tuple[str, ...]
    dof_names: tuple[str, ...]
    #: the plant parameter that is each coordinate's mass or inertia ("m_s", "masses[0]", "I_y"), for messages
    mass_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.dof_names)
        for name, shape in (("M", (n, n)), ("C", (n, n)), ("K", (n, n)), ("E", (n, len(self.input_names)))):
            object.__setattr__(self, name, check_array(name, getattr(self, name), shape=shape))
        S = check_array("S", self.S, ndim=2)
        if S.shape[1] != n:
            raise ValueError(f"S must have {n} columns (one per degree of freedom), got shape {S.shape}")
        object.__setattr__(self, "S", S)
        if np.any(np.linalg.eigvalsh(0.5 * (self.M + self.M.T)) <= 0):
            raise ValueError("M must be symmetric positive definite (all masses > 0)")

    @property
    def n_dof(self) -> int:
        return self.M.shape[0]

    def check_resolved(self, dt: float) -> None:
        """``ValueError`` if the plant moves faster than a physics step of ``dt`` resolves, which no mass, stiffness
        or damping of a real plant does: a natural frequency above the Nyquist frequency 1/(2·dt) (500 Hz at 1 ms),
        or a damping rate c/m above 2π/dt (critical damping of that frequency). Such a plant (a mass of 1e-300 kg)
        gives infinite or NaN observations. The message names the coordinate's mass parameter, its value and the
        smallest mass these stiffnesses and dampings allow (or the largest stiffness for this mass)."""
        w_max = np.pi / dt
        M, K, C = self.M, self.K, self.C
        diag = np.allclose(M, np.diag(np.diag(M)))
        with np.errstate(all="ignore"):
            # the Gershgorin bounds of M⁻¹K and M⁻¹C row by row (M diagonal): each at least the coordinate's share
            k_row = np.sum(np.abs(K), axis=1)
            c_row = np.sum(np.abs(C), axis=1)
            m = np.diag(M)
            try:
                lam = np.linalg.eigvals(np.linalg.solve(M, K))
                rate = np.linalg.eigvals(np.linalg.solve(M, C))
                w = float(np.sqrt(np.max(np.abs(lam))))
                g = float(np.max(np.abs(rate)))
            except np.linalg.LinAlgError:
                w = g = np.inf
        if not np.isfinite(w) or not np.isfinite(g):
            w, g = np.inf, np.inf
        if w <= w_max and g <= 2.0 * w_max:
            return
        names = self.mass_names if len(self.mass_names) == self.n_dof else tuple(
            f"the mass of {d!r}" for d in self.dof_names)
        nyquist = 0.5 / dt
        if w > w_max:
            i = int(np.argmax(k_row / m)) if diag else 0
            floor = k_row[i] / w_max ** 2
            what = (f"a natural frequency of {w / (2 * np.pi):.3g} Hz, above the {nyquist:g} Hz a physics step of "
                    f"dt = {dt:g} s resolves (1/(2·dt))")
            valid = (f"with these stiffnesses (row sum {k_row[i]:.3g}) {names[i]} must be at least {floor:.3g}, or the "
                     f"stiffnesses on it at most {m[i] * w_max ** 2:.3g}")
        else:
            i = int(np.argmax(c_row / m)) if diag else 0
            floor = c_row[i] / (2.0 * w_max)
            what = (f"a damping rate c/m of {g:.3g} 1/s, above the {2 * w_max:.3g} 1/s (2π/dt) a physics step of "
                    f"dt = {dt:g} s resolves")
            valid = (f"with these dampings (row sum {c_row[i]:.3g} N·s/m) {names[i]} must be at least {floor:.3g}, "
                     f"or the damping on it at most {2 * w_max * m[i]:.3g} N·s/m")
        raise ValueError(f"plant_params: {names[i]} = {m[i]:.3g} gives {what}: no real plant moves that fast; "
                         f"{valid} (or a smaller dt)")

    @property
    def n_dampers(self) -> int:
        return self.S.shape[0]

    def state_space(self, inertance: float = 0.0, extra_damping: np.ndarray | float = 0.0):
        """(A, B_F, B_w) of q' = [q, q̇] with damper forces F and inputs w as inputs.

        ``extra_damping``: viscous coefficient(s) added across the dampers (a linear dashpot c·ẋ_d in
        place of, or besides, the MR damper), used for the linear checks against python-control.
        """
        n = self.n_dof
        c_d = np.broadcast_to(np.asarray(extra_damping, dtype=float), (self.n_dampers,))
        M = self.M + inertance * self.S.T @ self.S
        C = self.C + self.S.T @ np.diag(c_d) @ self.S
        Minv = np.linalg.inv(M)
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -Minv @ self.K
        A[n:, n:] = -Minv @ C
        BF = np.vstack([np.zeros((n, self.n_dampers)), -Minv @ self.S.T])
        Bw = np.vstack([np.zeros((n, self.E.shape[1])), Minv @ self.E])
        return A, BF, Bw

    def static_deflection(self, load: np.ndarray, damper: DamperModel | None = None, u: float | None = None,
                          *, tol: float = 1e-12, max_iter: int = 50) -> np.ndarray:
        """q at rest under the static generalised ``load`` (e.g. E w): K q + Sᵀ (F_r(S q) − F_r(0)) = load, F_r the
        ``damper``'s force at rest at each stroke (:meth:`~mrd_env.dampers.DamperModel.rest_force`, effective
        command ``u``, default its minimum: e.g. a Spencer–Dyke accumulator's k1·x_d), Newton's method from the
        linear solution; without a damper K q = load."""
        q = np.linalg.solve(self.K, load)
        if damper is None or not np.any(q):
            return q
        u = damper.command.v_min if u is None else u
        f0 = damper.rest_force(0.0, u)

        def f(x):
            return np.array([damper.rest_force(float(v), u) - f0 for v in x])

        scale = max(float(np.max(np.abs(load))), 1e-300)
        for _ in range(max_iter):
            x = self.S @ q
            r = self.K @ q + self.S.T @ f(x) - load
            if np.max(np.abs(r)) <= tol * scale:
                return q
            h = 1e-7 * np.maximum(np.abs(x), 1e-3)
            k = (f(x + h) - f(x - h)) / (2 * h)
            q = q - np.linalg.solve(self.K + self.S.T @ np.diag(k) @ self.S, r)
        raise ValueError(f"no static equilibrium with the {damper.name!r} damper's rest forces after {max_iter} "
                         f"Newton steps (residual {np.max(np.abs(r)):.3g} of a load {scale:.3g}): its force at rest "
                         "jumps near the strokes of this load")


class CoupledPlant:
    """A :class:`LinearPlant` with one damper model at every damper location, stepped in batches.

    ``N`` independent copies (vectorised environments) share matrices; each copy has its own states.
    The inputs are w = (plant inputs..., 1) — the last channel carries the static preload balance.
    """

    def __init__(self, plant: LinearPlant, damper: DamperModel, *, N: int = 1, n_steps: int = 1,
                 dt: float = 1e-3, **integrator_options):
        self.plant = plant
        self.damper = damper
        kernel_module(type(damper))  # first, so that with a cold cache nothing below waits for numba (first_use)
        nd = plant.n_dampers
        m_d = damper.inertance()
        A, BF, Bw = plant.state_space(inertance=m_d)
        F_static = damper.force(0.0, 0.0, damper.command.v_min)
        Minv = np.linalg.inv(plant.M + m_d * plant.S.T @ plant.S)
        bias = np.concatenate([np.zeros(plant.n_dof), Minv @ plant.S.T @ np.full(nd, F_static)])
        n = plant.n_dof
        Cx = np.hstack([plant.S, np.zeros_like(plant.S)])
        Cv = np.hstack([np.zeros_like(plant.S), plant.S])
        self.nw = plant.E.shape[1] + 1
        self.system = SystemMatrices(nd=nd, nw=self.nw, A=A, BF=BF, Bw=np.hstack([Bw, bias[:, None]]),
                                     Cx=Cx, Cv=Cv)
        self.F_static = F_static
        self.n = 2 * n + nd * damper.n_states
        self._stepping = (N, n_steps, dt, integrator_options)
        self._stepper = None

    @property
    def stepper(self) -> Stepper:
        """The batch stepper of :meth:`step` (built on first use: environments use their own compiled core)."""
        if self._stepper is None:
            N, n_steps, dt, options = self._stepping
            self._stepper = Stepper(self.damper, self.system, N, n_steps, dt, **options)
            self.reset()
        return self._stepper

    @property
    def N(self) -> int:
        return self._stepping[0]

    def reset(self, q0: np.ndarray | None = None) -> None:
        """All copies at rest (or at plant state ``q0`` = [q, q̇], the dampers' internal states at rest at its
        strokes), effective command at its minimum."""
        st = self.stepper
        st.Y[:] = 0.0
        n2 = 2 * self.plant.n_dof
        if q0 is not None:
            st.Y[:, :n2] = q0
        st.Y[:, n2:] = self.damper.rest_states(self.plant.S @ st.Y[0, :self.plant.n_dof])
        st.U[:] = self.damper.command.v_min
        st.t = 0.0

    def inputs(self, w: np.ndarray) -> np.ndarray:
        """Append the constant channel to plant inputs of shape (N, n_steps + 1, n_inputs)."""
        return np.concatenate([w, np.ones(w.shape[:2] + (1,))], axis=2)

    def step(self, V: np.ndarray, w: np.ndarray):
        """Advance with commands V (N, n_steps, nd) and plant inputs w (N, n_steps + 1, n_inputs).

        Returns (F (N, n_steps, nd), Y (N, n_steps, n)) at the end of every step (views; copy to keep).
        """
        return self.stepper.step(V, self.inputs(w))

    def accelerations(self, Y: np.ndarray, F: np.ndarray, W: np.ndarray) -> np.ndarray:
        """q̈ from states, forces and full inputs W (with the constant channel): (..., n_dof)."""
        s = self.system
        n = self.plant.n_dof
        qdot = Y[..., : 2 * n] @ s.A.T + F @ s.BF.T + W @ s.Bw.T
        return qdot[..., n:]


def preset_with_overrides(presets: dict, name: str, kind: str, overrides: dict):
    """The preset ``name`` of a frozen-dataclass family, with field ``overrides`` (validated anew)."""
    if not isinstance(name, str) or name not in presets:
        raise ValueError(f"unknown {kind} preset {name!r}; available: {sorted(presets)}")
    base = presets[name]
    if not overrides:
        return base
    fields = {k: getattr(base, k) for k in base.__dataclass_fields__}
    unknown = set(overrides) - set(fields)
    if unknown:
        raise ValueError(f"unknown {kind} parameter(s) {sorted(unknown)}; valid: {sorted(fields)}")
    return type(base)(**{**fields, **overrides})
