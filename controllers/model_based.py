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

The cost may be the environment's own reward (``weights="reward"``: :func:`reward_weights`), its filtered terms
realised as states (:func:`continuous_filter`), the car in road coordinates (``frame="road"``).
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.linalg import expm, solve_discrete_are

from .base import Controller


def road_inputs(names) -> tuple[tuple[int, int], ...]:
    """The road inputs of a plant, one (z_r, ż_r) pair per wheel as indices into its ``input_names``: a channel
    ``z_r<wheel>`` followed by ``zdot_r<wheel>`` (the quarter car's (z_r, zdot_r); the half car's front and rear;
    the full car's fl, fr, rl, rr). Empty for a plant without one (a building)."""
    names = tuple(names)
    return tuple((i, i + 1) for i in range(len(names) - 1)
                 if names[i].startswith("z_r") and names[i + 1] == "zdot_r" + names[i][3:])


class LinearDesign:
    """The plant's linear model in the form the designs need, from what ``env.unwrapped`` declares.

    ``filtered``: names of filtered signals (``env.assembly.filters``: an output of a digital filter of a linear
    signal, e.g. the quarter car's ISO 2631 Wk-weighted ``sprung_acc_wk``) whose filter is appended to the state as
    a continuous-time realisation (:func:`continuous_filter`): x = [q, q̇, ξ_1, ...], n_plant the plant's states."""

    def __init__(self, env, filtered=(), frame: str = "absolute"):
        if frame not in ("absolute", "road"):
            raise ValueError(f"frame must be 'absolute' or 'road', got {frame!r}")
        self.env = env
        lp = env.linear_plant
        self.plant = lp
        self.A, self.Bf, self.Bw = lp.state_space(inertance=env.damper.inertance())
        self.n_plant = self.A.shape[0]
        self.n_dof = lp.n_dof
        self.nd = lp.n_dampers
        self.frame = frame
        self.shift = None       # (n, wheels): the static shifts g_i of the road frame
        self.road_pairs = ()    # the road inputs (z_r, ż_r) of each wheel, as input indices
        if frame == "road":
            self._road_frame()
        self.filtered: dict = {}  # filtered signal → (C, D_F, D_w) over the augmented state
        for name in dict.fromkeys(filtered):
            self._append_filter(name)
        self.n = self.A.shape[0]

    def _road_frame(self):
        """Displacements relative to the static equilibrium on the roads under the wheels: q_rel = q − Σ_i g_i z_r,i
        with g_i the static response to a unit height of wheel i's road (A [g_i; 0] = −B_w[:, z_r,i]: K g_i = E z_i;
        the quarter car's g = [1, 1], a rigid shift; the full car's, the body's and wheels' shift under one raised
        wheel), velocities absolute. The dynamics do not change, the roads enter only through their velocities:
        B_w[:, ż_r,i] → B_w[:, ż_r,i] − [g_i; 0], B_w[:, z_r,i] → 0 — a random road of ISO 8608's n⁻² spectrum has a
        white velocity, what the Kalman filter's process noise models; the road height, a random walk, drops out (in
        absolute coordinates it is white noise on z_r and the filter takes the body's drift with the road for a
        deflection of the tyre)."""
        pairs = road_inputs(self.plant.input_names)
        if not pairs:
            raise ValueError(f"frame='road' needs a road input (z_r, zdot_r) per wheel (a car); this plant's inputs "
                             f"are {self.plant.input_names}")
        n = self.n_dof
        self.Bw = self.Bw.copy()
        G = np.zeros((self.A.shape[0], len(pairs)))
        for j, (iz, izd) in enumerate(pairs):
            g = np.linalg.lstsq(self.A[n:, :n], -self.Bw[n:, iz], rcond=None)[0]
            G[:, j] = np.concatenate([g, np.zeros(n)])
            if not np.allclose(self.A @ G[:, j], -self.Bw[:, iz], rtol=1e-9,
                               atol=1e-9 * np.abs(self.Bw[:, iz]).max()):
                raise ValueError("frame='road': no static shift of the displacements follows the road height")
            self.Bw[:, izd] -= G[:, j]
            self.Bw[:, iz] = 0.0
        self.shift = G
        self.road_pairs = pairs

    def _append_filter(self, name: str):
        filters = {o: (i, sos) for i, o, sos in getattr(getattr(self.env, "assembly", None), "filters", ())}
        if name not in filters:
            raise ValueError(f"{name!r} is not a filtered signal of the environment (filtered: {sorted(filters)})")
        source, sos = filters[name]
        C, DF, Dw = self.signal(source)
        Af, Bf, Cf, Df = continuous_filter(sos, self.env.dt)
        n, m = self.A.shape[0], Af.shape[0]
        # ξ' = A_f ξ + B_f s, s = C x + D_F f + D_w w (the source signal); output C_f ξ + D_f s
        self.A = np.block([[self.A, np.zeros((n, m))], [Bf @ C, Af]])
        self.Bf = np.vstack([self.Bf, Bf @ DF])
        self.Bw = np.vstack([self.Bw, Bf @ Dw])
        for k, (Ck, DFk, Dwk) in self.filtered.items():
            self.filtered[k] = (np.hstack([Ck, np.zeros((Ck.shape[0], m))]), DFk, Dwk)
        self.filtered[name] = (np.hstack([Df @ C, Cf]), Df @ DF, Df @ Dw)

    def signal(self, name: str):
        """(C, D_F, D_w) of a linear output ``C x + D_F f + D_w w`` over the (augmented) state; ValueError if the
        signal is not one."""
        if name in self.filtered:
            return self.filtered[name]
        if name in ("damper_force", "command"):
            raise ValueError(f"{name!r} is not a linear output of the plant state, forces and inputs")
        m = self.env.signal_matrices(name)
        Dw = np.array(m["D_w"], dtype=float)
        if self.shift is not None:  # y = C q + D_w w = C q_rel + Σ_i (C g_i + D_w[:, z_r,i]) z_r,i + ...
            for j, (iz, _) in enumerate(self.road_pairs):
                cancel = np.abs(m["C"]) @ np.abs(self.shift[:, j]) + np.abs(Dw[:, iz])
                Dw[:, iz] += m["C"] @ self.shift[:, j]
                Dw[np.abs(Dw[:, iz]) <= 1e-12 * cancel, iz] = 0.0  # what cancels exactly, to round-off
        C = np.hstack([m["C"], np.zeros((m["C"].shape[0], self.A.shape[0] - m["C"].shape[1]))])
        return C, m["D_F"], Dw

    def output(self, sensor: str):
        """(C, D_f) of a signal, or None if it is not a usable measurement (see the module docstring)."""
        try:
            C, DF, Dw = self.signal(sensor)
        except ValueError:
            return None
        if sensor in self.filtered:  # computed, not measured
            return None
        if np.max(np.abs(Dw), initial=0.0) > 1e-9 * max(1.0, np.max(np.abs(C), initial=0.0)):
            return None
        return C, DF

    def cost_outputs(self, weights: dict):
        """(C_z, D_z, D_zw): the weighted outputs z = C_z x + D_z f + D_zw w of ``{signal: weight}`` (weights on
        squared outputs, scalar or one per channel), any linear output — a disturbance-driven one too (the quarter
        car's tyre load) and an appended filter's (:attr:`filtered`)."""
        Cs, Ds, Ws = [], [], []
        for name, w in weights.items():
            try:
                C, DF, Dw = self.signal(name)
            except ValueError:
                raise ValueError(f"cannot regulate {name!r}: it is not a linear function of the plant state, forces "
                                 "and inputs") from None
            s = np.sqrt(np.broadcast_to(np.asarray(w, dtype=float), (C.shape[0],)))[:, None]
            Cs.append(s * C)
            Ds.append(s * DF)
            Ws.append(s * Dw)
        return np.vstack(Cs), np.vstack(Ds), np.vstack(Ws)

    def regulated(self, weights: dict):
        """(C_z, D_z) stacked from weighted outputs ``{signal: weight}`` (weights on squared outputs) of the state
        and forces alone (no disturbance term)."""
        for name in weights:
            if self.output(name) is None and name not in self.filtered:
                raise ValueError(f"cannot regulate {name!r}: it is not a function of the plant state and forces")
        return self.cost_outputs(weights)[:2]


def continuous_filter(sos: np.ndarray, dt: float):
    """(A, B, C, D): a continuous-time realisation of the digital filter ``sos`` at sample interval ``dt`` — the
    analog filter whose bilinear (Tustin) transform at ``dt`` it is, section by section: z⁻¹ = (1 − sT/2)/(1 + sT/2)
    turns b₀ + b₁z⁻¹ + b₂z⁻² into (b₀ − b₁ + b₂)T²/4·s² + (b₀ − b₂)T·s + (b₀ + b₁ + b₂) (over (1 + sT/2)², which
    cancels). For a pre-warped bilinear design (the ISO 2631 weightings of :func:`mrd_env.metrics.weighting_sos`)
    it is the analog prototype with its corners at the pre-warped frequencies (Wk at 1 ms: 100 Hz → 103 Hz, the
    others within 0.3 %). Realised as a cascade of sections in observable canonical form
    (:func:`mrd_env.optimal.bound.sos_state_space`: the same matrices are the continuous realisation of the
    analog sections), its states scaled by a diagonal similarity (``scipy.linalg.matrix_balance``)."""
    from scipy.linalg import matrix_balance

    from mrd_env.optimal.bound import sos_state_space

    sos = np.atleast_2d(np.asarray(sos, dtype=float))
    T = float(dt)
    M = np.array([[T * T / 4.0, -T * T / 4.0, T * T / 4.0], [T, 0.0, -T], [1.0, 1.0, 1.0]])
    analog = np.hstack([sos[:, :3] @ M.T, sos[:, 3:] @ M.T])
    A, B, C, D = sos_state_space(analog)
    _, (s, _) = matrix_balance(A, permute=False, separate=True)
    return A * (1.0 / s)[:, None] * s[None, :], B / s[:, None], C * s[None, :], D


_NOMINAL_CACHE: dict = {}


def nominal_reference(env) -> dict:
    """{reward signal: mean square} of the environment's reward normaliser on a fixed nominal disturbance — what
    the reward divides each term by, with the episode's own disturbance replaced by a nominal one a controller can
    know in advance (the per-episode scale depends on the road or record the controller has not seen). The plant
    declares it (``Assembly.nominal_reference``, in its folder: e.g. the conventional passive car on a class-C
    road, the uncontrolled building under nominal Kanai–Tajimi records). Cached per plant and time step."""
    base = getattr(env, "unwrapped", env)
    asm = base.assembly
    key = (asm.kind, repr(asm.plant_params), float(base.dt), repr(asm.options.get("plant_params")))
    if key in _NOMINAL_CACHE:
        return dict(_NOMINAL_CACHE[key])
    if asm.nominal_reference is None:
        raise ValueError(f"weights='reward' needs the plant's nominal reference, which the {asm.kind!r} "
                         f"environment does not declare: pass weights={{signal: weight}}")
    out = dict(asm.nominal_reference())
    _NOMINAL_CACHE[key] = out
    return dict(out)


def reward_weights(env) -> dict:
    """The environment's quadratic reward as LQ weights ``{signal: weight}``: each term's reward weight over its
    :func:`nominal_reference` mean square — the reward's own cost rate, in the reward's units on the nominal
    disturbance (the passive car, or the uncontrolled building, costs about 1 per second there). Quarter car: the
    Wk-weighted sprung acceleration (``sprung_acc_wk``, a filtered signal: :class:`LinearDesign` appends the filter),
    the travel and the dynamic tyre load (``_tyre_load``, driven by the road too); building: the interstorey drifts
    and the absolute floor accelerations."""
    from mrd_env.envs.reward import QuadraticReward

    base = getattr(env, "unwrapped", env)
    reward = base.assembly.reward
    if not isinstance(reward, QuadraticReward):
        raise ValueError("weights='reward' needs the environment's quadratic reward (a QuadraticReward), got "
                         f"{type(reward).__name__}: pass weights={{signal: weight}}")
    ref = nominal_reference(base)
    missing = sorted(set(reward.weights) - set(ref))
    if missing:
        raise ValueError(f"weights='reward': no nominal reference for the reward's signal(s) {missing}")
    return {name: np.asarray(w, dtype=float) / max(ref[name], 1e-300) for name, w in reward.weights.items()}


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
        import control  # imported where a design is made: 2.6 s that every `import controllers` paid
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


class ObserverLaw(Controller):
    """Shared part of the model-based laws: measured outputs → Kalman estimate x̂."""

    requires = ("damper_force",)
    measurement_noise_default = 0.05  # RMS of each measured output, SI (m/s², m, m/s)

    def __init__(self, env, measurements=None, process_noise: float = 1.0, measurement_noise=None, filtered=(),
                 frame: str = "absolute"):
        super().__init__(env)
        self.design = LinearDesign(self.env, filtered, frame)
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


class ClippedOptimal(ObserverLaw):
    """Clipped-optimal control (Dyke, Spencer, Sain & Carlson 1996).

    An LQR (``control.lqr``) on the weighted responses z = C_z x + D_z f, J = ∫ zᵀz + fᵀ R f dt, gives
    f_c = −K x̂ from the Kalman estimate x̂; the damper command is the clipped on–off law
    u = u_max·H((f_c − f)·f) with f the measured damper force beyond its static preload (the force the linear
    model's input stands for).

    ``weights``: {signal: weight on its square}; default the environment's declared objective (building: the
    interstorey drifts with 1/(5 mm)²; quarter car: sprung acceleration with 1/(1 m/s²)² and travel with
    1/(5 cm)²). R = 1/(force_ref)² per damper with force_ref = 3000 N (the prototype damper's force scale;
    with these the El Centro lab ranking of Dyke et al. 1996 is reproduced, see the README). Any linear output
    may be weighted: one the disturbance drives too (its disturbance part is unknown here, w = 0; MPC's road
    preview knows it) and a filtered signal of ``env.assembly.filters``, whose filter is appended to the design
    state (:class:`LinearDesign`). ``weights="reward"``: the environment's own quadratic reward over fixed nominal
    scales (:func:`reward_weights`) — quarter car: 0.5 (Wk-weighted sprung acceleration)² / 1.36 (m/s²)² +
    0.25 travel² / (11.0 mm)² + 0.25 (dynamic tyre load)² / (761 N)², the passive car's mean squares on an ISO
    class-C road at 20 m/s; building: 0.5 Σ drift² / ⟨Σ drift²⟩ + 0.5 Σ a_abs² / ⟨Σ a_abs²⟩ of the uncontrolled
    building under nominal Kanai–Tajimi records; each costs about 1 per second on its nominal disturbance, like
    the reward.

    ``frame`` (the design's coordinates): "absolute" (the environment's states), or "road" (the car's
    displacements relative to the road under the wheel, :meth:`LinearDesign._road_frame`: the road enters through
    its velocity, the tyre deflection is a state the filter estimates, from the unsprung acceleration — usable
    then — among others). Default: "road" with ``weights="reward"`` on the car (its tyre-load term needs it: in
    absolute coordinates the filter takes the wheel's travel with the road for tyre deflection, about three
    times the true tyre load), "absolute" otherwise.

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

    def __init__(self, env, weights: dict | str | None = None, force_ref: float = 3000.0, inverse=None,
                 design: str = "continuous", frame: str | None = None, **observer):
        if design not in ("continuous", "sampled"):
            raise ValueError(f"design must be 'continuous' or 'sampled', got {design!r}")
        if not force_ref > 0:
            raise ValueError(f"force_ref must be > 0 N, got {force_ref}")
        base = getattr(env, "unwrapped", env)
        road = bool(road_inputs(base.linear_plant.input_names))
        if isinstance(weights, str):
            if weights != "reward":
                raise ValueError(f"weights must be None (the environment's objective), 'reward' or a dict "
                                 f"{{signal: weight}}, got {weights!r}")
            weights = reward_weights(base)
            frame = ("road" if road else "absolute") if frame is None else frame
        elif weights is None:
            weights = dict(base.objective)
        elif not isinstance(weights, Mapping):
            raise ValueError(f"weights must be None, 'reward' or a dict {{signal: weight}}, got "
                             f"{type(weights).__name__}")
        self.weights = weights = dict(weights)
        outputs = {o for _, o, _ in getattr(getattr(base, "assembly", None), "filters", ())}
        super().__init__(env, filtered=[k for k in weights if k in outputs], frame=frame or "absolute", **observer)
        if inverse is None:
            self.actuation = None
        else:
            from mrd_env.envs.actuation import ForceActuation

            self.actuation = ForceActuation(self.env, inverse)
            self.name = f"{self.name}+{self.actuation.inverse.name}"
        Cz, Dz, Dzw = self.design.cost_outputs(weights)
        Q = Cz.T @ Cz
        R = Dz.T @ Dz + np.eye(self.design.nd) / force_ref ** 2
        N = Cz.T @ Dz
        self.force_ref, self.design_kind = float(force_ref), design
        self.lq = (Q, R, N)  # the continuous cost ∫ xᵀQx + 2xᵀNf + fᵀRf dt (w = 0)
        self.cost = (Cz, Dz, Dzw)  # z = C_z x + D_z f + D_zw w, R₀ = 1/force_ref² on f besides
        if design == "continuous":
            import control  # imported where a design is made: 2.6 s that every `import controllers` paid
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


class Lyapunov(ObserverLaw):
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
            Q = 0.5 * (Q + Q.T)  # K = Sᵀ K_s S is symmetric to round-off only (the full car's), lyap wants it exactly
        import control  # imported where a design is made: 2.6 s that every `import controllers` paid
        self.P = control.lyap(d.A.T, Q)
        self._PB = self.P @ self.design.Bf

    def command(self, obs):
        x_hat, f = self.estimate(obs)
        return self.on_off(-(x_hat @ self._PB) * f > 0.0)
