"""A passivity-aware upper bound: the active-actuator bound (:mod:`.bound`) with the actuator barred from giving
back more energy than it has taken from the plant.

**What it covers.** Every force history F (the damper forces, linear between the 1 ms rows: the bound's model of
the environment, as for :func:`~.bound.active_bound`) with, at every row t_r,

* |F_i(t_r) − F_static| ≤ f_max for every damper i (the active bound's force box), and
* Σ_i ∫₀^{t_r} [(F_i − F_s,i)·ẋ_d,i − c_min,i·ẋ_d,i²] dτ ≥ −E₀ (summed over the dampers),

**The energy accounting.** Damper i's port is (F_i − F_s,i, ẋ_d,i). F_s,i (``static_forces``, N) is the damper's
force at rest at its initial stroke x_d,i(0) (:func:`static_forces`: F_static + F_r(x_d,i(0)) − F_r(0), F_r the
damper model's force at rest, :meth:`~mrd_env.dampers.DamperModel.rest_force`): F_static wherever the strokes start
at 0 (the quarter car, the buildings, the full car on a bump), F_static + k1·x_d,i(0) for the Spencer–Dyke damper
on the full car's warped start (the car at rest on the road's initial heights with the accumulators' k1·x_d in its
equilibrium; the environment resets the damper there, its force then is F_s,i). E₀ = ``storage`` (J, default 0) is
the energy the devices hold at t = 0 *relative to those forces*. For a device at rest at its initial stroke it is
0: a static spring F_r (nondecreasing) stores ∫_{x_d(0)}^{x_d} (F_r(ξ) − F_r(x_d(0))) dξ ≥ 0, nil at t = 0 — for
the Spencer–Dyke accumulator ½k1(x_d − x_d(0))² — and the environment resets the internal states at rest at the
initial stroke (y = x_d, z = 0: the k0 spring and the Bouc–Wen element hold nothing). So the class is that of
*passive devices with internal storage, empty at the start*; every semi-active force history belongs to it — every
F with (F_i − F_s,i)·ẋ_d,i ≥ 0 at every instant, whatever the damper's model, so long as it stays within f_max — and
so does a device that stores energy and gives it back later (a spring, a regenerative actuator with a lossless
battery). Referring the ports to F_static instead (the only accounting before issue 51) is not valid on a warped
start: ∫(F − F_static)·ẋ_d = ∫(F − F_s)·ẋ_d + Σ_i (F_s,i − F_static)(x_d,i − x_d,i(0)), and the last term has no
lower bound known in advance — the damper locked at its static forces, F ≡ F_s, would lie outside the class. The
plant's own initial energy (the full car starts moving with the road, stroke rates nil) is in the free response
x̄ below, which is data: it costs the class nothing. ``storage`` > 0 widens the class to cover a store explicitly
(the bound grows with it, to the active bound).

``min_damping`` c_min,i (N·s/m, default 0) narrows the class to devices that dissipate at least a dashpot c_min's
energy: F − F_s − c_min·ẋ_d passive, i.e. the semi-active damper's lower force limit F ∈ [c_min, c_max]·ẋ_d
(Savaresi et al. 2010, ch. 3) in cumulative form. :func:`viscous_floor` gives the Spencer–Dyke damper's: c0, c1 in
series at the minimum command, c0c1/(c0 + c1) (744 N·s/m for the automotive preset), since c1ẏ·ẋ = c1ẏ² + c0(ẋ − ẏ)²
+ α z (ẋ − ẏ) + k0 (x − y)(ẋ − ẏ) and c1ẏ² + c0(ẋ − ẏ)² ≥ c0c1/(c0 + c1)·ẋ² for every split of ẋ. Its validity rests
on the Bouc–Wen term as the whole bound's does (below), with less of the viscous dissipation to spare: checked on
the environment's runs (``experiments/measurements/accuracy/bound_bracket.py``), not proven.

One caveat is of the model, not of MR fluid: a Bouc–Wen gain α(u) that follows the command makes a spring of
stiffness α·A in its elastic range, and a spring whose stiffness is switched can be pumped (soft while it extends,
stiff while it recovers), at most ~Δα·z_max²/(2A) per cycle (17 mJ for the automotive preset, 11 mJ for the
prototype); with β > γ (the automotive preset) its unloading branch is stiffer than A as well. Measured: passive-on,
passive-off, every law of the yardstick at 1 ms, random and bang-bang commands and the clairvoyant optimum have
absorbed ≥ 0 J (to rounding) at every row of every episode checked (:func:`absorbed_energy` on the environment's
forces; ``experiments/measurements/accuracy/bound_bracket.py``, ``tests/optimal/test_bound.py``,
``tests/optimal/test_dissipative.py``).

**How.** The plant seen from the dampers' ports is passive: with M, K, C recovered from the problem's matrices
(:func:`port_storage`: M q̈ + C q̇ + K q = −Sᵀ(F − F_static) + E w), the storage ½eᵀPe, P = diag(K, M), and the
dissipation ½eᵀQe, Q = diag(0, 2C), satisfy for the deviation e = x − x̄ from the free response x̄ (F ≡ F_s, the
disturbance known, x̄(0) = x(0) whatever the initial state) the exact identity

    ∫₀ᵗ (F − F_s)·ẋ_d dτ = ∫₀ᵗ (F − F_s)·ẋ̄_d dτ − ½e(t)ᵀP e(t) − ½∫₀ᵗ eᵀQe dτ

(d/dt ½eᵀPe = −½eᵀQe − (F − F_s)·C_v e, since ė = Ae + B_F(F − F_s), P B_F = −C_vᵀ and AᵀP + PA = −Q). The first
term is linear in the forces (x̄ is data), the others are concave quadratics, and so is −c_min∫ẋ_d² (ẋ_d affine in
the unknowns): the energy condition at each row is a convex constraint. A running variable Y_t — the first term
minus the dissipation, a linear recursion (no damping in the plant and c_min = 0: the quarter car) or one rotated
second-order cone per row (the building's structural damping, the full car's tyres, c_min > 0) — turns it into one
cone per row, ½e_tᵀPe_t ≤ E₀ + Y_t, added to the active bound's QP. The integrals over each row are 3-point
Gauss–Legendre on the exact intra-row response (the force-linear part to rounding, the rest within ~1e-9
relative). Rows where the plant is still at rest with an empty store (before a bump arrives) force e = 0 exactly:
equalities, not cones at their apex. Clarabel solves the SOCP; the bound is −its dual objective (weak duality), an
upper bound on the return of every force history of the class to the solver's tolerance, as the active bound is.
Where Clarabel stops short of its tolerance with a dual residual ≤ 1e-9 and a gap ≤ ``ALMOST_GAP`` (on the full
car its primal residual grows in the last iterations) the dual objective is still a bound, looser by the gap; the
optimum's F and X are then approximate.

**Why not per damper, or the semi-active condition row by row.** Σ_i is a condition on the dampers together: one
damper's absorbed energy ∫(F_i − F_s,i)·ẋ_d,i has a cross term ∫F_i·(C_v,i e(F_j)) bilinear in two dampers' forces
(the plant's storage makes only the sum concave), so per-damper conditions are not convex. (F − F_s)·ẋ_d ≥ 0 row
by row is bilinear; the convex hull of {(F, v): (F − F_s)·v ≥ 0, |F − F_static| ≤ f_max} is the whole box unless the
stroke velocity v is bounded at that row, so a McCormick envelope (or any per-row cut) needs [v_lo, v_hi] valid for
every admissible trajectory. The class contains F ≡ F_s, and the car has no damping but its damper: bounds from the
force limit alone grow by ~41 m/s per second of episode (±4 m/s after 0.1 s, against 0.3 m/s RMS stroke velocity);
bounds restricted to trajectories scoring better than the best law but with the force box dropped (an ellipsoid,
closed form) were ±144 m/s on a 2 s ISO episode; tightening them by a convex problem per row is 2·10⁴ solves per
10 s episode. And even the envelope of the velocities the laws and the clairvoyant actually had (not a valid bound:
narrower than any valid one) leaves most of the bracket (``bound_bracket --oracle``; docs/yardstick.md). A
Lagrangian (Shor) relaxation with one multiplier per row is tractable only where the Lagrangian stays concave in the
forces; with nonincreasing multipliers it is a positive combination of the cumulative conditions imposed here
(concave by the plant's passivity) — whether other multipliers gain anything is open. A device's bounded storage
(∫ over any window ≥ −S_max) adds the energy stored at the window's start, a convex quadratic, on the wrong side;
the upper force limit F − F_s ≤ c_max·ẋ_d in cumulative form is concave ≥ convex. Counting the damper's accumulator
spring as a spring rather than a store (absorbed ≥ ½k1(x_d − x_d(0))², convex) was tried: 0.01–0.03 points of the
bracket on the quarter car's bumps and an ISO-C episode, so it is not offered (docs/yardstick.md).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .bound import BoundResult, Rows, check_arguments, clarabel_solve, first_order_hold, normalise_rows, program
from .problem import EpisodeProblem

#: Gauss–Legendre nodes per row for the energy integrals.
NODES = 3
#: the relative duality gap accepted where Clarabel stops short of its tolerance ("almost solved", or for
#: insufficient progress, its primal residual growing as cones tighten at their apex: the full car) with a
#: negligible dual residual: the bound is the dual objective, valid whatever the gap, looser by it (the full car's
#: bump stalls at 7e-5)
ALMOST_GAP = 1e-4


@dataclass
class DissipativeBoundResult(BoundResult):
    """The passivity-aware bound of an episode: :class:`~.bound.BoundResult`'s fields (``kind`` "passive"), the
    initial store ``storage`` (J), the ports' reference forces ``static_forces`` (N, (nd,)) and least damping
    ``min_damping`` (N·s/m, (nd,)), and the optimum's ``absorbed`` energy, the class's quantity
    Σ∫₀^{t_r} [(F − F_s)·ẋ_d − c_min·ẋ_d²] (J, (n_rows,))."""

    storage: float = 0.0
    absorbed: np.ndarray | None = None
    static_forces: np.ndarray | None = None
    min_damping: np.ndarray | None = None


@dataclass(frozen=True)
class PortStorage:
    """The plant seen from the damper's port: M, K, C recovered from (A, B_F, C_v), the storage matrix
    P = diag(K, M) and the dissipation matrix Q = diag(0, 2C) (AᵀP + PA = −Q, P B_F = −C_vᵀ)."""

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    P: np.ndarray
    Q: np.ndarray


def port_storage(problem: EpisodeProblem, rtol: float = 1e-9) -> PortStorage:
    """The mechanical energy of the problem's plant as a storage function of its damper port.

    The plant is x = [q, q̇], A = [[0, I], [−M⁻¹K, −M⁻¹C]], B_F = [0; −M⁻¹Sᵀ], C_v = [0, S]; M (symmetric) solves
    M·B_F,v = −Sᵀ with M·A₂₁ and M·A₂₂ symmetric (least squares, then checked). ``ValueError`` where the
    equations have no solution with M ≻ 0, K ⪰ 0, C ⪰ 0 (not a mechanical plant with a passive port)."""
    A, BF, Cv = np.asarray(problem.A, float), np.asarray(problem.BF, float), np.asarray(problem.Cv, float)
    nx = problem.nx
    n = nx // 2
    if 2 * n != nx or np.any(A[:n, :n]) or not np.allclose(A[:n, n:], np.eye(n)) or np.any(BF[:n]) \
            or np.any(Cv[:, :n]):
        raise ValueError("dissipative_bound needs a mechanical plant x = [q, q̇] with the damper on velocities")
    A21, A22, Bv, S = A[n:, :n], A[n:, n:], BF[n:], Cv[:, n:]
    iu = np.triu_indices(n)
    m = len(iu[0])

    def mat(vec):
        Mx = np.zeros((n, n))
        Mx[iu] = vec
        return Mx + np.triu(Mx, 1).T

    # the equations are linear in svec(M): build them column by column
    il = np.tril_indices(n, -1)
    cols = []
    for j in range(m):
        e = np.zeros(m)
        e[j] = 1.0
        Mj = mat(e)
        MA, MC = Mj @ A21, Mj @ A22
        cols.append(np.concatenate([(Mj @ Bv).ravel(), (MA - MA.T)[il], (MC - MC.T)[il]]))
    G = np.array(cols).T
    rhs = np.concatenate([-S.T.ravel(), np.zeros(2 * len(il[0]))])
    sol, *_ = np.linalg.lstsq(G, rhs, rcond=None)
    M = mat(sol)
    resid = np.linalg.norm(G @ sol - rhs) / max(np.linalg.norm(rhs), 1e-300)
    K = -M @ A21
    C = -M @ A22
    K, C = 0.5 * (K + K.T), 0.5 * (C + C.T)
    lm, lk, lc = (np.linalg.eigvalsh(X) for X in (M, K, C))
    if resid > rtol or lm.min() <= 0 or lk.min() < -rtol * max(lk.max(), 1.0) \
            or lc.min() < -rtol * max(lc.max(), 1.0):
        raise ValueError(f"the plant's damper port has no mechanical storage (residual {resid:.1e}, eigenvalues "
                         f"of M {lm.min():.3g}, K {lk.min():.3g}, C {lc.min():.3g}): dissipative_bound needs "
                         "M q̈ + C q̇ + K q = −Sᵀ F + E w with M ≻ 0, K ⪰ 0, C ⪰ 0")
    P = scipy.linalg.block_diag(K, M)
    Q = scipy.linalg.block_diag(np.zeros((n, n)), 2.0 * C)
    return PortStorage(M, K, C, P, Q)


def _node_maps(A: np.ndarray, B: np.ndarray, dt: float, s: np.ndarray):
    """Per node fraction s_k of a row: (Φ_k, Γ0_k, Γ1_k) with x(t_r + s_k dt) = Φ_k x_r + Γ0_k u_r
    + Γ1_k (u_{r+1} − u_r) for u linear between rows."""
    n, m = B.shape
    Mx = np.zeros((n + 2 * m, n + 2 * m))
    Mx[:n, :n], Mx[:n, n:n + m], Mx[n:n + m, n + m:] = A, B, np.eye(m)
    out = []
    for sk in s:
        E = scipy.linalg.expm(Mx * sk * dt)
        out.append((E[:n, :n], E[:n, n:n + m], E[:n, n + m:] / dt))
    return out


def _gauss(k: int = NODES):
    x, w = np.polynomial.legendre.leggauss(k)
    return 0.5 * (x + 1.0), 0.5 * w   # nodes in (0, 1), weights summing to 1


def static_forces(problem: EpisodeProblem) -> np.ndarray:
    """The dampers' forces at rest at their initial strokes x_d(0) = C_x x0 (N, (nd,)): F_static + F_r(x_d,i(0)) −
    F_r(0), F_r the damper's force at rest at the minimum command (where the environment resets the effective
    command), :meth:`~mrd_env.dampers.DamperModel.rest_force`. Exactly F_static where a stroke starts at 0 (no
    damper model needed there)."""
    p = problem
    xd0 = np.asarray(p.Cx, dtype=float) @ np.asarray(p.x0, dtype=float)
    out = np.full(p.nd, float(p.F_static))
    moved = np.nonzero(xd0)[0]
    if moved.size:
        if p.damper is None:
            raise ValueError("static_forces: the problem's strokes start off zero and it has no damper model to "
                             "give their forces at rest; pass static_forces to dissipative_bound")
        u = p.v_min
        f0 = p.damper.rest_force(0.0, u)
        for i in moved:
            out[i] += p.damper.rest_force(float(xd0[i]), u) - f0
    return out


def viscous_floor(damper) -> float:
    """The least viscous damping of a Spencer–Dyke damper at any command (N·s/m): its dashpots c0 and c1 in series
    at the minimum command, c0c1/(c0 + c1) (c0, c1 grow with the command): c1ẏ² + c0(ẋ − ẏ)² ≥ c0c1/(c0 + c1)·ẋ²
    for every split of ẋ (see the module docstring). ``ValueError`` for another model (no such floor derived)."""
    if getattr(damper, "name", None) != "spencer_dyke":
        raise ValueError(f"viscous_floor is derived for the Spencer–Dyke damper only, got "
                         f"{getattr(damper, 'name', type(damper).__name__)!r}: give min_damping yourself")
    q, u = damper.params, float(damper.command.v_min)
    c0, c1 = q.c0a + q.c0b * u, q.c1a + q.c1b * u
    return float(c0 * c1 / (c0 + c1)) if c0 + c1 > 0 else 0.0


def _per_damper(problem: EpisodeProblem, value, name: str, unit: str, lo: float = -np.inf) -> np.ndarray:
    """A scalar or (nd,) argument as a finite float array (nd,) ≥ ``lo``, else ``ValueError`` naming it."""
    if isinstance(value, (bool, str)):
        raise ValueError(f"{name} must be a number or {problem.nd} numbers in {unit}, got {value!r}")
    try:
        v = np.broadcast_to(np.asarray(value, dtype=float), (problem.nd,)).copy()
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or {problem.nd} numbers (one per damper) in {unit}, "
                         f"got {value!r}") from None
    if not np.all(np.isfinite(v)) or np.any(v < lo):
        raise ValueError(f"{name} must be finite{'' if lo == -np.inf else f' and >= {lo:g}'} {unit}, got {value!r}")
    return v


def _response(problem: EpisodeProblem, F: np.ndarray) -> np.ndarray:
    """The plant's states at every row (n_rows, nx) under the forces ``F`` (n_rows, nd), linear between rows."""
    p = problem
    Phi, Ga, Gb = first_order_hold(p.A, np.hstack([p.BF, p.Bw]), p.dt)
    U = np.hstack([F, p.W])
    drive = U[:-1] @ (Ga - Gb).T + U[1:] @ Gb.T
    X = np.empty((p.n_rows, p.nx))
    X[0] = p.x0
    for r in range(p.n_rows - 1):
        X[r + 1] = Phi @ X[r] + drive[r]
    return X


def free_response(problem: EpisodeProblem, static_forces=None) -> np.ndarray:
    """The plant's states at every row (n_rows, nx) with the damper forces held at ``static_forces`` (default
    :func:`static_forces`; F_static where the strokes start at 0) (exact, FOH)."""
    Fs = _reference(problem, static_forces)
    return _response(problem, np.tile(Fs, (problem.n_rows, 1)))


def _reference(problem, static_forces):
    return static_forces_of(problem) if static_forces is None else \
        _per_damper(problem, static_forces, "static_forces", "N")


static_forces_of = static_forces   # the module-level name, for the functions whose argument shadows it


def absorbed_energy(problem: EpisodeProblem, F, X=None, static_forces=None, min_damping=0.0) -> np.ndarray:
    """Σ_i ∫₀^{t_r} [(F_i − F_s,i)·ẋ_d,i − c_min,i·ẋ_d,i²] dτ (J) at every row r of the force history ``F``
    (n_rows, nd; linear between rows) on the problem's plant: the energy the dampers have taken from the plant
    beyond a dashpot c_min's (``min_damping``, default 0), their ports referred to ``static_forces`` (default
    :func:`static_forces`). ``X``: the plant's states at the rows (default: the exact response of the plant to
    ``F``, the bound's model). The class of :func:`dissipative_bound` is ``absorbed_energy(...) >= −storage`` at
    every row."""
    p = problem
    Fs = _reference(p, static_forces)
    cmin = _per_damper(p, min_damping, "min_damping", "N·s/m", lo=0.0)
    F = np.asarray(F, dtype=float).reshape(p.n_rows, p.nd)
    B = np.hstack([p.BF, p.Bw])
    U = np.hstack([F, p.W])
    X = _response(p, F) if X is None else np.asarray(X, dtype=float)
    s, w = _gauss()
    dF = F - Fs
    per_row = np.zeros(p.n_rows - 1)
    for (Phk, G0, G1), sk, wk in zip(_node_maps(p.A, B, p.dt, s), s, w):
        Xk = X[:-1] @ Phk.T + U[:-1] @ G0.T + (U[1:] - U[:-1]) @ G1.T
        Fk = (1 - sk) * dF[:-1] + sk * dF[1:]
        Vk = Xk @ p.Cv.T
        per_row += wk * p.dt * np.sum(Fk * Vk - cmin * Vk ** 2, axis=1)
    return np.concatenate([[0.0], np.cumsum(per_row)])


def dissipative_bound(problem: EpisodeProblem, f_max: float | None = None, storage: float = 0.0,
                      solver: str = "clarabel", limits: bool = True, tol: float = 1e-8, static_forces=None,
                      min_damping=0.0) -> DissipativeBoundResult:
    """The passivity-aware bound of ``problem`` (see the module docstring): an upper bound on the return of every
    force history within ``f_max`` of F_static that never gives back more energy than it has absorbed plus
    ``storage`` (J), its ports referred to ``static_forces`` (N, scalar or one per damper; default
    :func:`static_forces`, the dampers' forces at rest at their initial strokes) and, with ``min_damping`` c_min
    (N·s/m, scalar or per damper; default 0), beyond a dashpot c_min's dissipation. ``f_max``, ``solver``,
    ``limits`` and ``tol`` as for :func:`~.bound.active_bound` (the same default force limit); never above the
    active bound of the same ``f_max`` (to the solvers' tolerances). ``RuntimeError`` where the class holds no
    force history within the limits (e.g. f_max below the static forces' offset from F_static)."""
    f_max, source = check_arguments(problem, f_max, solver, tol)
    if isinstance(storage, bool) or not isinstance(storage, (int, float, np.floating, np.integer)) \
            or not np.isfinite(storage) or storage < 0:
        raise ValueError(f"storage must be finite and >= 0 J, got {storage!r}")
    storage = float(storage)
    p = problem
    Fs = _reference(p, static_forces)
    cmin = _per_damper(p, min_damping, "min_damping", "N·s/m", lo=0.0)
    ps = port_storage(p)
    extra = {"storage": storage, "static_forces": Fs, "min_damping": cmin}
    if f_max == 0.0:   # one force history, F ≡ F_static: the active bound's, if it lies in the class
        from dataclasses import asdict

        from .bound import active_bound

        F0 = np.full((p.n_rows, p.nd), p.F_static)
        taken = absorbed_energy(p, F0, static_forces=Fs, min_damping=cmin)
        if taken.min() < -storage - 1e-9 * max(float(np.max(np.abs(taken))), 1e-300):
            raise RuntimeError("dissipative_bound: the problem is infeasible: with f_max = 0 the one force history, "
                               f"F ≡ F_static, gives back {-taken.min():.3g} J beyond the store of {storage:g} J")
        res = active_bound(p, f_max=0.0, solver=solver, limits=limits, tol=tol)
        return DissipativeBoundResult(**{**asdict(res), "kind": "passive", "f_max_source": source},
                                      absorbed=taken, **extra)
    t0 = time.perf_counter()
    prog = program(p, f_max, limits)
    L = prog.L
    N, nx, nd, dt = L.N, L.nx, L.nd, p.dt
    n0, n = L.n, L.n + N
    iY = n0 + np.arange(N)            # Y_t, t = 1..N: the energy the plant may hold beyond its free response
    r0 = np.arange(N)                 # rows r = 0..N−1 (intervals [t_r, t_{r+1}])
    FsR = np.tile(Fs, (N + 1, 1))
    Xf = _response(p, FsR)            # the free response x̄: every damper holding its static force
    s, w = _gauss()
    maps = _node_maps(p.A, np.hstack([p.BF, p.Bw]), dt, s)
    Uf = np.hstack([FsR, p.W])
    # the free stroke velocity against the force's two ends on each row: ∫ ΔF v̄ = a_r·ΔF_r + b_r·ΔF_{r+1}
    a, b = np.zeros((N, nd)), np.zeros((N, nd))
    for (Phk, G0, G1), sk, wk in zip(maps, s, w):
        vk = (Xf[:-1] @ Phk.T + Uf[:-1] @ G0.T + (Uf[1:] - Uf[:-1]) @ G1.T) @ p.Cv.T
        a += wk * dt * (1 - sk) * vk
        b += wk * dt * sk * vk
    lin0 = -np.sum((a + b) * Fs, axis=1)   # ∫ ΔF v̄ = a_r·F_r + b_r·F_{r+1} + lin0_r
    # per row, the energy a force of f_max could have taken along the free velocity so far (+ the store): the
    # scale of Y_t and of its cones; rows where it is nil — below 1e-20 of the episode's, rounding in a plant at
    # rest with nothing stored — have e_t = 0 and Y_t = 0
    fscale = f_max if f_max > 0 else 1000.0
    step = fscale * np.sum(np.abs(a) + np.abs(b), axis=1)
    avail = storage + np.cumsum(step)                     # at t = 1..N
    floor = 1e-20 * max(float(avail[-1]), 1e-300)
    rest = avail <= floor
    T0 = int(np.argmin(rest)) if not rest.all() else N   # rows t = 1..T0 at rest
    cY = np.maximum(avail, floor if floor > 0 else 1.0)   # the cones' unit per row: ||x||² ≤ β ⟺
    cstep = np.maximum(step, 1e-3 * cY)                   # ||(β − c, 2√c x)|| ≤ β + c
    Fcol = [L.F(r0) + j for j in range(nd)], [L.F(r0 + 1) + j for j in range(nd)]
    dissipative = bool(np.any(ps.C)) or bool(np.any(cmin > 0))
    eq = Rows()
    b_eq_x = []
    soc = Rows()
    b_soc, dims = [], []
    if T0:
        # at rest with an empty store the energy condition forces e_t = x_t − x̄_t = 0 and Y_t = 0 (t ≤ T0)
        st = eq.new(T0 * nx)
        eq.add(np.eye(nx), st + np.arange(T0) * nx, L.x(np.arange(1, T0 + 1)))
        b_eq_x.append(Xf[1:T0 + 1].ravel())
        st = eq.new(T0)
        eq.add(np.ones((1, 1)), st + np.arange(T0), iY[:T0])
        b_eq_x.append(np.zeros(T0))
    live = r0[T0:]                    # the rows r whose energy step Y_r → Y_{r+1} is constrained (r ≥ T0)
    if not dissipative:
        # Y_{r+1} − Y_r − a_r·F_r − b_r·F_{r+1} = lin0_r  (Y_0 = 0)
        st = eq.new(live.size)
        ri = st + np.arange(live.size)
        eq.add(np.ones((1, 1)), ri, iY[live])
        has = live >= 1
        eq.add(-np.ones((1, 1)), ri[has], iY[live[has] - 1])
        for j in range(nd):
            eq.i += [ri, ri]
            eq.j += [Fcol[0][j][live], Fcol[1][j][live]]
            eq.v += [-a[live, j], -b[live, j]]
        b_eq_x.append(lin0[live])
    elif live.size:
        # ½∫_r^{r+1} eᵀQe + ∫ c_min·ẋ_d² ≤ β_r = Y_r − Y_{r+1} + a_r·ΔF_r + b_r·ΔF_{r+1}: (β + c, β − c, 2√c·g) in
        # the cone, g = [√(½ w_k dt)·L_q e(τ_k), √(w_k dt·c_min)·ẋ_d(τ_k)]_k at the nodes τ_k = t_r + s_k dt, with
        # e(τ) = Φ(τ)(x_r − x̄_r) + Γ0 ΔF_r + Γ1 (ΔF_{r+1} − ΔF_r) and x(τ) = Φ(τ) x_r + Γ0 u_r + Γ1 (u_{r+1} − u_r)
        lam, V = np.linalg.eigh(ps.Q)
        keep = lam > 1e-12 * lam.max() if lam.max() > 0 else np.zeros(nx, bool)
        Lq = np.sqrt(lam[keep])[:, None] * V[:, keep].T
        Lc = np.sqrt(cmin[cmin > 0])[:, None] * np.asarray(p.Cv, float)[cmin > 0]
        nq_, nc_ = Lq.shape[0], Lc.shape[0]
        d = 2 + len(s) * (nq_ + nc_)
        m_ = live.size
        st = soc.new(m_ * d)
        rb = st + np.arange(m_) * d
        c = cstep[live]
        bconst = np.zeros((m_, d))
        has = live >= 1
        first = live == 0             # row 0 starts from the known x0 (= x̄_0): no variable, a constant
        for k_, sign in enumerate((1.0, -1.0)):   # the rows β + c and β − c: s = b − A v
            rr = rb + k_
            soc.add(-np.ones((1, 1)), rr[has], iY[live[has] - 1])      # +Y_r (r ≥ 1)
            soc.add(np.ones((1, 1)), rr, iY[live])                      # −Y_{r+1}
            for j in range(nd):
                soc.i += [rr, rr]
                soc.j += [Fcol[0][j][live], Fcol[1][j][live]]
                soc.v += [-a[live, j], -b[live, j]]
            bconst[:, k_] = sign * c + lin0[live]
        sc = 2.0 * np.sqrt(c)
        Wl, Wn = p.W[live], p.W[live + 1]
        for k_, ((Phk, G0, G1), wk) in enumerate(zip(maps, w)):
            G0F, G1F, G0W, G1W = G0[:, :nd], G1[:, :nd], G0[:, nd:], G1[:, nd:]
            col0 = 2 + k_ * (nq_ + nc_)
            e_const = -(Xf[live] @ Phk.T + Fs @ G0F.T)            # e(τ) = … − Φ x̄_r − Γ0 F_s
            e_const[first] += p.x0 @ Phk.T                         # + Φ x_0 on row 0 (x_0 is not a variable)
            x_const = Wl @ (G0W - G1W).T + Wn @ G1W.T              # x(τ) = … + Γ0 W_r + Γ1 (W_{r+1} − W_r)
            x_const[first] += p.x0 @ Phk.T
            for Lm, const, off, fac in ((Lq, e_const, col0, np.sqrt(0.5 * wk * dt)),
                                        (Lc, x_const, col0 + nq_, np.sqrt(wk * dt))):
                mk = fac * Lm                                          # (rows, nx), times 2√c per live row
                for i_ in range(mk.shape[0]):
                    rows_i = rb + off + i_
                    for blk, cols, sel in ((mk[i_] @ Phk, L.x(live[has]), has),
                                           (mk[i_] @ (G0F - G1F), L.F(live), None),
                                           (mk[i_] @ G1F, L.F(live + 1), None)):
                        rsel = rows_i if sel is None else rows_i[sel]
                        scl = sc if sel is None else sc[sel]
                        for jx in np.nonzero(blk)[0]:
                            soc.i.append(rsel)
                            soc.j.append(cols + jx)
                            soc.v.append(-scl * blk[jx])
                if mk.shape[0]:
                    bconst[:, off:off + mk.shape[0]] = sc[:, None] * (const @ mk.T)
        b_soc.append(bconst.ravel())
        dims += [d] * m_
    # ½e_tᵀPe_t ≤ E₀ + Y_t (t = T0+1..N): (β + c, β − c, √(2c)·L_p e_t) in the cone, β = E₀ + Y_t
    lam, V = np.linalg.eigh(ps.P)
    Lp = np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T
    d = 2 + nx
    tl = np.arange(T0 + 1, N + 1)
    m_ = tl.size
    st = soc.new(m_ * d)
    rb = st + np.arange(m_) * d
    c = cY[tl - 1]
    soc.add(-np.ones((1, 1)), rb, iY[tl - 1])
    soc.add(-np.ones((1, 1)), rb + 1, iY[tl - 1])
    sc = np.sqrt(2.0 * c)
    for i_ in range(nx):
        for jx in np.nonzero(Lp[i_])[0]:
            soc.i.append(rb + 2 + i_)
            soc.j.append(L.x(tl) + jx)
            soc.v.append(-sc * Lp[i_, jx])
    bconst = np.zeros((m_, d))
    bconst[:, 0], bconst[:, 1] = storage + c, storage - c
    bconst[:, 2:] = -sc[:, None] * (Xf[tl] @ Lp.T)
    b_soc.append(bconst.ravel())
    dims += [d] * m_
    # the whole program, scaled as the active bound's (Y_t by its row's energy scale)
    pad = lambda A_: sp.hstack([A_, sp.csc_matrix((A_.shape[0], N))]).tocsc()  # noqa: E731
    A_eq = sp.vstack([pad(prog.A_eq), eq.matrix(n)]).tocsc()
    b_eq = np.concatenate([prog.b_eq, *b_eq_x])
    A_in = pad(prog.A_in)
    scale = np.concatenate([prog.scale, 0.1 * cY])
    Dm = sp.diags(scale)
    A_eq_s, b_eq = normalise_rows((A_eq @ Dm).tocsc(), b_eq)
    A_in_s, lo, hi = normalise_rows((A_in @ Dm).tocsc(), prog.lo, prog.hi)
    A_s = (soc.matrix(n) @ Dm).tocsr()
    b_s = np.concatenate(b_soc)
    # each cone scaled as a whole (a cone is invariant under a positive factor, not under row scaling)
    dims = np.asarray(dims, dtype=int)
    row_max = np.asarray(abs(A_s).max(axis=1).todense()).ravel()
    block = np.repeat(np.arange(len(dims)), dims)
    bmax = np.zeros(len(dims))
    np.maximum.at(bmax, block, row_max)
    dscale = 1.0 / np.where(bmax > 0, bmax, 1.0)[block]
    A_s = (sp.diags(dscale) @ A_s).tocsc()
    b_s = b_s * dscale
    Pdiag = np.zeros(n)
    Pdiag[prog.iy] = 2.0 * scale[prog.iy] ** 2
    P = sp.diags(Pdiag).tocsc()
    t_setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    z, primal, dual, status, iters = clarabel_solve(P, np.zeros(n), A_eq_s, b_eq, A_in_s, lo, hi, tol,
                                                    soc=(A_s, b_s, dims), who="dissipative_bound",
                                                    almost_gap=ALMOST_GAP, stalled_ok=True)
    t_solve = time.perf_counter() - t1
    v = z * scale
    X, F, limit_active = prog.solution(v[:n0])
    return DissipativeBoundResult(
        bound=float(-min(dual, primal)), primal_return=float(-primal), f_max=f_max, f_max_source=source, F=F,
        X=X, limit_active=limit_active, solver=solver, status=status, iterations=int(iters),
        setup_seconds=t_setup, solve_seconds=t_solve, kind="passive",
        absorbed=absorbed_energy(p, F, X, static_forces=Fs, min_damping=cmin), **extra)
