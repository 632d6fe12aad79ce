"""Model-based semi-active laws: clipped-optimal LQG (Dyke et al. 1996) and Lyapunov (Jansen & Dyke 2000).

Both design on the plant's linear model with the damper forces f as the control input (python-control):

    ẋ = A x + B_f f + B_w w,    x = [q, q̇]        (``LinearPlant.state_space``)
    y = C_y x + D_y f                              measured outputs (accelerations, strokes, ...)

and run a discrete Kalman filter (``control.dlqe`` on the zero-order-hold model at the control period)
fed with the measured outputs and the measured damper forces; the disturbance w is its process noise.
"""
from __future__ import annotations

import control
import numpy as np
from scipy.linalg import expm

from .base import Controller

#: Output rows per sensor name: which function of (q, q̇, q̈) a sensor measures. Accelerations are
#: formed from the model's acceleration rows; a building's absolute accelerations q̈ + 1·ẍ_g do not depend
#: on ẍ_g (the ground term of q̈ cancels), the quarter car's sprung acceleration does not depend on the road.
MEASURABLE = ("abs_acc", "sprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel", "drift",
              "floor_vel", "floor_disp", "damper_stroke", "damper_velocity")


class LinearDesign:
    """The plant's linear model in the form the designs need, built from ``env.unwrapped``."""

    def __init__(self, env):
        lp = env.linear_plant
        self.plant = lp
        m_d = env.damper.inertance() if hasattr(env.damper, "inertance") else 0.0
        self.A, self.Bf, self.Bw = lp.state_space(inertance=m_d)
        self.n = self.A.shape[0]
        self.n_dof = lp.n_dof
        self.nd = lp.n_dampers

    def output(self, sensor: str):
        """(C, D_f) of a sensor's rows, or None if it is not a state function (an input, a force)."""
        n, S = self.n_dof, self.plant.S
        Z = np.zeros((n, n))
        acc_C, acc_D = self.A[n:], self.Bf[n:]
        rows = {
            "abs_acc": (acc_C, acc_D), "sprung_acc": (acc_C[:1], acc_D[:1]),
            "travel": (np.hstack([S, 0 * S]), None), "damper_stroke": (np.hstack([S, 0 * S]), None),
            "travel_rate": (np.hstack([0 * S, S]), None), "damper_velocity": (np.hstack([0 * S, S]), None),
            "sprung_vel": (np.hstack([Z, np.eye(n)])[:1], None), "unsprung_vel": (np.hstack([Z, np.eye(n)])[1:2], None),
            "floor_vel": (np.hstack([Z, np.eye(n)]), None), "floor_disp": (np.hstack([np.eye(n), Z]), None),
            "drift": (np.hstack([np.eye(n) - np.eye(n, k=-1), Z]), None),
        }
        if sensor not in rows:
            return None
        C, D = rows[sensor]
        return C, (np.zeros((C.shape[0], self.nd)) if D is None else D)

    def regulated(self, env, weights: dict):
        """(C_z, D_z) stacked from weighted outputs ``{sensor: weight}`` (weights on squared outputs)."""
        Cs, Ds = [], []
        for name, w in weights.items():
            out = self.output(name)
            if out is None:
                raise ValueError(f"cannot regulate {name!r}: it is not a function of the plant state")
            Cs.append(np.sqrt(w) * out[0])
            Ds.append(np.sqrt(w) * out[1])
        return np.vstack(Cs), np.vstack(Ds)


class KalmanEstimator:
    """Stationary discrete Kalman filter (predictor form, ``control.dlqe``) at the control period.

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
        # the same update regrouped: x̂[k+1] = (Φ − LC) x̂ + (Γ_f − LD) f + L y (fewer products per step)
        self._Ax = self.Phi - self.L @ C
        self._Bf = self.Gf - self.L @ D
        self.x = np.zeros(n)

    def reset(self):
        self.x[:] = 0.0

    def update(self, y: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Return x̂[k] (the prediction from the past) and advance the filter with y[k], f[k]."""
        x = self.x
        self.x = self._Ax @ x + self._Bf @ f + self.L @ y
        return x


class _ObserverLaw(Controller):
    """Shared part of the model-based laws: measured outputs → Kalman estimate x̂."""

    requires = ("damper_force",)
    measurement_noise_default = 0.05  # RMS of each measured output, SI (m/s², m, m/s)

    def __init__(self, env, measurements=None, process_noise: float = 1.0, measurement_noise=None):
        super().__init__(env)
        self.design = LinearDesign(self.env)
        usable = [n for n in self.layout if n in MEASURABLE] if measurements is None else list(measurements)
        if not usable:
            raise ValueError(f"{type(self).__name__} needs at least one measured response among {MEASURABLE}; "
                             f"the environment measures {list(self.layout)}")
        for name in usable:
            if name not in self.layout:
                raise ValueError(f"measurement {name!r} is not among the environment's sensors {list(self.layout)}")
        self.measurements = usable
        self._y_index = np.concatenate([np.arange(self.layout[n].start, self.layout[n].stop) for n in usable])
        Cs, Ds = zip(*(self.design.output(n) for n in usable))
        C, D = np.vstack(Cs), np.vstack(Ds)
        noise = self.measurement_noise_default if measurement_noise is None else measurement_noise
        self.kf = KalmanEstimator(self.design, C, D, self.control_dt, process_noise,
                                  np.broadcast_to(np.asarray(noise, float) ** 2, (C.shape[0],)))

    def reset(self):
        self.kf.reset()

    def estimate(self, obs):
        y = obs[self._y_index]
        f = self.dynamic_force(obs)
        return self.kf.update(y, f), f


class ClippedOptimal(_ObserverLaw):
    """Clipped-optimal control (Dyke, Spencer, Sain & Carlson 1996).

    An LQR (``control.lqr``) on the weighted responses z = C_z x + D_z f,
    J = ∫ zᵀz + fᵀ R f dt, gives f_c = −K x̂ from the Kalman estimate x̂; the damper command is the
    clipped on–off law u = u_max·H((f_c − f)·f) with f the measured damper force beyond its static preload
    (the force the linear model's input stands for).

    Default weights: building — interstorey drifts ``drift`` with 1/(5 mm)², absolute accelerations
    ``abs_acc`` with 0; quarter car — sprung acceleration with 1/(1 m/s²)² and suspension travel with
    1/(5 cm)²; R = 1/(force_ref)² per damper with force_ref = 3000 N (the prototype damper's force scale;
    with these the El Centro lab ranking of Dyke et al. 1996 is reproduced, see the README).
    """

    name = "clipped_optimal"

    def __init__(self, env, weights: dict | None = None, force_ref: float = 3000.0, **observer):
        super().__init__(env, **observer)
        if weights is None:
            weights = ({"drift": 1 / 0.005 ** 2} if self.design.plant.input_names == ("xg_ddot",)
                       else {"sprung_acc": 1.0, "travel": 1 / 0.05 ** 2})
        if not force_ref > 0:
            raise ValueError(f"force_ref must be > 0 N, got {force_ref}")
        Cz, Dz = self.design.regulated(self.env, weights)
        Q = Cz.T @ Cz
        R = Dz.T @ Dz + np.eye(self.design.nd) / force_ref ** 2
        N = Cz.T @ Dz
        self.weights = weights
        self.K, self.S_riccati, self.closed_loop_poles = control.lqr(self.design.A, self.design.Bf, Q, R, N)
        self.K = np.asarray(self.K)

    def desired_force(self, x_hat):
        return -self.K @ x_hat

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        fc = self.desired_force(x_hat)
        return self.on_off((fc - f) * f > 0.0)


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
            M = d.plant.M
            Q = np.block([[d.plant.K, np.zeros((n, n))], [np.zeros((n, n)), M]])
        self.P = control.lyap(d.A.T, Q)

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        return self.on_off(-(x_hat @ self.P @ self.design.Bf) * f > 0.0)
