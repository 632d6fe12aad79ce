"""A passivity-aware upper bound: the active-actuator bound (:mod:`.bound`) with the actuator barred from giving
back more energy than it has taken from the plant.

**What it covers.** Every force history F (total damper force, linear between the 1 ms rows: the bound's model of
the environment, as for :func:`~.bound.active_bound`) with, at every row t_r,

* |F(t_r) − F_static| ≤ f_max (the active bound's force limit), and
* ∫₀^{t_r} (F − F_static)·ẋ_d dτ ≥ −E₀ (summed over the dampers where there are several),

E₀ = ``storage`` (J, default 0): the device, started with an empty store, has never given the plant more energy than
it has taken from it. That is a *passive device with internal storage*, a class larger than the semi-active one:
every force history with (F − F_static)·ẋ_d ≥ 0 at every instant belongs to it (its absorbed energy never falls),
and so does a device that stores energy and returns it later (a spring, a regenerative actuator with a lossless
battery). The bound holds for all of them — every semi-active damper whose force stays within f_max, whatever its
model — and for every passive damper model whose internal store starts empty. The environment's Spencer–Dyke damper:
the accumulator spring k1 stores ½k1·x_d² (x_d(0) = 0: the plant starts at its static equilibrium), the internal
spring k0 ½k0(x − y)², the Bouc–Wen element its hysteretic z, the dashpots c0, c1 dissipate. One caveat is of the
model, not of MR fluid: a Bouc–Wen gain α(u) that follows the command makes a spring of stiffness α·A in its elastic
range, and a spring whose stiffness is switched can be pumped (soft while it extends, stiff while it recovers), at
most ~Δα·z_max²/(2A) per cycle (17 mJ for the automotive preset, 11 mJ for the prototype). Measured: passive-on,
passive-off, every law of the yardstick at 1 ms, random and bang-bang commands and the clairvoyant optimum have
absorbed ≥ 0 J (to rounding) at every row of every episode checked (:func:`absorbed_energy` on the environment's forces;
``experiments/measurements/accuracy/bound_bracket.py``, ``tests/optimal/test_bound.py``); ``storage`` > 0 widens the class
to cover a store explicitly (the bound grows with it, to the active bound).

**How.** The plant seen from the damper's port is passive: with M, K, C recovered from the problem's matrices
(:func:`port_storage`: M q̈ + C q̇ + K q = −Sᵀ(F − F_static) + E w), the storage ½eᵀPe, P = diag(K, M), and the
dissipation ½eᵀQe, Q = diag(0, 2C), satisfy for the deviation e = x − x̄ from the free response x̄ (F ≡ F_static,
the disturbance known) the exact identity

    ∫₀ᵗ (F − F_static)·ẋ_d dτ = ∫₀ᵗ (F − F_static)·ẋ̄_d dτ − ½e(t)ᵀP e(t) − ½∫₀ᵗ eᵀQe dτ

(d/dt ½eᵀPe = −½eᵀQe − (F − F_static)·C_v e, since P B_F = −C_vᵀ and AᵀP + PA = −Q). The first term is linear in
the forces (x̄ is data), the others are concave quadratics: the energy condition at each row is a convex constraint.
A running variable Y_t — the first term minus the dissipation, a linear recursion (no damping in the plant, the car)
or one rotated second-order cone per row (the building's structural damping) — turns it into one cone per row,
½e_tᵀPe_t ≤ E₀ + Y_t, added to the active bound's QP. The integrals over each row are 3-point Gauss–Legendre on the
exact intra-row response (the force-linear part to rounding, the rest within ~1e-9 relative). Rows where the plant
is still at rest with an empty store (before a bump arrives) force e = 0 exactly: equalities, not cones at their
apex. Clarabel solves the SOCP; the bound is −its dual objective (weak duality), an upper bound on the return of
every force history of the class to the solver's tolerance, as the active bound is.

**Why not the semi-active condition row by row.** (F − F_static)·ẋ_d ≥ 0 is bilinear; the convex hull of
{(F, v): (F − F_static)·v ≥ 0, |F − F_static| ≤ f_max} is the whole box unless the stroke velocity v is bounded at
that row, so a McCormick envelope (or any per-row cut) needs [v_lo, v_hi] valid for every admissible trajectory.
The class contains F ≡ F_static, and the car has no damping but its damper: bounds from the force limit alone grow
by ~41 m/s per second of episode (±4 m/s after 0.1 s, against 0.3 m/s RMS stroke velocity); bounds restricted to
trajectories scoring better than the best law but with the force box dropped (an ellipsoid, closed form) were
±144 m/s on a 2 s ISO episode; tightening them by a convex problem per row is 2·10⁴ solves per 10 s episode. And even
the envelope of the velocities the laws and the clairvoyant actually had (not a valid bound: narrower than any
valid one) leaves most of the bracket (``bench_bound_bracket --oracle``; docs/yardstick.md). A Lagrangian (Shor)
relaxation with one multiplier per row is tractable only where the Lagrangian stays concave in the forces; with
nonincreasing multipliers it is a positive combination of the cumulative conditions imposed here (concave by the
plant's passivity) — whether other multipliers gain anything is open.
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


@dataclass
class DissipativeBoundResult(BoundResult):
    """The passivity-aware bound of an episode: :class:`~.bound.BoundResult`'s fields (``kind`` "passive") and the
    initial store ``storage`` (J) and the optimum's ``absorbed`` energy ∫₀^{t_r} (F − F_static)·ẋ_d (n_rows,)."""

    storage: float = 0.0
    absorbed: np.ndarray | None = None


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


def free_response(problem: EpisodeProblem) -> np.ndarray:
    """The plant's states at every row (n_rows, nx) with the damper force held at F_static (exact, FOH)."""
    return _response(problem, np.full((problem.n_rows, problem.nd), problem.F_static))


def absorbed_energy(problem: EpisodeProblem, F, X=None) -> np.ndarray:
    """∫₀^{t_r} (F − F_static)·ẋ_d dτ (J, summed over the dampers) at every row r of the force history ``F``
    (n_rows, nd; linear between rows) on the problem's plant: the energy the dampers have taken from the plant.
    ``X``: the plant's states at the rows (default: the exact response of the plant to ``F``, the bound's
    model). The class of :func:`dissipative_bound` is ``absorbed_energy(...) >= −storage`` at every row."""
    p = problem
    F = np.asarray(F, dtype=float).reshape(p.n_rows, p.nd)
    B = np.hstack([p.BF, p.Bw])
    U = np.hstack([F, p.W])
    X = _response(p, F) if X is None else np.asarray(X, dtype=float)
    s, w = _gauss()
    dF = F - p.F_static
    per_row = np.zeros(p.n_rows - 1)
    for (Phk, G0, G1), sk, wk in zip(_node_maps(p.A, B, p.dt, s), s, w):
        Xk = X[:-1] @ Phk.T + U[:-1] @ G0.T + (U[1:] - U[:-1]) @ G1.T
        Fk = (1 - sk) * dF[:-1] + sk * dF[1:]
        per_row += wk * p.dt * np.sum(Fk * (Xk @ p.Cv.T), axis=1)
    return np.concatenate([[0.0], np.cumsum(per_row)])


def dissipative_bound(problem: EpisodeProblem, f_max: float | None = None, storage: float = 0.0,
                      solver: str = "clarabel", limits: bool = True, tol: float = 1e-8) -> DissipativeBoundResult:
    """The passivity-aware bound of ``problem`` (see the module docstring): an upper bound on the return of every
    force history within ``f_max`` of F_static that never gives back more energy than it has absorbed plus
    ``storage`` (J). ``f_max``, ``solver``, ``limits`` and ``tol`` as for :func:`~.bound.active_bound` (the same
    default force limit); never above the active bound of the same ``f_max`` (to the solvers' tolerances)."""
    f_max, source = check_arguments(problem, f_max, solver, tol)
    if isinstance(storage, bool) or not isinstance(storage, (int, float, np.floating, np.integer)) \
            or not np.isfinite(storage) or storage < 0:
        raise ValueError(f"storage must be finite and >= 0 J, got {storage!r}")
    storage = float(storage)
    ps = port_storage(problem)
    if f_max == 0.0:   # one force history, F ≡ F_static, which takes no energy: the active bound's, exactly
        from dataclasses import asdict

        from .bound import active_bound

        res = active_bound(problem, f_max=0.0, solver=solver, limits=limits, tol=tol)
        return DissipativeBoundResult(**{**asdict(res), "kind": "passive", "f_max_source": source},
                                      storage=storage, absorbed=np.zeros(problem.n_rows))
    t0 = time.perf_counter()
    p = problem
    prog = program(p, f_max, limits)
    L = prog.L
    N, nx, nd, dt = L.N, L.nx, L.nd, p.dt
    n0, n = L.n, L.n + N
    iY = n0 + np.arange(N)            # Y_t, t = 1..N: the energy the plant may hold beyond its free response
    r0 = np.arange(N)                 # rows r = 0..N−1 (intervals [t_r, t_{r+1}])
    Xf = free_response(p)
    s, w = _gauss()
    maps = _node_maps(p.A, np.hstack([p.BF, p.Bw]), dt, s)
    Uf = np.hstack([np.full((N + 1, nd), p.F_static), p.W])
    # the free stroke velocity against the force's two ends on each row: ∫ ΔF v̄ = a_r·ΔF_r + b_r·ΔF_{r+1}
    a, b = np.zeros((N, nd)), np.zeros((N, nd))
    for (Phk, G0, G1), sk, wk in zip(maps, s, w):
        vk = (Xf[:-1] @ Phk.T + Uf[:-1] @ G0.T + (Uf[1:] - Uf[:-1]) @ G1.T) @ p.Cv.T
        a += wk * dt * (1 - sk) * vk
        b += wk * dt * sk * vk
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
    dissipative = bool(np.any(ps.C))
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
        # Y_{r+1} − Y_r − a_r·F_r − b_r·F_{r+1} = −(a_r + b_r)·F_static  (Y_0 = 0)
        st = eq.new(live.size)
        ri = st + np.arange(live.size)
        eq.add(np.ones((1, 1)), ri, iY[live])
        has = live >= 1
        eq.add(-np.ones((1, 1)), ri[has], iY[live[has] - 1])
        for j in range(nd):
            eq.i += [ri, ri]
            eq.j += [Fcol[0][j][live], Fcol[1][j][live]]
            eq.v += [-a[live, j], -b[live, j]]
        b_eq_x.append(-np.sum(a + b, axis=1)[live] * p.F_static)
    elif live.size:
        # ½∫_r^{r+1} eᵀQe ≤ β_r = Y_r − Y_{r+1} + a_r·ΔF_r + b_r·ΔF_{r+1}: (β + c, β − c, 2√c·g) in the cone,
        # g = [√(½ w_k dt)·L_q e(t_r + s_k dt)]_k, e(τ) = Φ(τ)(x_r − x̄_r) + Γ0 ΔF_r + Γ1 (ΔF_{r+1} − ΔF_r)
        lam, V = np.linalg.eigh(ps.Q)
        keep = lam > 1e-12 * lam.max()
        Lq = np.sqrt(lam[keep])[:, None] * V[:, keep].T
        nq_ = Lq.shape[0]
        d = 2 + len(s) * nq_
        m_ = live.size
        st = soc.new(m_ * d)
        rb = st + np.arange(m_) * d
        c = cstep[live]
        bconst = np.zeros((m_, d))
        has = live >= 1
        for k_, sign in enumerate((1.0, -1.0)):   # the rows β + c and β − c: s = b − A v
            rr = rb + k_
            soc.add(-np.ones((1, 1)), rr[has], iY[live[has] - 1])      # +Y_r (r ≥ 1)
            soc.add(np.ones((1, 1)), rr, iY[live])                      # −Y_{r+1}
            for j in range(nd):
                soc.i += [rr, rr]
                soc.j += [Fcol[0][j][live], Fcol[1][j][live]]
                soc.v += [-a[live, j], -b[live, j]]
            bconst[:, k_] = sign * c - np.sum(a + b, axis=1)[live] * p.F_static
        FsV = np.full(nd, p.F_static)
        for k_, ((Phk, G0, G1), wk) in enumerate(zip(maps, w)):
            m = np.sqrt(0.5 * wk * dt) * Lq                            # (nq_, nx), times 2√c per row
            G0F, G1F = G0[:, :nd], G1[:, :nd]
            rows_k = rb + 2 + k_ * nq_
            sc = 2.0 * np.sqrt(c)
            for i_ in range(nq_):
                for blk, cols, sel in ((m[i_] @ Phk, L.x(live[has]), has), (m[i_] @ (G0F - G1F), L.F(live), None),
                                       (m[i_] @ G1F, L.F(live + 1), None)):
                    rows_i = (rows_k + i_) if sel is None else (rows_k + i_)[sel]
                    scl = sc if sel is None else sc[sel]
                    for jx in np.nonzero(blk)[0]:
                        soc.i.append(rows_i)
                        soc.j.append(cols + jx)
                        soc.v.append(-scl * blk[jx])
            bconst[:, 2 + k_ * nq_: 2 + (k_ + 1) * nq_] = \
                -sc[:, None] * ((Xf[live] @ Phk.T + FsV @ G0F.T) @ m.T)
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
                                               soc=(A_s, b_s, dims), who="dissipative_bound")
    t_solve = time.perf_counter() - t1
    v = z * scale
    X, F, limit_active = prog.solution(v[:n0])
    return DissipativeBoundResult(
        bound=float(-min(dual, primal)), primal_return=float(-primal), f_max=f_max, f_max_source=source, F=F,
        X=X, limit_active=limit_active, solver=solver, status=status, iterations=int(iters),
        setup_seconds=t_setup, solve_seconds=t_solve, kind="passive", storage=storage,
        absorbed=absorbed_energy(p, F, X))
