"""The active-actuator bound: the best return of an episode with the damper replaced by an ideal force actuator.

On the episode of an :class:`~.problem.EpisodeProblem` the damper force F becomes a free input within
|F − F_static| ≤ f_max at every physics row (dt = 1 ms), linear between rows (the environment's force is
continuous; a first-order hold reproduces its trajectories within 0.2 % of their peaks where a zero-order hold
misses by 5–15 %). Any semi-active damper whose force stays within f_max produces such a history, so the optimum
bounds its return from above (the customary ideal-actuator reference: Dyke et al. 1996; Savaresi et al.,
Semi-Active Suspension Control Design for Vehicles, 2010, ch. 5). On the linear plant with the environment's
quadratic reward it is a convex QP::

    min  Σ_{r=1}^{N} Σ_i ỹ_i(r)²                           (= −return; ỹ_i = √weight_i · s_i, N = n_rows − 1)
    s.t. x_{r+1} = Φ x_r + Γ_a u_r + Γ_b (u_{r+1} − u_r),  u = [F, W]   (exact for u linear between rows)
         ξ_{r+1} = A_f ξ_r + B_f s_r,  y = C_f ξ + D_f s,  ξ_1 = 0      (a term's causal filter, e.g. ISO Wk,
                                                                         its second-order sections in state space)
         |F_r − F_static| ≤ f_max (r = 0..N),   |G_lim·[x_r, F_r, W_r]| ≤ bound (r = 1..N)

with the states x_r, forces F_r, filter states ξ_r and weighted outputs ỹ_r of every row as variables (sparse:
~10⁵ variables for 10 s), solved by Clarabel (Goulart & Chen 2024, interior point). Its dual objective is a lower
bound on the optimal cost up to its dual residual (weak duality; tolerances 1e-8), so ``bound`` = −(dual objective)
is an upper bound on the return of every such controller, not an estimate. An infeasible problem (no force history
within f_max keeps the stroke within its limit) or a failed solve raises ``RuntimeError``.

The ideal actuator may push energy into the plant, which no damper can: :mod:`.dissipative` adds the convex part of
that restriction (a bound on every passive device, tighter on transients), on this module's :func:`program`.

The solvers are optional dependencies, imported on first use.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .problem import EpisodeProblem, sos_state_space  # noqa: F401  (sos_state_space: re-exported)

#: Clarabel only: OSQP (first-order ADMM) did not reach 1e-6 on a 2 s car episode in 200 000 iterations (265 s), the
#: 2000-step dynamics chain conditioning it badly, where Clarabel's interior point needs 14 iterations (1 s).
SOLVERS = ("clarabel",)


@dataclass
class BoundResult:
    """The active-actuator bound of an episode.

    ``bound``: the upper bound on the return (−Clarabel's dual objective); ``primal_return``: the return of the
    optimal force history on the linear plant (−the primal objective, ≤ ``bound`` by the duality gap);
    ``f_max`` (N) and ``f_max_source``; the optimal total forces ``F`` (n_rows, nd, preload
    included) and plant states ``X`` (n_rows, nx); ``limit_active``: a stroke limit binds somewhere; the solver's
    name, status, iterations and wall times (s); ``kind``: "active" (this module) or "passive"
    (:func:`~.dissipative.dissipative_bound`)."""

    bound: float
    primal_return: float
    f_max: float
    f_max_source: str
    F: np.ndarray
    X: np.ndarray
    limit_active: bool
    solver: str
    status: str
    iterations: int
    setup_seconds: float
    solve_seconds: float
    kind: str = "active"

    def covers(self, force, f_static: float) -> bool:
        """True if a force history (total, N) stays within f_max of ``f_static``: the bound holds for it."""
        f = np.asarray(force, dtype=float)
        return bool(np.nanmax(np.abs(f - f_static), initial=0.0) <= self.f_max * (1 + 1e-12))


def passive_on_force_peak(problem: EpisodeProblem) -> float:
    """The damper's largest |F − F_static| in the episode at its maximum command (passive-on, re-simulated in the
    environment). A switching law can exceed it (it can let the stroke velocity grow with the damper off, then
    switch on: skyhook on the 5 cm bump, 7.4 kN against passive-on's 5.3 kN): check with
    :meth:`BoundResult.covers`, or give ``f_max`` (the yardstick gives the largest force of all its controllers)."""
    U = np.full((problem.n_steps, problem.nd), problem.v_max)
    tr = problem.replay(U, states=True)
    return float(np.nanmax(np.abs(tr.F - problem.F_static)))


def first_order_hold(A: np.ndarray, B: np.ndarray, dt: float):
    """(Φ, Γ_a, Γ_b) with x_{r+1} = Φ x_r + Γ_a u_r + Γ_b (u_{r+1} − u_r), exact for u linear between samples
    (as :func:`mrd_env.mechanics.response.foh_response`)."""
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n], M[:n, n:n + m], M[n:n + m, n + m:] = A, B, np.eye(m)
    E = scipy.linalg.expm(M * dt)
    return E[:n, :n], E[:n, n:n + m], E[:n, n + m:] / dt


class _Layout:
    """Variable indices: F_0, then per row r = 1..N the block [x_r, F_r, ξ_r, ỹ_r]."""

    def __init__(self, N, nx, nd, nxi, ny):
        self.N, self.nx, self.nd, self.nxi, self.ny = N, nx, nd, nxi, ny
        self.block = nx + nd + nxi + ny
        self.n = nd + N * self.block

    def _at(self, r, offset):
        return self.nd + (np.asarray(r) - 1) * self.block + offset

    def x(self, r):
        return self._at(r, 0)

    def F(self, r):
        r = np.asarray(r)
        return np.where(r == 0, 0, self._at(r, self.nx))

    def xi(self, r):
        return self._at(r, self.nx + self.nd)

    def y(self, r):
        return self._at(r, self.nx + self.nd + self.nxi)


class Rows:
    """A sparse constraint block built row-block by row-block: M (a × b) at (row0 + i, col0 + j) for every r."""

    def __init__(self):
        self.i, self.j, self.v = [], [], []
        self.n = 0

    def add(self, M, rows0, cols0):
        M = np.atleast_2d(M)
        ii, jj = np.nonzero(M)
        if ii.size == 0:
            return
        rows0, cols0 = np.atleast_1d(rows0), np.atleast_1d(cols0)
        self.i.append((rows0[:, None] + ii[None]).ravel())
        self.j.append((cols0[:, None] + jj[None]).ravel())
        self.v.append(np.broadcast_to(M[ii, jj], (rows0.size, ii.size)).ravel())

    def new(self, count):
        start = self.n
        self.n += count
        return start

    def matrix(self, n_cols):
        if not self.i:
            return sp.csc_matrix((self.n, n_cols))
        return sp.csc_matrix((np.concatenate(self.v), (np.concatenate(self.i), np.concatenate(self.j))),
                             shape=(self.n, n_cols))


def active_bound(problem: EpisodeProblem, f_max: float | None = None, solver: str = "clarabel",
                 limits: bool = True, tol: float = 1e-8) -> BoundResult:
    """The active-actuator bound of ``problem`` (see the module docstring).

    ``f_max``: the actuator's force limit beyond the preload (N, finite); None: the damper's largest force in the
    episode at its maximum command (:func:`passive_on_force_peak`). ``solver``: "clarabel" (the only one, see
    ``SOLVERS``). ``limits``: impose the episode's stroke limits (a controller that exceeds them is penalised far
    below any bound). ``tol``: the solver's tolerances (gap and feasibility)."""
    f_max, source = check_arguments(problem, f_max, solver, tol)
    t0 = time.perf_counter()
    prog = program(problem, f_max, limits)
    L, scale = prog.L, prog.scale
    Dm = sp.diags(scale)
    A_eq_s, b_eq = normalise_rows((prog.A_eq @ Dm).tocsc(), prog.b_eq)
    A_in_s, lo, hi = normalise_rows((prog.A_in @ Dm).tocsc(), prog.lo, prog.hi)
    Pdiag = np.zeros(L.n)
    Pdiag[prog.iy] = 2.0 * scale[prog.iy] ** 2
    P = sp.diags(Pdiag).tocsc()
    q = np.zeros(L.n)
    t_setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    z, primal, dual, status, iters = clarabel_solve(P, q, A_eq_s, b_eq, A_in_s, lo, hi, tol)
    t_solve = time.perf_counter() - t1
    X, F, limit_active = prog.solution(z * scale)
    # weak duality: dual ≤ optimum ≤ primal; the smaller of the two is the safe side if rounding inverts them
    return BoundResult(bound=float(-min(dual, primal)), primal_return=float(-primal), f_max=f_max,
                       f_max_source=source, F=F, X=X, limit_active=limit_active, solver=solver, status=status,
                       iterations=int(iters), setup_seconds=t_setup, solve_seconds=t_solve)


def check_arguments(problem, f_max, solver, tol) -> tuple[float, str]:
    """(f_max, its source) after checking a bound's arguments (``ValueError`` naming the bad one)."""
    if not isinstance(problem, EpisodeProblem):
        raise ValueError(f"problem must be an EpisodeProblem (mrd_env.optimal.episode_problem), got "  # noqa: TRY004
                         f"{type(problem).__name__}")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {list(SOLVERS)}, got {solver!r}")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1e-2):
        raise ValueError(f"tol must be in (0, 1e-2), got {tol!r}")
    if f_max is None:
        return passive_on_force_peak(problem), "passive-on's peak force in the episode"
    if isinstance(f_max, bool) or not isinstance(f_max, (int, float, np.floating, np.integer)) \
            or not math.isfinite(f_max) or f_max < 0:
        # without a limit forces the cost hardly sees (spikes the plant filters out) make the optimum
        # unbounded in direction: the interior point fails numerically (measured on the car)
        raise ValueError(f"f_max must be finite and >= 0 N, got {f_max!r}")
    return float(f_max), "given"


@dataclass
class Program:
    """The active bound's QP in the problem's own units (before scaling): the variable layout ``L``, the cost's
    channels, the plant over rows (Φ, Γ_a, Γ_b split into force and disturbance columns), the equalities
    ``A_eq z = b_eq``, the inequalities ``lo ≤ A_in z ≤ hi``, the variables' typical sizes ``scale`` and the
    indices ``iy`` of the weighted outputs (the cost is Σ z[iy]²). :mod:`.dissipative` adds its own rows to it."""

    p: EpisodeProblem
    f_max: float
    limits: bool
    L: "_Layout"
    chans: list
    Phi: np.ndarray
    GaF: np.ndarray
    GbF: np.ndarray
    GaW: np.ndarray
    GbW: np.ndarray
    A_eq: sp.csc_matrix
    b_eq: np.ndarray
    A_in: sp.csc_matrix
    lo: np.ndarray
    hi: np.ndarray
    scale: np.ndarray
    iy: np.ndarray

    def solution(self, v: np.ndarray):
        """(X (n_rows, nx), F (n_rows, nd), a stroke limit binds) of the unscaled solution ``v``."""
        p, L = self.p, self.L
        N, nx, nd = L.N, L.nx, L.nd
        r1 = np.arange(1, N + 1)
        X = np.empty((N + 1, nx))
        X[0] = p.x0
        X[1:] = v[L.x(r1)[:, None] + np.arange(nx)]
        F = np.empty((N + 1, nd))
        F[0] = v[:nd]
        F[1:] = v[L.F(r1)[:, None] + np.arange(nd)]
        limit_active = False
        if self.limits and p.limits:
            for lim in p.limits:
                s_ = np.hstack([X, F, p.W]) @ np.asarray(lim.G, dtype=float).ravel()
                limit_active |= bool(np.max(np.abs(s_[1:])) >= lim.bound * (1 - 1e-6))
        return X, F, limit_active


def program(problem: EpisodeProblem, f_max: float, limits: bool = True) -> Program:
    """The active bound's QP of ``problem`` with the force limit ``f_max`` (see the module docstring)."""
    p = problem
    nx, nd, N, dt = p.nx, p.nd, p.n_rows - 1, p.dt
    W = p.W
    # the plant over rows, inputs u = [F, W] linear between rows
    Phi, Ga, Gb = first_order_hold(p.A, np.hstack([p.BF, p.Bw]), dt)
    GaF, GbF, GaW, GbW = Ga[:, :nd], Gb[:, :nd], Ga[:, nd:], Gb[:, nd:]
    # the cost terms: each channel's weighted output ỹ = √w·(filter of) G·[x, F, W]
    chans = []   # (√w·G rows over [x, F] (k, nx+nd), √w·G over W (k, nw), filter or None)
    for term in p.terms:
        sw = np.sqrt(np.asarray(term.weight, dtype=float))[:, None]
        G = np.asarray(term.G, dtype=float)
        for i in range(G.shape[0]):
            chans.append((G[i:i + 1, :nx + nd], G[i:i + 1, nx + nd:], sw[i, 0],
                          None if term.sos is None else sos_state_space(term.sos)))
    ny = len(chans)
    nxi = sum(0 if c[3] is None else c[3][0].shape[0] for c in chans)
    L = _Layout(N, nx, nd, nxi, ny)
    rows, rhs = Rows(), []  # rhs: (first row, values) of the equality right-hand side
    r0, r1 = np.arange(N), np.arange(1, N + 1)
    # dynamics, r = 0..N−1: x_{r+1} − Φ x_r − (Γa−Γb)_F F_r − Γb_F F_{r+1} = (Γa−Γb)_W W_r + Γb_W W_{r+1} (+ Φ x0)
    start = rows.new(N * nx)
    ri = start + r0 * nx
    rows.add(np.eye(nx), ri, L.x(r0 + 1))
    rows.add(-Phi, ri[1:], L.x(r0[1:]))
    rows.add(-(GaF - GbF), ri, L.F(r0))
    rows.add(-GbF, ri, L.F(r0 + 1))
    b_dyn = W[:-1] @ (GaW - GbW).T + W[1:] @ GbW.T
    b_dyn[0] += Phi @ p.x0
    rhs.append((start, b_dyn.ravel()))
    # the weighted outputs (r = 1..N) and the filters' states
    start = rows.new(N * ny)
    yrows = start + (r1 - 1) * ny
    b_y = np.zeros((N, ny))
    k = 0
    for c, (Gxf, Gw, sw, filt) in enumerate(chans):
        rows.add(np.ones((1, 1)), yrows + c, L.y(r1) + c)
        if filt is None:  # ỹ − √w·G_xf·[x, F] = √w·G_w·W
            rows.add(-sw * Gxf[:, :nx], yrows + c, L.x(r1))
            rows.add(-sw * Gxf[:, nx:], yrows + c, L.F(r1))
            b_y[:, c] = sw * (W[1:] @ Gw.T)[:, 0]
            continue
        # ỹ − √w·(C ξ + D·G_xf·[x, F]) = √w·D·G_w·W
        Af, Bf, Cf, Df = filt
        nf, d0 = Af.shape[0], float(Df[0, 0])
        rows.add(-sw * Cf, yrows + c, L.xi(r1) + k)
        rows.add(-sw * d0 * Gxf[:, :nx], yrows + c, L.x(r1))
        rows.add(-sw * d0 * Gxf[:, nx:], yrows + c, L.F(r1))
        b_y[:, c] = sw * d0 * (W[1:] @ Gw.T)[:, 0]
        # ξ_1 = 0;  ξ_{r+1} − A ξ_r − B·G_xf·[x_r, F_r] = B·G_w·W_r
        fs = rows.new(N * nf)
        fr = fs + (r1 - 1) * nf
        rows.add(np.eye(nf), fr, L.xi(r1) + k)
        rows.add(-Af, fr[1:], L.xi(r1[:-1]) + k)
        rows.add(-Bf @ Gxf[:, :nx], fr[1:], L.x(r1[:-1]))
        rows.add(-Bf @ Gxf[:, nx:], fr[1:], L.F(r1[:-1]))
        b_xi = np.zeros((N, nf))
        b_xi[1:] = (W[1:-1] @ Gw.T) @ Bf.T
        rhs.append((fs, b_xi.ravel()))
        k += nf
    rhs.append((start, b_y.ravel()))
    if f_max == 0.0:  # no force beyond the preload: an equality (a box of zero width has no interior)
        start = rows.new((N + 1) * nd)
        rows.add(np.eye(nd), start + np.arange(N + 1) * nd, L.F(np.arange(N + 1)))
        rhs.append((start, np.full((N + 1) * nd, p.F_static)))
    b_eq = np.zeros(rows.n)
    for first, values in rhs:
        b_eq[first:first + values.size] = values
    A_eq = rows.matrix(L.n)
    # inequalities: the force box (F_0..F_N) and the stroke limits (rows 1..N)
    ineq = Rows()
    lo, hi = [], []
    if f_max > 0.0:
        s = ineq.new((N + 1) * nd)
        rows_f = s + np.arange(N + 1) * nd
        ineq.add(np.eye(nd), rows_f, L.F(np.arange(N + 1)))
        lo.append(np.full((N + 1) * nd, p.F_static - f_max))
        hi.append(np.full((N + 1) * nd, p.F_static + f_max))
    if limits:
        for lim in p.limits:
            g = np.asarray(lim.G, dtype=float).ravel()
            s = ineq.new(N)
            ri = s + (r1 - 1)
            ineq.add(g[None, :nx], ri, L.x(r1))
            ineq.add(g[None, nx:nx + nd], ri, L.F(r1))
            off = W[1:] @ g[nx + nd:]
            lo.append(-lim.bound - off)
            hi.append(lim.bound - off)
    A_in = ineq.matrix(L.n)
    lo = np.concatenate(lo) if lo else np.zeros(0)
    hi = np.concatenate(hi) if hi else np.zeros(0)
    # variable scaling (the solver sees O(1) unknowns): states and filter states by their size in the free response
    # (no damper force), forces by f_max (or 1 kN), weighted outputs as they are (√cost per row)
    scale = _scales(p, L, chans, Phi, GaF, GbF, GaW, GbW, f_max)
    iy = np.concatenate([L.y(r1) + c for c in range(ny)])
    return Program(p, f_max, limits, L, chans, Phi, GaF, GbF, GaW, GbW, A_eq, b_eq, A_in, lo, hi, scale, iy)


def _scales(p, L, chans, Phi, GaF, GbF, GaW, GbW, f_max):
    """Typical sizes of the variables, from the plant's response with F = F_static (no damper force)."""
    N, nx, nd = L.N, L.nx, L.nd
    W = p.W
    X = np.empty((N + 1, nx))
    X[0] = p.x0
    Fs = np.full(nd, p.F_static)
    drive = W[:-1] @ (GaW - GbW).T + W[1:] @ GbW.T + Fs @ GaF.T
    for r in range(N):
        X[r + 1] = Phi @ X[r] + drive[r]
    sx = np.max(np.abs(X), axis=0)
    sx = np.where(sx > 0, sx, 1.0)
    s = np.ones(L.n)
    fscale = f_max if f_max > 0 else 1000.0
    s[:nd] = fscale
    r1 = np.arange(1, N + 1)
    for i in range(nx):
        s[L.x(r1) + i] = sx[i]
    for i in range(nd):
        s[L.F(r1) + i] = fscale
    k = 0
    for Gxf, Gw, sw, filt in chans:
        if filt is None:
            continue
        Af, Bf = filt[:2]
        nf = Af.shape[0]
        u = np.hstack([X, np.tile(Fs, (N + 1, 1))]) @ Gxf.T + W @ Gw.T
        xi = np.zeros(nf)
        peak = np.zeros(nf)
        for r in range(1, N + 1):
            peak = np.maximum(peak, np.abs(xi))
            xi = Af @ xi + Bf[:, 0] * u[r, 0]
        peak = np.where(peak > 0, peak, 1.0)
        for i in range(nf):
            s[L.xi(r1) + k + i] = peak[i]
        k += nf
    return s


def normalise_rows(A, *sides):
    """Every row of A (and its right-hand sides) divided by its largest coefficient."""
    m = np.asarray(abs(A).max(axis=1).todense()).ravel() if A.shape[0] else np.zeros(0)
    d = 1.0 / np.where(m > 0, m, 1.0)
    return (sp.diags(d) @ A).tocsc(), *(side * d for side in sides)


def clarabel_solve(P, q, A_eq, b_eq, A_in, lo, hi, tol, soc=None, who="active_bound", almost_gap=1e-6,
                   stalled_ok=False):
    """Solve min ½zᵀPz + qᵀz s.t. A_eq z = b_eq, lo ≤ A_in z ≤ hi and, with ``soc`` = (A_s, b_s, dims), every
    block of b_s − A_s z (consecutive rows, sizes ``dims``) in a second-order cone. (z, primal, dual objective,
    status, iterations); ``RuntimeError`` if infeasible or not solved. "Almost solved" is accepted where the dual
    residual is ≤ 1e-6 (the dual objective is then still a lower bound on the cost) and the relative gap
    ≤ ``almost_gap`` (how much looser than the optimum the bound may be); with ``stalled_ok`` also a stop for
    insufficient progress where the dual residual is ≤ 1e-9 and the gap ≤ ``almost_gap`` (a dual-feasible point's
    objective is a lower bound whatever the primal residual; the primal iterate is then approximate)."""
    import clarabel

    blocks, rhs = [A_eq, A_in, -A_in], [b_eq, hi, -lo]
    cones = [clarabel.ZeroConeT(A_eq.shape[0])]
    if A_in.shape[0]:
        cones.append(clarabel.NonnegativeConeT(2 * A_in.shape[0]))
    if soc is not None:
        A_s, b_s, dims = soc
        blocks.append(A_s)
        rhs.append(b_s)
        cones.extend(clarabel.SecondOrderConeT(int(d)) for d in dims)
    A = sp.vstack(blocks).tocsc()
    b = np.concatenate(rhs)
    st = clarabel.DefaultSettings()
    st.verbose = False
    st.tol_gap_abs = st.tol_gap_rel = tol
    st.tol_feas = tol
    st.max_iter = 200
    res = clarabel.DefaultSolver(P, q, A, b, cones, st).solve()
    status = str(res.status)
    if res.status == clarabel.SolverStatus.PrimalInfeasible or "Infeasible" in status:
        raise RuntimeError(f"{who}: the problem is infeasible ({status}): no force history within f_max keeps the "
                           "episode within its limits")
    gap = abs(res.obj_val - res.obj_val_dual) / max(1.0, abs(res.obj_val))
    # "almost solved": the reduced tolerances (1e-5) hold; the dual objective is still a bound if the gap is small
    near = res.status == clarabel.SolverStatus.AlmostSolved and gap <= almost_gap and res.r_dual <= 1e-6
    near |= stalled_ok and res.status == clarabel.SolverStatus.InsufficientProgress and gap <= almost_gap \
        and res.r_dual <= 1e-9
    if res.status != clarabel.SolverStatus.Solved and not near:
        raise RuntimeError(f"{who}: Clarabel did not solve the problem ({status} after {res.iterations} "
                           "iterations); no bound is reported")
    return np.asarray(res.x), float(res.obj_val), float(res.obj_val_dual), status, res.iterations
