"""Model-based semi-active laws: clipped-optimal LQG (Dyke et al. 1996) and Lyapunov (Jansen & Dyke 2000).

Both design on the linear model the environment declares, with the damper forces f as the control input
(python-control):

    ẋ = A x + B_f f + B_w w,    x = [q, q̇]        (``env.linear_plant.state_space``)
    y = C_y x + D_y f                              measured outputs (``env.signal_matrices(sensor)``)

and run a discrete Kalman filter (``control.dlqe`` on the zero-order-hold model at the control period) fed with
the measured outputs and the measured damper forces; the disturbance w is its process noise. A sensor is a
usable measurement when it is a linear output that does not depend directly on the unknown disturbance
(D_w = 0: accelerations of the sprung mass or of the floors in absolute terms, strokes, velocities; not the
unsprung acceleration, which the road drives directly, nor the ground acceleration itself).
"""
from __future__ import annotations

import control
import numpy as np
from scipy.linalg import expm, solve_discrete_are

from .base import Controller


class LinearDesign:
    """The plant's linear model in the form the designs need, from what ``env.unwrapped`` declares."""

    def __init__(self, env):
        self.env = env
        lp = env.linear_plant
        self.plant = lp
        self.A, self.Bf, self.Bw = lp.state_space(inertance=env.damper.inertance())
        self.n = self.A.shape[0]
        self.n_dof = lp.n_dof
        self.nd = lp.n_dampers

    def output(self, sensor: str):
        """(C, D_f) of a signal, or None if it is not a usable measurement (see the module docstring)."""
        if sensor in ("damper_force", "command"):
            return None
        try:
            m = self.env.signal_matrices(sensor)
        except ValueError:
            return None
        if np.max(np.abs(m["D_w"]), initial=0.0) > 1e-9 * max(1.0, np.max(np.abs(m["C"]), initial=0.0)):
            return None
        return m["C"], m["D_F"]

    def regulated(self, weights: dict):
        """(C_z, D_z) stacked from weighted outputs ``{signal: weight}`` (weights on squared outputs)."""
        Cs, Ds = [], []
        for name, w in weights.items():
            out = self.output(name)
            if out is None:
                raise ValueError(f"cannot regulate {name!r}: it is not a function of the plant state and forces")
            Cs.append(np.sqrt(w) * out[0])
            Ds.append(np.sqrt(w) * out[1])
        return np.vstack(Cs), np.vstack(Ds)


def van_loan(Ac: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """(Φ, Q_d) with Φ = e^{A_c T} and Q_d = ∫₀ᵀ e^{A_cᵀt} Q_c e^{A_c t} dt, from one matrix exponential
    (Van Loan 1978, "Computing integrals involving the matrix exponential", IEEE TAC 23(3), theorem 1):
    expm([[−A_cᵀ, Q_c], [0, A_c]]·T) = [[·, G], [0, Φ]], Q_d = Φᵀ G."""
    n = Ac.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -Ac.T
    M[:n, n:] = Qc
    M[n:, n:] = Ac
    E = expm(M * T)
    Phi = E[n:, n:]
    Qd = Phi.T @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)


def sampled_lq(A, B, Q, R, N, T: float):
    """The sampled-data LQ problem of ẋ = A x + B u, J = ∫ xᵀQx + 2xᵀNu + uᵀRu dt with u held over each period T
    (zero-order hold), exactly: J = Σ_k x_kᵀ Q_d x_k + 2 x_kᵀ N_d u_k + u_kᵀ R_d u_k, x_{k+1} = Φ x_k + Γ u_k
    (Van Loan 1978; Franklin, Powell & Workman, Digital Control of Dynamic Systems, 3rd ed., §9.4.4).

    Returns (Φ, Γ, Q_d, R_d, N_d)."""
    n, m = B.shape
    Ac = np.zeros((n + m, n + m))
    Ac[:n, :n], Ac[:n, n:] = A, B
    Qc = np.block([[Q, N], [N.T, R]])
    E, Qd = van_loan(Ac, Qc, T)
    return E[:n, :n], E[:n, n:], Qd[:n, :n], Qd[n:, n:], Qd[:n, n:]


def dlqr(Phi, Gamma, Q, R, N):
    """Infinite-horizon discrete LQR with a cross term: P from the discrete algebraic Riccati equation,
    K = (R + ΓᵀPΓ)⁻¹(ΓᵀPΦ + Nᵀ), u_k = −K x_k. Returns (K, P)."""
    P = solve_discrete_are(Phi, Gamma, Q, R, s=N)
    P = 0.5 * (P + P.T)
    K = np.linalg.solve(R + Gamma.T @ P @ Gamma, Gamma.T @ P @ Phi + N.T)
    return K, P


class KalmanEstimator:
    """Stationary discrete Kalman filter (predictor form, ``control.dlqe``) at the control period, for a batch
    of independent estimates (one row each).

    x̂[k+1] = Φ x̂[k] + Γ_f f[k] + L (y[k] − C x̂[k] − D f[k])
    """

    def __init__(self, design: LinearDesign, C: np.ndarray, D: np.ndarray, dt: float,
                 process_noise: float, measurement_noise: np.ndarray):
        n, nd, nw = design.n, design.nd, design.Bw.shape[1]
        M = np.zeros((n + nd + nw, n + nd + nw))
        M[:n, :n] = design.A
        M[:n, n:n + nd] = design.Bf
        M[:n, n + nd:] = design.Bw
        E = expm(M * dt)  # zero-order-hold discretisation of A, B_f and B_w together
        self.Phi, self.Gf, self.Gw = E[:n, :n], E[:n, n:n + nd], E[:n, n + nd:]
        self.C, self.D = C, D
        QN = process_noise * np.eye(nw)
        RN = np.diag(np.broadcast_to(measurement_noise, (C.shape[0],)).astype(float))
        self.L, self.P, self.poles = control.dlqe(self.Phi, self.Gw, C, QN, RN)
        self.L = np.asarray(self.L)
        # the same update regrouped: x̂[k+1] = (Φ − LC) x̂ + (Γ_f − LD) f + L y, transposed for row batches
        self._AxT = np.ascontiguousarray((self.Phi - self.L @ C).T)
        self._BfT = np.ascontiguousarray((self.Gf - self.L @ D).T)
        self._LT = np.ascontiguousarray(self.L.T)
        self.x = np.zeros((1, n))

    def allocate(self, n_rows: int) -> None:
        self.x = np.zeros((n_rows, self.Phi.shape[0]))

    def reset(self, mask=None):
        if mask is None:
            self.x[:] = 0.0
        else:
            self.x[mask] = 0.0

    def update(self, y: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Return x̂[k] (the prediction from the past, (N, n)) and advance the filter with y[k], f[k] (rows)."""
        x = self.x
        self.x = x @ self._AxT + f @ self._BfT + y @ self._LT
        return x


class _ObserverLaw(Controller):
    """Shared part of the model-based laws: measured outputs → Kalman estimate x̂."""

    requires = ("damper_force",)
    measurement_noise_default = 0.05  # RMS of each measured output, SI (m/s², m, m/s)

    def __init__(self, env, measurements=None, process_noise: float = 1.0, measurement_noise=None):
        super().__init__(env)
        self.design = LinearDesign(self.env)
        if measurements is None:
            usable = [n for n in self.layout if self.design.output(n) is not None]
        else:
            usable = list(measurements)
        if not usable:
            raise ValueError(f"{type(self).__name__} needs at least one measured response (a linear output that "
                             f"does not depend directly on the disturbance); the environment measures "
                             f"{list(self.layout)}")
        for name in usable:
            if name not in self.layout:
                raise ValueError(f"measurement {name!r} is not among the environment's sensors {list(self.layout)}")
            if self.design.output(name) is None:
                raise ValueError(f"measurement {name!r} is not a usable measured response")
        self.measurements = usable
        self._y_index = np.concatenate([np.arange(self.layout[n].start, self.layout[n].stop) for n in usable])
        Cs, Ds = zip(*(self.design.output(n) for n in usable))
        C, D = np.vstack(Cs), np.vstack(Ds)
        noise = self.measurement_noise_default if measurement_noise is None else measurement_noise
        self.kf = KalmanEstimator(self.design, C, D, self.control_dt, process_noise,
                                  np.broadcast_to(np.asarray(noise, float) ** 2, (C.shape[0],)))

    def allocate(self, n_rows):
        super().allocate(n_rows)
        self.kf.allocate(n_rows)

    def reset_rows(self, mask):
        self.kf.reset(mask)

    def estimate(self, obs):
        y = obs[:, self._y_index]
        f = self.dynamic_force(obs)
        return self.kf.update(y, f), f


class ClippedOptimal(_ObserverLaw):
    """Clipped-optimal control (Dyke, Spencer, Sain & Carlson 1996).

    An LQR (``control.lqr``) on the weighted responses z = C_z x + D_z f, J = ∫ zᵀz + fᵀ R f dt, gives
    f_c = −K x̂ from the Kalman estimate x̂; the damper command is the clipped on–off law
    u = u_max·H((f_c − f)·f) with f the measured damper force beyond its static preload (the force the linear
    model's input stands for).

    ``weights``: {signal: weight on its square}; default the environment's declared objective (building: the
    interstorey drifts with 1/(5 mm)²; quarter car: sprung acceleration with 1/(1 m/s²)² and travel with
    1/(5 cm)²). R = 1/(force_ref)² per damper with force_ref = 3000 N (the prototype damper's force scale;
    with these the El Centro lab ranking of Dyke et al. 1996 is reproduced, see the README).

    ``design``: "continuous" (default) the continuous-time LQR above; "sampled" the LQR of the same cost for the
    force held over each control period ``control_dt`` — the sampled-data problem solved exactly
    (:func:`sampled_lq`, Van Loan 1978) and its discrete Riccati equation (:func:`dlqr`): f_c[k] = −K_d x̂[k]. It
    tends to the continuous design as control_dt → 0 and is what the controller can actually do at a coarse
    control rate (the horizon-1 unconstrained :class:`~controllers.mpc.MPC`).

    ``inverse``: None (the on–off law above), or an inverse model that turns f_c into the command instead — a
    name of :func:`mrd_env.inverse.make_inverse` ("heaviside", "sid", "model", "neural") or an
    :class:`~mrd_env.inverse.Inverse` — through :class:`mrd_env.envs.actuation.ForceActuation` (the inverses
    other than "heaviside" read the damper's stroke and velocity sensors too).
    """

    name = "clipped_optimal"

    def __init__(self, env, weights: dict | None = None, force_ref: float = 3000.0, inverse=None,
                 design: str = "continuous", **observer):
        if design not in ("continuous", "sampled"):
            raise ValueError(f"design must be 'continuous' or 'sampled', got {design!r}")
        super().__init__(env, **observer)
        if inverse is None:
            self.actuation = None
        else:
            from mrd_env.envs.actuation import ForceActuation

            self.actuation = ForceActuation(self.env, inverse)
            self.name = f"{self.name}+{self.actuation.inverse.name}"
        weights = dict(self.env.objective) if weights is None else dict(weights)
        if not force_ref > 0:
            raise ValueError(f"force_ref must be > 0 N, got {force_ref}")
        Cz, Dz = self.design.regulated(weights)
        Q = Cz.T @ Cz
        R = Dz.T @ Dz + np.eye(self.design.nd) / force_ref ** 2
        N = Cz.T @ Dz
        self.weights, self.force_ref, self.design_kind = weights, float(force_ref), design
        self.lq = (Q, R, N)  # the continuous cost ∫ xᵀQx + 2xᵀNf + fᵀRf dt
        if design == "continuous":
            self.K, self.S_riccati, self.closed_loop_poles = control.lqr(self.design.A, self.design.Bf, Q, R, N)
            self.K = np.asarray(self.K)
        else:
            Phi, Gamma, Qd, Rd, Nd = sampled_lq(self.design.A, self.design.Bf, Q, R, N, self.control_dt)
            self.K, self.S_riccati = dlqr(Phi, Gamma, Qd, Rd, Nd)
            self.closed_loop_poles = np.linalg.eigvals(Phi - Gamma @ self.K)

    def desired_force(self, x_hat):
        """f_c = −K x̂ per row, (N, nd)."""
        return -x_hat @ self.K.T

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        fc = self.last_desired = self.desired_force(x_hat)
        return self.actuate(fc, f, obs)

    def actuate(self, fc, f, obs):
        """The command for desired forces f_c and measured forces f beyond the preload: the clipped on–off law
        u = u_max·H((f_c − f)·f), or the inverse model's command."""
        if self.actuation is not None:
            return self.actuation.from_observation(fc, obs)
        return self.on_off((fc - f) * f > 0.0)

    def reset_rows(self, mask):
        super().reset_rows(mask)
        if self.actuation is not None:
            self.actuation.reset(mask)


class Lyapunov(_ObserverLaw):
    """Lyapunov-based law (Leitmann 1994; Jansen & Dyke 2000): V = xᵀPx with AᵀP + PA = −Q;
    u = u_max·H(−x̂ᵀ P B_f f), i.e. full command whenever the damper force makes V decrease fastest.

    Q defaults to the identity on the plant's energy coordinates scaled so that P has the units of energy.
    """

    name = "lyapunov"

    def __init__(self, env, Q: np.ndarray | None = None, **observer):
        super().__init__(env, **observer)
        d = self.design
        if Q is None:
            n = d.n_dof
            Q = np.block([[d.plant.K, np.zeros((n, n))], [np.zeros((n, n)), d.plant.M]])
        self.P = control.lyap(d.A.T, Q)
        self._PB = self.P @ self.design.Bf

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        return self.on_off(-(x_hat @ self._PB) * f > 0.0)
