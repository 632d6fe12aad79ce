"""The project's stepping scheme in JAX (:mod:`mrd_env.stepping`, ``_kernel_template.py``), for one system; vmap
batches it.

Alexander's two-stage SDIRK with the linear plant eliminated, Newton on each damper's internal states and force,
the command lag integrated exactly. Two schemes:

* ``exact``: the kernel's step as it is: Newton with its stop rule (corrections below ``NEWTON_TOL`` of the
  tolerance), its matrix reuse (a factorised Newton matrix carried between the stages and the steps of a control
  period, refreshed when convergence slows), the filtered error estimate and 2^k sub-steps on demand
  (``while_loop``s). It matches the numba kernel to rounding; forward-mode differentiable only (no reverse mode
  through ``while_loop``), and a vmapped batch waits for its slowest member. Its vectors are lists of scalars, its
  Newton matrix the kernel's whole (m × m, m = dampers × (states + 1)), every sum in the kernel's order: that is
  what keeps it within rounding of the kernel.
* ``differentiable``: a fixed amount of work per step: ``substeps`` sub-steps (a power of two, default 1), each
  the same two stages with ``newton_iterations`` full Newton iterations (default 2, the Jacobian refreshed at each)
  and no error control: straight-line code that reverse mode goes through. It works on arrays: the plant's
  vectors and its eliminated matrices as matrix products, every damper's functions at once over the damper axis
  (``vmap`` of the model's), and the Newton system reduced by block elimination to the dampers' forces (each
  damper's internal states eliminated by its own ns × ns block; what is left, (I − diag(α) P_x − diag(β) P_v) ΔF
  = r, is nd × nd). Under ``vmap`` every operation is one array operation over the batch and the dampers, so its
  cost hardly grows with the plant's size (``docs/jax.md``).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from ..stepping._kernel_template import MAX_ITER, NEWTON_TOL
from ..stepping.scheme import GAMMA, NO_CONVERGENCE, NONFINITE, OK
from .dampers import fast_power
from .linalg import lu_factor, lu_solve

__all__ = ["Plant", "Work", "lag_value", "delay_split", "macro_step", "end_forces", "empty_work", "OK",
           "NONFINITE", "NO_CONVERGENCE"]


class Plant(NamedTuple):
    """The linear part (:class:`mrd_env.stepping.SystemMatrices`): C (2, nd, nq), D (3, nd, nw) and, per sub-step
    level k (h = dt/2^k), Ainv (L, nq, nq), Bbar (L, nq, nw), Mq (L, nq, nd), PP (L, 2, nd, nd)."""
    C: jnp.ndarray
    D: jnp.ndarray
    Ainv: jnp.ndarray
    Bbar: jnp.ndarray
    Mq: jnp.ndarray
    PP: jnp.ndarray


class Work(NamedTuple):
    """The Newton matrix the exact scheme keeps between the stages and steps of a control period: its LU factors
    (m, m), pivots (m,), the damper Jacobians (nd, ns + 1, ns + 2) and the level it was made for (−1: none)."""
    K: jnp.ndarray
    piv: jnp.ndarray
    Jd: jnp.ndarray
    level: jnp.ndarray


def empty_work(nd: int, ns: int) -> Work:
    m = nd * (ns + 1)
    return Work(jnp.zeros((m, m)), jnp.zeros(m, jnp.int32), jnp.zeros((nd, ns + 1, ns + 2)),
                jnp.asarray(-1, jnp.int32))


def _rows(M):
    """A 2-D array as a list of lists of its scalars."""
    return [[M[i, k] for k in range(M.shape[1])] for i in range(M.shape[0])]


def _mv(M, v, start=None):
    """M·v as a list (M a list of rows), accumulated from ``start`` (a list, default zeros) in index order."""
    out = []
    for i, row in enumerate(M):
        acc = 0.0 if start is None else start[i]
        for k, m in enumerate(row):
            acc = acc + m * v[k]
        out.append(acc)
    return out


def _max(a, b):
    """The kernel's ``if e > err: err = e`` (a NaN e leaves err as it is)."""
    return jnp.where(b > a, b, a)


# --- the command lag (mrd_env.command_lag) -------------------------------------------------------------------
def lag_value(u0, va, vb, ts, eta_rise, eta_fall, tau):
    """u at ``tau`` after a step's start from u0, command va until ``ts`` and vb after (exact)."""
    e1 = jnp.where(va > u0, eta_rise, eta_fall)
    first = va + (u0 - va) * jnp.exp(-e1 * tau)
    us = jnp.where(ts > 0.0, va + (u0 - va) * jnp.exp(-e1 * ts), u0)
    e2 = jnp.where(vb > us, eta_rise, eta_fall)
    second = vb + (us - vb) * jnp.exp(-e2 * (tau - ts))
    return jnp.where(tau <= ts, first, second)


def delay_split(delay, dt):
    """(m, s) of :func:`mrd_env.command_lag.delay_split`: m whole steps and s = τ − m·dt."""
    m = jnp.floor(delay / dt * (1.0 + 1e-12))
    s = jnp.maximum(delay - m * dt, 0.0)
    return m.astype(jnp.int32), s


# --- one system's pieces ---------------------------------------------------------------------------------------
def kinematics(C, D, q, w):
    """Strokes, velocities and accelerations of the dampers (lists over dampers)."""
    nd = C.shape[1]
    xs, vs, As = [], [], []
    for j in range(nd):
        x = 0.0
        v = 0.0
        a = 0.0
        for i in range(len(q)):
            x = x + C[0, j, i] * q[i]
            v = v + C[1, j, i] * q[i]
        for m in range(len(w)):
            x = x + D[0, j, m] * w[m]
            v = v + D[1, j, m] * w[m]
            a = a + D[2, j, m] * w[m]
        xs.append(x)
        vs.append(v)
        As.append(a)
    return xs, vs, As


def _interpolate(w0, w1, frac):
    return [a + (b - a) * frac for a, b in zip(w0, w1)]


def _split(Y, nq, nd, ns):
    return list(Y[:nq]), [list(Y[nq + j * ns:nq + (j + 1) * ns]) for j in range(nd)]


def _newton_matrix(model, P, S, xs, vs, As, u, hg, PP0, PP1):
    """The Newton matrix of the damper unknowns (s_j, F_j) and the damper Jacobians, as the kernel assembles them."""
    nd, ns = len(S), model.ns
    m = nd * (ns + 1)
    K = [[0.0] * m for _ in range(m)]
    Jd = []
    for j in range(nd):
        J = model.partials(P[j], tuple(S[j]), xs[j], vs[j], As[j], u[j])
        Jd.append(J)
        b = j * ns
        f = nd * ns + j
        for i in range(ns):
            for k in range(ns):
                K[b + i][b + k] = -hg * J[i][k]
            K[b + i][b + i] = K[b + i][b + i] + 1.0
            K[f][b + i] = -J[ns][i]
            for k in range(nd):
                K[b + i][nd * ns + k] = -hg * (J[i][ns] * PP0[j][k] + J[i][ns + 1] * PP1[j][k])
        for k in range(nd):
            K[f][nd * ns + k] = -(J[ns][ns] * PP0[j][k] + J[ns][ns + 1] * PP1[j][k])
        K[f][f] = K[f][f] + 1.0
    return K, [[list(row) for row in J] for J in Jd]


def _residual(model, P, S, Rs, Fz, xs, vs, As, u, hg):
    nd, ns = len(S), model.ns
    r = [None] * (nd * (ns + 1))
    for j in range(nd):
        g = model.rhs(P[j], tuple(S[j]), xs[j], vs[j], u[j])
        for i in range(ns):
            r[j * ns + i] = -(S[j][i] - Rs[j][i] - hg * g[i])
        r[nd * ns + j] = -(Fz[j] - model.force(P[j], tuple(S[j]), xs[j], vs[j], As[j], u[j]))
    return r


def _stroke(xbar, PP, Fz):
    out = []
    for j in range(len(xbar)):
        x = xbar[j]
        for k in range(len(Fz)):
            x = x + PP[j][k] * Fz[k]
        out.append(x)
    return out


def solve_stage(model, lv, P, R, u, w, hg, S, Fz, atol, rtol, reuse, work):
    """The exact scheme's stage equation Z = R + hγ f(Z) with the plant eliminated (the kernel's ``solve_stage``).
    ``S``: the damper states' guess (list per damper), ``Fz`` the forces' guess. Returns (ok, q, S, Fz, work)."""
    C, D, Ainv, Bbar, Mq, PP = lv
    nd, ns = len(S), model.ns
    nq = Ainv.shape[0]
    Rq, Rs = _split(R, nq, nd, ns)
    A_, B_, M_ = _rows(Ainv), _rows(Bbar), _rows(Mq)
    PP0, PP1 = _rows(PP[0]), _rows(PP[1])
    qbar = _mv(B_, w, _mv(A_, Rq))
    xbar, vbar, As = kinematics(C, D, qbar, w)

    def update(S, Fz, r):
        S = [[S[j][i] + r[j * ns + i] for i in range(ns)] for j in range(nd)]
        Fz = [Fz[j] + r[nd * ns + j] for j in range(nd)]
        return S, Fz

    def body(c):
        it, S, Fz, K, piv, Jd, fresh, prev, state = c
        xs, vs = _stroke(xbar, PP0, Fz), _stroke(vbar, PP1, Fz)
        Kn, Jn = _newton_matrix(model, P, S, xs, vs, As, u, hg, PP0, PP1)
        LUn, pivn, okf = lu_factor(Kn)
        sel = lambda old, new: [[jnp.where(fresh, a, b) for a, b in zip(ro, rn)] for ro, rn in zip(old, new)]  # noqa: E731
        K = sel(K, LUn)
        piv = [jnp.where(fresh, a, b) for a, b in zip(piv, pivn)]
        Jd = [sel(Jo, Jnew) for Jo, Jnew in zip(Jd, Jn)]
        factor_failed = ~fresh & ~okf
        r = lu_solve(K, piv, _residual(model, P, S, Rs, Fz, xs, vs, As, u, hg))
        S, Fz = update(S, Fz, r)
        err = jnp.asarray(0.0)
        for j in range(nd):
            for i in range(ns):
                err = _max(err, jnp.abs(r[j * ns + i]) / (atol + rtol * jnp.abs(S[j][i])))
        dq = _mv(M_, r[nd * ns:])
        for i in range(nq):
            err = _max(err, jnp.abs(dq[i]) / (atol + rtol * jnp.abs(qbar[i])))
        finite = jnp.isfinite(err)
        state = jnp.where(factor_failed | ~finite, 2, jnp.where(err <= 1.0, 1, 0))
        fresh = ~((err > 0.25 * prev) | (it % 4 == 3))
        return it + 1, S, Fz, K, piv, Jd, fresh, err, state

    K0 = _rows(work.K)
    piv0 = [work.piv[i] for i in range(work.piv.shape[0])]
    Jd0 = [_rows(work.Jd[j]) for j in range(nd)]
    init = (jnp.asarray(0), S, Fz, K0, piv0, Jd0, jnp.asarray(reuse), jnp.asarray(jnp.inf), jnp.asarray(0))
    it, S, Fz, K, piv, Jd, _, _, state = lax.while_loop(lambda c: (c[-1] == 0) & (c[0] < MAX_ITER), body, init)
    work = work._replace(K=jnp.asarray(K), piv=jnp.stack(piv).astype(jnp.int32),
                         Jd=jnp.stack([jnp.asarray(J) for J in Jd]))
    return state == 1, _mv(M_, Fz, qbar), S, Fz, work


def sdirk_step(model, lv, P, lag, cmds, Y, u0, Fz, w0, w1, tau0, h, H, atol, rtol, level, work):
    """The exact scheme's SDIRK2 step of length h from τ0 inside the macro step of length H (the kernel's
    ``sdirk_step``). ``cmds`` = (va, vb, ts) per damper. Returns (ok, error estimate, Y, Fz, work)."""
    C, D, Ainv, Bbar, Mq, PP = lv
    nd, ns = len(Fz), model.ns
    nq = Ainv.shape[0]
    va, vb, ts = cmds
    hg = h * GAMMA
    reuse = work.level == level
    work = work._replace(level=jnp.asarray(level, jnp.int32))
    Yq, Ys = _split(Y, nq, nd, ns)
    # stage 1 at τ0 + γh, from an explicit Euler prediction of the damper states
    tau = tau0 + GAMMA * h
    w = _interpolate(w0, w1, tau0 / H)
    xs, vs, _ = kinematics(C, D, Yq, w)
    S1 = []
    for j in range(nd):
        g = model.rhs(P[j], tuple(Ys[j]), xs[j], vs[j], u0[j])
        S1.append([Ys[j][i] + hg * g[i] for i in range(ns)])
    u1 = [lag_value(u0[j], va[j], vb[j], ts[j], lag[j][0], lag[j][1], tau) for j in range(nd)]
    w = _interpolate(w0, w1, tau / H)
    ok1, q1, S1, F1, work = solve_stage(model, lv, P, Y, u1, w, hg, S1, list(Fz), NEWTON_TOL * atol,
                                        NEWTON_TOL * rtol, reuse, work)
    Z1 = q1 + [s for Sj in S1 for s in Sj]
    # stage 2 at τ0 + h (stiffly accurate: the step's result), from stage 1's slope carried on
    tau = tau0 + h
    f1 = [(Z1[i] - Y[i]) / hg for i in range(len(Y))]
    R = [Y[i] + h * (1.0 - GAMMA) * f1[i] for i in range(len(Y))]
    Z2g = [Y[i] + h * f1[i] for i in range(len(Y))]
    F2 = [Fz[j] + (F1[j] - Fz[j]) / GAMMA for j in range(nd)]
    u2 = [lag_value(u0[j], va[j], vb[j], ts[j], lag[j][0], lag[j][1], tau) for j in range(nd)]
    w = _interpolate(w0, w1, tau / H)
    _, S2g = _split(Z2g, nq, nd, ns)
    ok2, q2, S2, F2, work = solve_stage(model, lv, P, R, u2, w, hg, S2g, F2, NEWTON_TOL * atol, NEWTON_TOL * rtol,
                                        True, work)
    Z2 = q2 + [s for Sj in S2 for s in Sj]
    ok = ok1 & ok2
    err = jnp.asarray(0.0)
    # the filtered local error estimate (SDIRK2 minus the embedded solution, through the last Newton matrix)
    est = [Z2[i] - (Y[i] + h * f1[i]) for i in range(len(Y))]
    eq0 = _mv(_rows(Ainv), est[:nq])
    ex0, ev0, _ = kinematics(C, D[:, :, :0], eq0, [])
    r = [None] * (nd * (ns + 1))
    for j in range(nd):
        J = work.Jd[j]
        for i in range(ns):
            r[j * ns + i] = est[nq + j * ns + i] + hg * (J[i, ns] * ex0[j] + J[i, ns + 1] * ev0[j])
        r[nd * ns + j] = J[ns, ns] * ex0[j] + J[ns, ns + 1] * ev0[j]
    r = lu_solve(_rows(work.K), [work.piv[i] for i in range(work.piv.shape[0])], r)
    eq = _mv(_rows(Mq), r[nd * ns:], eq0)
    for i in range(nq):
        err = _max(err, jnp.abs(eq[i]) / (atol + rtol * jnp.maximum(jnp.abs(Y[i]), jnp.abs(Z2[i]))))
    for j in range(nd):
        for i in range(ns):
            o = nq + j * ns + i
            err = _max(err, jnp.abs(r[j * ns + i]) / (atol + rtol * jnp.maximum(jnp.abs(Y[o]), jnp.abs(Z2[o]))))
    work = work._replace(level=jnp.where(ok, work.level, -1))
    # the result back into the invariant set (z within ±z_s); discrete modes (the acceleration branch) switch here,
    # from the stroke rate at the step's end, as in the kernel
    xs, vs, _ = kinematics(C, D, Z2[:nq], w)
    Zq, Zs = _split(Z2, nq, nd, ns)
    Zs = [list(model.project(P[j], tuple(Zs[j]), xs[j], vs[j], u2[j])) for j in range(nd)]
    Ynew = Zq + [s for Sj in Zs for s in Sj]
    return ok, jnp.where(ok, err, jnp.inf), Ynew, F2, work


def _end_forces_lists(model, C, D, P, Y, U, w):
    """:func:`end_forces` on lists of scalars, every sum in the kernel's order (the exact scheme)."""
    nd, ns = len(U), model.ns
    nq = C.shape[2]
    Yq, Ys = _split(Y, nq, nd, ns)
    xs, vs, As = kinematics(C, D, Yq, w)
    F = [model.force(P[j], tuple(Ys[j]), xs[j], vs[j], As[j], U[j]) for j in range(nd)]
    finite = jnp.asarray(True)
    for v in list(F) + list(Y):
        finite = finite & jnp.isfinite(v)
    return F, finite


def _level_plant(plant: Plant, level):
    return Plant(plant.C, plant.D, plant.Ainv[level], plant.Bbar[level], plant.Mq[level], plant.PP[level])


def _macro_step_exact(model, plant: Plant, P, lag, cmds, Y, U, Fz, w0, w1, dt, atol, rtol, nsub, work, max_level):
    """The exact scheme's macro step on lists of scalars (:func:`macro_step`)."""
    nd = len(U)
    va, vb, ts = cmds
    level0 = sum((jnp.maximum(nsub, 1) >= 2 ** k).astype(jnp.int32) for k in range(1, max_level + 1))

    def sub_body(c):
        sidx, level, Yc, Fc, worst, ok, wk = c
        h = dt / (2.0 ** level)
        good, err, Yn, Fn, wk = sdirk_step(model, _level_plant(plant, level), P, lag, cmds, Yc, U, Fc, w0, w1,
                                           sidx * h, h, dt, atol, rtol, level, wk)
        Yc = [jnp.where(good, a, b) for a, b in zip(Yn, Yc)]
        Fc = [jnp.where(good, a, b) for a, b in zip(Fn, Fc)]
        return sidx + 1, level, Yc, Fc, jnp.where(good & (err > worst), err, worst), ok & good, wk

    def try_body(c):
        level, _, _, _, _, _, wk = c
        init = (jnp.asarray(0), level, list(Y), list(Fz), jnp.asarray(0.0), jnp.asarray(True), wk)
        _, _, Yc, Fc, worst, ok, wk = lax.while_loop(lambda s: s[5] & (s[0] < 2 ** s[1]), sub_body, init)
        accept = ok & ((worst <= 1.0) | (level >= max_level))
        fail = ~accept & (level >= max_level)
        status = jnp.where(accept, 1, jnp.where(fail, 2, 0))
        return jnp.where(status == 0, level + 1, level), Yc, Fc, worst, ok, status, wk

    init = (level0, list(Y), list(Fz), jnp.asarray(0.0), jnp.asarray(True), jnp.asarray(0), work)
    level, Yc, Fc, worst, _, status, work = lax.while_loop(lambda c: c[5] == 0, try_body, init)
    failed = status == 2
    Unew = [lag_value(U[j], va[j], vb[j], ts[j], lag[j][0], lag[j][1], dt) for j in range(nd)]
    Fnew, finite = _end_forces_lists(model, plant.C, plant.D, P, Yc, Unew, w1)
    status = jnp.where(failed, NO_CONVERGENCE, jnp.where(finite, OK, NONFINITE))
    keep = lambda new, old: [jnp.where(failed, b, a) for a, b in zip(new, old)]  # noqa: E731
    used = jnp.left_shift(1, level)
    nsub_next = jnp.where((level > 0) & (8.0 * worst < 0.8), used // 2, used)
    return status, keep(Yc, Y), keep(Unew, U), keep(Fnew, Fz), used, nsub_next, work


# --- the differentiable scheme: arrays over the dampers -------------------------------------------------------
def _columns(S):
    """An (nd, ns) array of damper states as the tuple of its ns columns (nd,), the models' ``s``."""
    return tuple(S[:, i] for i in range(S.shape[1]))


def _over_dampers(fn):
    """A damper model's function of one damper's scalars applied to every damper at once (the leading axis of
    each argument: P (nd, n_params), the states' columns, strokes, rates, commands)."""
    return jax.vmap(fn)


def _kinematics(C, Dw, q):
    """Strokes, stroke rates and accelerations (nd,) of the dampers at q (nq,), the input's part Dw = D·w (3, nd)
    given (a step's inputs are interpolated: so are their products, made once per step)."""
    return C[0] @ q + Dw[0], C[1] @ q + Dw[1], Dw[2]


def _solve_dominant(M, b):
    """x of M x = b for one small system, M (n, n) and b (n,) arrays, by Gaussian elimination without pivoting:
    for the differentiable scheme's force system, I − diag(α) P_x − diag(β) P_v, which stays within a few percent of
    the identity (the dampers' stiffness and damping times the plant's compliance over hγ: measured on every plant,
    a diagonal of 1.003–1.05 and off-diagonal rows summing to at most 6.4 % of it, ``tests/jax/test_jax_twin.py``),
    so diagonally dominant, where elimination without pivoting is stable. Partial pivoting's row selections cost a
    third of the full car's step."""
    n = b.shape[0]
    A = [[M[i, k] for k in range(n)] for i in range(n)]
    x = [b[i] for i in range(n)]
    for k in range(n):
        for i in range(k + 1, n):
            f = A[i][k] / A[k][k]
            for c in range(k + 1, n):
                A[i][c] = A[i][c] - f * A[k][c]
            x[i] = x[i] - f * x[k]
    for i in range(n - 1, -1, -1):
        for c in range(i + 1, n):
            x[i] = x[i] - A[i][c] * x[c]
        x[i] = x[i] / A[i][i]
    return jnp.stack(x)


def _newton_update(model, P, S, Fz, xbar, vbar, As, u, Rs, hg, PP0, PP1):
    """One full Newton iteration of a stage for every damper at once: the kernel's system in the unknowns
    (s_j, F_j) reduced by block elimination. Each damper's state rows (I − hγ ∂g/∂s) Δs_j − hγ (∂g/∂x e_x,j +
    ∂g/∂ẋ e_v,j) = r_s,j, with e_x = P_x ΔF and e_v = P_v ΔF the strokes' and rates' responses to the forces,
    give Δs_j = a0_j + hγ (a_x,j e_x,j + a_v,j e_v,j) from that damper's own ns × ns block; its force row then
    leaves ΔF − α ⊙ e_x − β ⊙ e_v = r_F + ∂F/∂s · a0, nd × nd. The same Newton step as the whole m × m matrix's,
    up to rounding."""
    ns = model.ns
    xs, vs = xbar + PP0 @ Fz, vbar + PP1 @ Fz
    s = _columns(S)
    J = _over_dampers(model.partials)(P, s, xs, vs, As, u)  # J[r][c] (nd,): rows ṡ then F, columns s, x, ẋ
    g = _over_dampers(model.rhs)(P, s, xs, vs, u)
    F = _over_dampers(model.force)(P, s, xs, vs, As, u)
    r_s = [-(s[i] - Rs[:, i] - hg * g[i]) for i in range(ns)]
    r_F = -(Fz - F)
    # each damper's own block A = I − hγ ∂g/∂s, elementwise over the dampers
    A = [[(1.0 if i == k else 0.0) - hg * J[i][k] for k in range(ns)] for i in range(ns)]
    LU, piv, _ = lu_factor(A)
    a0 = lu_solve(LU, piv, r_s)
    ax = lu_solve(LU, piv, [J[i][ns] for i in range(ns)])
    av = lu_solve(LU, piv, [J[i][ns + 1] for i in range(ns)])
    alpha, beta, r = J[ns][ns], J[ns][ns + 1], r_F
    for i in range(ns):
        alpha = alpha + hg * J[ns][i] * ax[i]
        beta = beta + hg * J[ns][i] * av[i]
        r = r + J[ns][i] * a0[i]
    nd = Fz.shape[0]
    dF = _solve_dominant(jnp.eye(nd) - alpha[:, None] * PP0 - beta[:, None] * PP1, r)
    ex, ev = PP0 @ dF, PP1 @ dF
    dS = [a0[i] + hg * (ax[i] * ex + av[i] * ev) for i in range(ns)]
    return (S + jnp.stack(dS, axis=1) if ns else S), Fz + dF


def _stage(model, lv, P, Rq, Rs, u, inputs, hg, S, Fz, newton_iterations):
    """The differentiable scheme's stage equation Z = R + hγ f(Z): ``newton_iterations`` full Newton iterations
    from the guess (S (nd, ns), Fz (nd,)); ``inputs`` = (D·w, B̄·w) at the stage's time. Returns (q, S, Fz)."""
    C, _, Ainv, _, Mq, PP = lv
    Dw, Bw = inputs
    qbar = Ainv @ Rq + Bw
    xbar, vbar, As = _kinematics(C, Dw, qbar)
    for _ in range(newton_iterations):
        S, Fz = _newton_update(model, P, S, Fz, xbar, vbar, As, u, Rs, hg, PP[0], PP[1])
    return qbar + Mq @ Fz, S, Fz


def _sdirk_step(model, lv, P, lag, cmds, Y, u0, Fz, inputs, tau0, h, H, newton_iterations):
    """The differentiable scheme's SDIRK2 step of length h from τ0 inside the macro step of length H, on arrays
    (:func:`sdirk_step`'s equations without its error estimate); ``inputs(f)`` = (D·w, B̄·w) at the fraction f of
    the macro step. Returns (Y, Fz)."""
    C, Ainv = lv.C, lv.Ainv
    nq, nd, ns = Ainv.shape[0], Fz.shape[0], model.ns
    va, vb, ts = cmds
    hg = h * GAMMA
    Yq, Ys = Y[:nq], Y[nq:].reshape(nd, ns)
    # stage 1 at τ0 + γh, from an explicit Euler prediction of the damper states
    tau = tau0 + GAMMA * h
    xs, vs, _ = _kinematics(C, inputs(tau0 / H)[0], Yq)
    g = _over_dampers(model.rhs)(P, _columns(Ys), xs, vs, u0)
    S1 = Ys + hg * jnp.stack(g, axis=1) if ns else Ys
    u1 = lag_value(u0, va, vb, ts, lag[:, 0], lag[:, 1], tau)
    q1, S1, F1 = _stage(model, lv, P, Yq, Ys, u1, inputs(tau / H), hg, S1, Fz, newton_iterations)
    # stage 2 at τ0 + h (stiffly accurate: the step's result), from stage 1's slope carried on
    tau = tau0 + h
    f1 = (jnp.concatenate([q1, S1.reshape(-1)]) - Y) / hg
    R = Y + h * (1.0 - GAMMA) * f1
    S2 = (Y + h * f1)[nq:].reshape(nd, ns)
    F2 = Fz + (F1 - Fz) / GAMMA
    u2 = lag_value(u0, va, vb, ts, lag[:, 0], lag[:, 1], tau)
    at2 = inputs(tau / H)
    q2, S2, F2 = _stage(model, lv, P, R[:nq], R[nq:].reshape(nd, ns), u2, at2, hg, S2, F2, newton_iterations)
    # back into the invariant set; discrete modes switch from the stroke rate at the step's end (as the kernel)
    xs, vs, _ = _kinematics(C, at2[0], q2)
    S2 = jnp.stack(_over_dampers(model.project)(P, _columns(S2), xs, vs, u2), axis=1) if ns else S2
    return jnp.concatenate([q2, S2.reshape(-1)]), F2


def end_forces(model, C, D, P, Y, U, w, *, exact: bool = False):
    """The forces (nd,) at the state Y (n,), effective commands U (nd,) and input w (nw,); and whether everything
    is finite. ``exact``: every sum in the kernel's order (the exact scheme's)."""
    if exact:
        F, finite = _end_forces_lists(model, C, D, P, list(Y), list(U), list(w))
        return jnp.stack(F), finite
    return _forces(model, C, D @ w, P, Y, U)


def _forces(model, C, Dw, P, Y, U):
    """:func:`end_forces` (differentiable scheme) with the input's part Dw = D·w (3, nd) given."""
    nq, nd = C.shape[2], U.shape[0]
    xs, vs, As = _kinematics(C, Dw, Y[:nq])
    with fast_power():
        F = _over_dampers(model.force)(P, _columns(Y[nq:].reshape(nd, model.ns)), xs, vs, As, U)
    return F, jnp.all(jnp.isfinite(F)) & jnp.all(jnp.isfinite(Y))


def macro_step(model, plant: Plant, P, lag, cmds, Y, U, Fz, w0, w1, dt, atol, rtol, nsub, work, *, exact: bool,
               max_level: int, substeps: int = 1, newton_iterations: int = 2):
    """Advance one system by ``dt`` (inputs w0 → w1, delayed commands ``cmds``), the kernel's ``macro_step``.

    Arrays: Y (n,), U (nd,), Fz (nd,), w0 and w1 (nw,), P (nd, n_params), lag (nd, 2) the lag rates (rise, fall),
    ``cmds`` = (va, vb, ts), each (nd,); ``nsub`` the sub-steps to start with and ``work`` the carried Newton
    matrix (exact scheme; ``None`` for the differentiable one). Returns (status, Y, U, Fz, sub-steps used,
    sub-steps to start the next step with, work)."""
    if exact:
        nd = U.shape[0]
        status, Yc, Un, Fn, used, nsub_next, work = _macro_step_exact(
            model, plant, P, [[lag[j, 0], lag[j, 1]] for j in range(nd)], tuple(list(c) for c in cmds), list(Y),
            list(U), list(Fz), list(w0), list(w1), dt, atol, rtol, nsub, work, max_level)
        return status, jnp.stack(Yc), jnp.stack(Un), jnp.stack(Fn), used, nsub_next, work
    va, vb, ts = cmds
    level = max(0, int(round(math.log2(substeps))))
    h = dt / substeps
    lv = _level_plant(plant, level)
    # the inputs' products at the step's ends, interpolated inside it as the inputs are
    Dw0, Dw1 = plant.D @ w0, plant.D @ w1
    Bw0, Bw1 = lv.Bbar @ w0, lv.Bbar @ w1

    def inputs(f):
        return Dw0 + (Dw1 - Dw0) * f, Bw0 + (Bw1 - Bw0) * f

    Yc, Fc = Y, Fz
    with fast_power():
        for sidx in range(substeps):
            Yc, Fc = _sdirk_step(model, lv, P, lag, cmds, Yc, U, Fc, inputs, sidx * h, h, dt, newton_iterations)
        Unew = lag_value(U, va, vb, ts, lag[:, 0], lag[:, 1], dt)
        Fnew, finite = _forces(model, plant.C, Dw1, P, Yc, Unew)
    status = jnp.where(finite, OK, NONFINITE)
    used = jnp.asarray(substeps)
    return status, Yc, Unew, Fnew, used, used, work
