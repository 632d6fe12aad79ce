"""The project's stepping scheme in JAX (:mod:`mrd_env.stepping`, ``_kernel_template.py``), for one system; vmap
batches it.

Alexander's two-stage SDIRK with the linear plant eliminated, Newton on each damper's internal states and force,
the command lag integrated exactly. Two schemes:

* ``exact``: the kernel's step as it is: Newton with its stop rule (corrections below ``NEWTON_TOL`` of the
  tolerance), its matrix reuse (the Newton matrix carried between the stages and the steps of a control period,
  refreshed when convergence slows), the filtered error estimate and 2^k sub-steps on demand (``while_loop``s). It
  matches the numba kernel to rounding; forward-mode differentiable only (no reverse mode through ``while_loop``),
  and a vmapped batch waits for its slowest member.
* ``differentiable``: a fixed amount of work per step: ``substeps`` sub-steps (a power of two, default 1), each
  the same two stages with ``newton_iterations`` full Newton iterations (default 2, the Jacobian refreshed at each)
  and no error control: straight-line code that reverse mode goes through.

Both work on arrays, so that under ``vmap`` every operation is one array operation over the batch and the dampers
and the cost hardly grows with the plant's size: the plant's vectors and eliminated matrices as matrix products
(the inputs' products made once per step and interpolated inside it, as the inputs are), every damper's functions
at once over the damper axis (``vmap`` of the model's), and the Newton system of the unknowns (s_j, F_j) reduced by
block elimination (:func:`_newton_solve`): each damper's internal states eliminated by its own ns × ns block, which
leaves the nd × nd force system (I − diag(α) P_x − diag(β) P_v) ΔF = r. The same Newton steps as the kernel's
factorised m × m matrix (m = dampers × (states + 1)), up to rounding. What keeps the exact scheme within rounding
of the kernel is its sums (:data:`KERNEL_SUMS`): the plant's products accumulated in the kernel's order and the
inputs interpolated before they are multiplied, as the kernel does (with matrix products instead, its records
differ from the kernel's by up to 5·10⁻¹³ of a state's peak instead of 5·10⁻¹⁴; the Newton solve's own rounding
changes nothing measurable, since Newton converges to the same stage solution whatever the path's last digits).
The differentiable scheme uses matrix products (:data:`MATRIX_SUMS`), the inputs' products made once per step.
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from ..stepping._kernel_template import MAX_ITER, NEWTON_TOL
from ..stepping.scheme import GAMMA, NO_CONVERGENCE, NONFINITE, OK
from .dampers import fast_power
from .linalg import lu_factor, lu_solve

__all__ = ["Plant", "Work", "lag_value", "delay_split", "macro_step", "end_forces", "empty_work", "force_system", "OK",
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
    """What the exact scheme keeps of its Newton matrix between the stages and steps of a control period: the
    damper Jacobians it was made from (``J[r][c]`` (nd,), :func:`_jacobian`) and the sub-step level it was made for
    (−1: none). The
    matrix is a function of them (and of the level's plant), so it is made again from them where the kernel reuses
    its factors: the same matrix, the same Newton steps."""
    J: tuple
    level: jnp.ndarray


def empty_work(nd: int, ns: int) -> Work:
    return Work(tuple(tuple(jnp.zeros(nd) for _ in range(ns + 2)) for _ in range(ns + 1)), jnp.asarray(-1, jnp.int32))


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


# --- the pieces both schemes share ------------------------------------------------------------------------------
def _columns(S):
    """An (nd, ns) array of damper states as the tuple of its ns columns (nd,), the models' ``s``."""
    return tuple(S[:, i] for i in range(S.shape[1]))


class Sums(NamedTuple):
    """How a scheme forms the plant's linear algebra: ``mv(M, v, start)`` = start + M v (start optional),
    ``inputs(D, Bbar, w0, w1)`` → a function of the fraction f of the step giving the input there, in the form
    ``kinematics(C, D, inp, q)`` (strokes, stroke rates and accelerations (nd,) at q) and ``qbar(Ainv, Bbar, Rq,
    inp)`` (= Ainv R_q + B̄ w) take."""
    mv: Callable
    inputs: Callable
    kinematics: Callable
    qbar: Callable


def _ordered_mv(M, v, start=None):
    """start + M v accumulated over v's entries in order, as the kernel's loops (vectorised over M's rows)."""
    acc = start
    for k in range(v.shape[0]):
        acc = M[..., k] * v[k] if acc is None else acc + M[..., k] * v[k]
    return jnp.zeros(M.shape[:-1]) if acc is None else acc


#: The exact scheme's sums: the kernel's order (C q then D w in one accumulator, A⁻¹ R_q then B̄ w), the inputs
#: interpolated before the products.
KERNEL_SUMS = Sums(
    mv=_ordered_mv,
    inputs=lambda D, Bbar, w0, w1: lambda f: w0 + (w1 - w0) * f,
    kinematics=lambda C, D, w, q: (_ordered_mv(D[0], w, _ordered_mv(C[0], q)),
                                   _ordered_mv(D[1], w, _ordered_mv(C[1], q)), _ordered_mv(D[2], w)),
    qbar=lambda Ainv, Bbar, Rq, w: _ordered_mv(Bbar, w, _ordered_mv(Ainv, Rq)))


def _products(D, Bbar, w0, w1):
    """inputs(f) = (D w, B̄ w) at the fraction f of a step from w0 to w1, the products made at its ends (B̄ w
    None without B̄)."""
    Dw0, Dw1 = D @ w0, D @ w1
    if Bbar is None:
        return lambda f: (Dw0 + (Dw1 - Dw0) * f, None)
    Bw0, Bw1 = Bbar @ w0, Bbar @ w1
    return lambda f: (Dw0 + (Dw1 - Dw0) * f, Bw0 + (Bw1 - Bw0) * f)


#: The differentiable scheme's sums: matrix products, the inputs' products made once per step and interpolated.
MATRIX_SUMS = Sums(
    mv=lambda M, v, start=None: M @ v if start is None else start + M @ v,
    inputs=_products,
    kinematics=lambda C, D, inp, q: (C[0] @ q + inp[0][0], C[1] @ q + inp[0][1], inp[0][2]),
    qbar=lambda Ainv, Bbar, Rq, inp: Ainv @ Rq + inp[1])


def param_columns(P):
    """The dampers' parameters P (nd, n_params) as the tuple of its columns (nd,), which the models index
    (``p[k]``); a tuple is returned as it is. Split once per step rather than indexed at every use: a traced
    array index is two operations each time, a quarter of a step's program, which tracing and differentiating
    pay for (the step's results are the same to the bit)."""
    return P if isinstance(P, tuple) else tuple(P[:, i] for i in range(P.shape[1]))


def _over_dampers(fn):
    """A damper model's function of one damper's scalars applied to every damper at once (the leading axis of
    each argument: P's columns (:func:`param_columns`), the states' columns, strokes, rates, commands)."""
    return jax.vmap(fn)


def _jacobian(model, P, S, xs, vs, As, u):
    """The dampers' Jacobians of (ṡ, F) with respect to (s, x, ẋ), the kernel's ``Jd``, as rows of columns:
    ``J[r][c]`` (nd,), rows ṡ then F, columns s, then x, then ẋ (kept apart: stacking them would copy them)."""
    J = _over_dampers(model.partials)(P, _columns(S), xs, vs, As, u)
    return tuple(tuple(jnp.broadcast_to(c, xs.shape) for c in row) for row in J)


def _residual(model, P, S, Rs, Fz, xs, vs, As, u, hg):
    """The damper equations' residuals, as the kernel's (the right-hand side of the Newton system): each state's
    −(s − R_s − hγ ṡ) (nd, ns) and each force's −(F − φ(s, x, ẋ)) (nd,)."""
    s = _columns(S)
    g = _over_dampers(model.rhs)(P, s, xs, vs, u)
    F = _over_dampers(model.force)(P, s, xs, vs, As, u)
    r_s = -(S - Rs - hg * jnp.stack(g, axis=1)) if S.shape[1] else S
    return r_s, -(Fz - F)


def _solve_in_order(M, b):
    """(x, ok) of M x = b for one small system, M (n, n) and b (n,) arrays, by Gaussian elimination without
    pivoting; ``ok`` False where a pivot is 0 or not finite. For the force system (:func:`force_system`): the
    identity less the dampers' stiffness and damping times the plant's compliance over hγ, whose off-diagonal
    entries are a few percent of the plant's own (P_x, P_v) times the row's damper's α or β. On every plant, over
    the dampers' whole range (states, stroke rates up to 2 m/s, commands, every sub-step level), partial pivoting
    would keep the diagonal at every step, so this is the kernel's own elimination, its row swaps never taken
    (``tests/jax/test_jax_twin.py``; a row can lose its diagonal dominance, where a damper's effective damping β
    turns strongly negative, 10⁻⁴ of the states sampled on the full car, but not its column). Partial pivoting's
    row selections cost a third of the full car's step."""
    n = b.shape[0]
    A = [[M[i, k] for k in range(n)] for i in range(n)]
    x = [b[i] for i in range(n)]
    for k in range(n):
        for i in range(k + 1, n):
            f = A[i][k] / A[k][k]
            for c in range(k + 1, n):
                A[i][c] = A[i][c] - f * A[k][c]
            x[i] = x[i] - f * x[k]
    ok = jnp.asarray(True)
    for i in range(n - 1, -1, -1):
        for c in range(i + 1, n):
            x[i] = x[i] - A[i][c] * x[c]
        x[i] = x[i] / A[i][i]
        ok = ok & (A[i][i] != 0.0) & jnp.isfinite(A[i][i])
    return jnp.stack(x), ok


def _state_blocks(J, hg):
    """Each damper's own block A = I − hγ ∂g/∂s of the Newton matrix made from the dampers' Jacobians J
    (:func:`_jacobian`), factorised (LU with partial pivoting, elementwise over the dampers), and what it leaves of
    the force rows: a_x = A⁻¹ ∂g/∂x, a_v = A⁻¹ ∂g/∂ẋ, α = ∂F/∂x + hγ ∂F/∂s · a_x, β = ∂F/∂ẋ + hγ ∂F/∂s · a_v.
    Returns (LU, pivots, ok, a_x, a_v, α, β)."""
    ns = len(J) - 1
    A = [[(1.0 if i == k else 0.0) - hg * J[i][k] for k in range(ns)] for i in range(ns)]
    LU, piv, ok = lu_factor(A)
    ax = lu_solve(LU, piv, [J[i][ns] for i in range(ns)])
    av = lu_solve(LU, piv, [J[i][ns + 1] for i in range(ns)])
    alpha, beta = J[ns][ns], J[ns][ns + 1]
    for i in range(ns):
        alpha = alpha + hg * J[ns][i] * ax[i]
        beta = beta + hg * J[ns][i] * av[i]
    return LU, piv, jnp.all(ok), ax, av, alpha, beta


def force_system(alpha, beta, PP0, PP1):
    """The dampers' force system I − (α P_x + β P_v) (nd, nd) left by :func:`_state_blocks`, as the kernel writes
    its force block (the same matrix, entry for entry, for models without internal states)."""
    return jnp.eye(PP0.shape[0]) - (alpha[:, None] * PP0 + beta[:, None] * PP1)


def _newton_solve(J, r_s, r_F, hg, PP0, PP1):
    """(Δs (nd, ns), ΔF (nd,), ok) of the Newton system the kernel factorises whole, made from the dampers'
    Jacobians J (:func:`_jacobian`), by block elimination. Each damper's state rows
    (I − hγ ∂g/∂s) Δs_j − hγ (∂g/∂x e_x,j + ∂g/∂ẋ e_v,j) = r_s,j, with e_x = P_x ΔF and e_v = P_v ΔF the strokes'
    and rates' responses to the forces, give Δs_j = a0_j + hγ (a_x,j e_x,j + a_v,j e_v,j) from that damper's own
    ns × ns block (:func:`_state_blocks`); its force row then leaves ΔF − α ⊙ e_x − β ⊙ e_v = r_F + ∂F/∂s · a0,
    nd × nd (:func:`force_system`, :func:`_solve_in_order`). ``ok``: no block singular."""
    ns = r_s.shape[1]
    LU, piv, ok, ax, av, alpha, beta = _state_blocks(J, hg)
    a0 = lu_solve(LU, piv, [r_s[:, i] for i in range(ns)])
    r = r_F
    for i in range(ns):
        r = r + J[ns][i] * a0[i]
    dF, okF = _solve_in_order(force_system(alpha, beta, PP0, PP1), r)
    ex, ev = PP0 @ dF, PP1 @ dF
    dS = jnp.stack([a0[i] + hg * (ax[i] * ex + av[i] * ev) for i in range(ns)], axis=1) if ns else r_s
    return dS, dF, ok & okF


def _forces(sums, model, C, D, inp, P, Y, U):
    """:func:`end_forces` at the input ``inp`` (in the form of ``sums``)."""
    nq, nd = C.shape[2], U.shape[0]
    xs, vs, As = sums.kinematics(C, D, inp, Y[:nq])
    F = _over_dampers(model.force)(P, _columns(Y[nq:].reshape(nd, model.ns)), xs, vs, As, U)
    return F, jnp.all(jnp.isfinite(F)) & jnp.all(jnp.isfinite(Y))


def _worst(e):
    """The largest of the error ratios e, as the kernel's ``if e > err: err = e`` from 0 (a NaN is passed over)."""
    return jnp.max(jnp.where(jnp.isnan(e), 0.0, e), initial=0.0)


def _level_plant(plant: Plant, level):
    return Plant(plant.C, plant.D, plant.Ainv[level], plant.Bbar[level], plant.Mq[level], plant.PP[level])


def _sdirk_step(sums, model, lv, P, lag, cmds, Y, u0, Fz, inputs, tau0, h, H, stage, work):
    """One SDIRK2 step of length h from τ0 inside the macro step of length H (the kernel's ``sdirk_step`` without
    its error estimate and projection): ``inputs(f)`` the input at the fraction f of the macro step (``sums``),
    ``stage(work, lv, Rq, Rs, u, inputs, hg, S, Fz, first)`` a scheme's stage solve returning (ok, q, S, Fz, work),
    ``work`` what it passes on from stage to stage. Returns (ok, Y, Fz, f1, u2, the stage-2 inputs, work)."""
    C = lv.C
    nq, nd, ns = lv.Ainv.shape[0], Fz.shape[0], model.ns
    va, vb, ts = cmds
    hg = h * GAMMA
    Yq, Ys = Y[:nq], Y[nq:].reshape(nd, ns)
    # stage 1 at τ0 + γh, from an explicit Euler prediction of the damper states
    tau = tau0 + GAMMA * h
    xs, vs, _ = sums.kinematics(C, lv.D, inputs(tau0 / H), Yq)
    g = _over_dampers(model.rhs)(P, _columns(Ys), xs, vs, u0)
    S1 = Ys + hg * jnp.stack(g, axis=1) if ns else Ys
    u1 = lag_value(u0, va, vb, ts, lag[:, 0], lag[:, 1], tau)
    ok1, q1, S1, F1, work = stage(work, lv, Yq, Ys, u1, inputs(tau / H), hg, S1, Fz, True)
    # stage 2 at τ0 + h (stiffly accurate: the step's result), from stage 1's slope carried on
    tau = tau0 + h
    f1 = (jnp.concatenate([q1, S1.reshape(-1)]) - Y) / hg
    R = Y + h * (1.0 - GAMMA) * f1
    S2 = (Y + h * f1)[nq:].reshape(nd, ns)
    F2 = Fz + (F1 - Fz) / GAMMA
    u2 = lag_value(u0, va, vb, ts, lag[:, 0], lag[:, 1], tau)
    at2 = inputs(tau / H)
    ok2, q2, S2, F2, work = stage(work, lv, R[:nq], R[nq:].reshape(nd, ns), u2, at2, hg, S2, F2, False)
    return ok1 & ok2, jnp.concatenate([q2, S2.reshape(-1)]), F2, f1, u2, at2, work


def _project(sums, model, C, D, P, Y, u, inp):
    """The step's result back into the models' invariant set (z within ±z_s); discrete modes (the acceleration
    branch) switch here, from the stroke rate at the step's end (the input ``inp``), as in the kernel."""
    nq, nd, ns = C.shape[2], u.shape[0], model.ns
    if not ns:
        return Y
    xs, vs, _ = sums.kinematics(C, D, inp, Y[:nq])
    S = jnp.stack(_over_dampers(model.project)(P, _columns(Y[nq:].reshape(nd, ns)), xs, vs, u), axis=1)
    return jnp.concatenate([Y[:nq], S.reshape(-1)])


# --- the differentiable scheme --------------------------------------------------------------------------------
def _stage_fixed(model, P, newton_iterations):
    """The differentiable scheme's stage solve: ``newton_iterations`` full Newton iterations from the guess."""
    sums = MATRIX_SUMS

    def stage(work, lv, Rq, Rs, u, inp, hg, S, Fz, first):
        C, D, Ainv, Bbar, Mq, PP = lv
        qbar = sums.qbar(Ainv, Bbar, Rq, inp)
        xbar, vbar, As = sums.kinematics(C, D, inp, qbar)
        for _ in range(newton_iterations):
            xs, vs = xbar + PP[0] @ Fz, vbar + PP[1] @ Fz
            r_s, r_F = _residual(model, P, S, Rs, Fz, xs, vs, As, u, hg)
            dS, dF, _ = _newton_solve(_jacobian(model, P, S, xs, vs, As, u), r_s, r_F, hg, PP[0], PP[1])
            S, Fz = S + dS, Fz + dF
        return jnp.asarray(True), qbar + Mq @ Fz, S, Fz, work
    return stage


# --- the exact scheme -----------------------------------------------------------------------------------------
def _stage_exact(model, P, atol, rtol, level, active):
    """The exact scheme's stage solve (the kernel's ``solve_stage``): Newton until its last correction is below
    ``NEWTON_TOL`` of the tolerance on every state (the plant's change is M_q ΔF), at most ``MAX_ITER`` times, the
    Newton matrix made from the Jacobians kept in the :class:`Work` while convergence is fast, from fresh ones when
    a correction shrinks by less than 4 or every fourth iteration. A stage starts from the kept matrix when it was
    made at this ``level`` (the second stage always). Not ``active`` (a system whose result the enclosing loop
    drops): no iteration, so that a vmapped batch does not wait for its Newton iterations."""
    atol, rtol = NEWTON_TOL * atol, NEWTON_TOL * rtol
    sums = KERNEL_SUMS

    def stage(work, lv, Rq, Rs, u, inp, hg, S, Fz, first):
        C, D, Ainv, Bbar, Mq, PP = lv
        qbar = sums.qbar(Ainv, Bbar, Rq, inp)
        xbar, vbar, As = sums.kinematics(C, D, inp, qbar)
        scale_q = atol + rtol * jnp.abs(qbar)

        def body(c):
            it, S, Fz, J, fresh, prev, state = c
            xs, vs = sums.mv(PP[0], Fz, xbar), sums.mv(PP[1], Fz, vbar)
            J = jax.tree_util.tree_map(lambda kept, new: jnp.where(fresh, kept, new), J,
                                       _jacobian(model, P, S, xs, vs, As, u))
            r_s, r_F = _residual(model, P, S, Rs, Fz, xs, vs, As, u, hg)
            dS, dF, okf = _newton_solve(J, r_s, r_F, hg, PP[0], PP[1])
            S, Fz = S + dS, Fz + dF
            err = jnp.maximum(_worst(jnp.abs(dS) / (atol + rtol * jnp.abs(S))),
                              _worst(jnp.abs(sums.mv(Mq, dF)) / scale_q))
            state = jnp.where((~fresh & ~okf) | ~jnp.isfinite(err), 2, jnp.where(err <= 1.0, 1, 0))
            fresh = ~((err > 0.25 * prev) | (it % 4 == 3))
            return it + 1, S, Fz, J, fresh, err, state

        reuse = (work.level == level) if first else jnp.asarray(True)
        init = (jnp.where(active, 0, MAX_ITER), S, Fz, work.J, reuse, jnp.asarray(jnp.inf), jnp.asarray(0))
        _, S, Fz, J, _, _, state = lax.while_loop(lambda c: (c[-1] == 0) & (c[0] < MAX_ITER), body, init)
        return state == 1, sums.mv(Mq, Fz, qbar), S, Fz, Work(J, jnp.asarray(level, jnp.int32))
    return stage


def _sdirk_step_exact(model, lv, P, lag, cmds, Y, u0, Fz, inputs, tau0, h, H, atol, rtol, level, work, active):
    """The exact scheme's SDIRK2 step (the kernel's ``sdirk_step``): the two stages, then the filtered local error
    estimate (SDIRK2 minus the embedded solution, through the last Newton matrix). Returns (ok, error estimate, Y,
    Fz, work); not ``active``: no Newton iterations (:func:`_stage_exact`)."""
    C, Ainv, Mq, PP = lv.C, lv.Ainv, lv.Mq, lv.PP
    nq, nd, ns = Ainv.shape[0], Fz.shape[0], model.ns
    hg = h * GAMMA
    sums = KERNEL_SUMS
    ok, Z2, F2, f1, u2, at2, work = _sdirk_step(sums, model, lv, P, lag, cmds, Y, u0, Fz, inputs, tau0, h, H,
                                                _stage_exact(model, P, atol, rtol, level, active), work)
    est = Z2 - (Y + h * f1)
    eq0 = sums.mv(Ainv, est[:nq])
    ex0, ev0 = sums.mv(C[0], eq0), sums.mv(C[1], eq0)
    J, est_s = work.J, est[nq:].reshape(nd, ns)
    r_s = jnp.stack([est_s[:, i] + hg * (J[i][ns] * ex0 + J[i][ns + 1] * ev0) for i in range(ns)], axis=1) \
        if ns else est_s
    r_F = J[ns][ns] * ex0 + J[ns][ns + 1] * ev0
    dS, dF, _ = _newton_solve(J, r_s, r_F, hg, PP[0], PP[1])
    scale = atol + rtol * jnp.maximum(jnp.abs(Y), jnp.abs(Z2))
    err = jnp.maximum(_worst(jnp.abs(sums.mv(Mq, dF, eq0)) / scale[:nq]),
                      _worst(jnp.abs(dS.reshape(-1)) / scale[nq:]))
    work = Work(work.J, jnp.where(ok, jnp.asarray(level, jnp.int32), -1))
    return ok, jnp.where(ok, err, jnp.inf), _project(sums, model, C, lv.D, P, Z2, u2, at2), F2, work


def _macro_step_exact(model, plant: Plant, P, lag, cmds, Y, U, Fz, w0, w1, dt, atol, rtol, nsub, work, max_level):
    """The exact scheme's macro step (:func:`macro_step`): sub-steps of dt/2^k, k from the last step's, doubled
    until every sub-step converges and the largest error estimate is within the tolerance (or k is the largest).

    Under ``vmap`` a loop runs until its last system is done, and the body runs for every system, the results of
    those already done dropped: a system that is done starts no inner loop and no Newton iteration, so that a
    batch's cost per step is its slowest system's, not the product of every loop's slowest."""
    level0 = sum((jnp.maximum(nsub, 1) >= 2 ** k).astype(jnp.int32) for k in range(1, max_level + 1))
    inputs = KERNEL_SUMS.inputs(plant.D, None, w0, w1)

    def sub_body(c):
        sidx, level, Yc, Fc, worst, ok, wk = c
        h = dt / (2.0 ** level)
        lv = _level_plant(plant, level)
        active = ok & (sidx < 2 ** level)
        good, err, Yn, Fn, wk = _sdirk_step_exact(model, lv, P, lag, cmds, Yc, U, Fc, inputs, sidx * h, h, dt,
                                                  atol, rtol, level, wk, active)
        Yc, Fc = jnp.where(good, Yn, Yc), jnp.where(good, Fn, Fc)
        return sidx + 1, level, Yc, Fc, jnp.where(good & (err > worst), err, worst), ok & good, wk

    def try_body(c):
        level, _, _, _, _, status, wk = c
        first = jnp.where(status == 0, 0, 2 ** level)  # a system already accepted: no sub-step
        init = (first, level, Y, Fz, jnp.asarray(0.0), jnp.asarray(True), wk)
        _, _, Yc, Fc, worst, ok, wk = lax.while_loop(lambda s: s[5] & (s[0] < 2 ** s[1]), sub_body, init)
        accept = ok & ((worst <= 1.0) | (level >= max_level))
        fail = ~accept & (level >= max_level)
        status = jnp.where(accept, 1, jnp.where(fail, 2, 0))
        return jnp.where(status == 0, level + 1, level), Yc, Fc, worst, ok, status, wk

    init = (level0, Y, Fz, jnp.asarray(0.0), jnp.asarray(True), jnp.asarray(0), work)
    level, Yc, Fc, worst, _, status, work = lax.while_loop(lambda c: c[5] == 0, try_body, init)
    used = jnp.left_shift(1, level)
    nsub_next = jnp.where((level > 0) & (8.0 * worst < 0.8), used // 2, used)
    return status == 2, Yc, Fc, used, nsub_next, work


# --- the macro step ---------------------------------------------------------------------------------------------
def end_forces(model, C, D, P, Y, U, w, *, exact: bool = False):
    """The forces (nd,) at the state Y (n,), effective commands U (nd,) and input w (nw,); and whether everything
    is finite. ``exact``: the models' general exponent by pow, as the kernel (else :func:`~.dampers.fast_power`)."""
    P = param_columns(P)
    if exact:
        return _forces(KERNEL_SUMS, model, C, D, w, P, Y, U)
    with fast_power():
        return _forces(MATRIX_SUMS, model, C, D, MATRIX_SUMS.inputs(D, None, w, w)(1.0), P, Y, U)


def macro_step(model, plant: Plant, P, lag, cmds, Y, U, Fz, w0, w1, dt, atol, rtol, nsub, work, *, exact: bool,
               max_level: int, substeps: int = 1, newton_iterations: int = 2):
    """Advance one system by ``dt`` (inputs w0 → w1, delayed commands ``cmds``), the kernel's ``macro_step``.

    Arrays: Y (n,), U (nd,), Fz (nd,), w0 and w1 (nw,), P (nd, n_params) or its :func:`param_columns` (split once
    outside a loop of steps), lag (nd, 2) the lag rates (rise, fall),
    ``cmds`` = (va, vb, ts), each (nd,); ``nsub`` the sub-steps to start with and ``work`` the kept Newton matrix
    (exact scheme; ``None`` for the differentiable one). Returns (status, Y, U, Fz, sub-steps used, sub-steps to
    start the next step with, work)."""
    va, vb, ts = cmds
    P = param_columns(P)
    Unew = lag_value(U, va, vb, ts, lag[:, 0], lag[:, 1], dt)
    if exact:
        failed, Yc, Fc, used, nsub_next, work = _macro_step_exact(model, plant, P, lag, cmds, Y, U, Fz, w0, w1, dt,
                                                                  atol, rtol, nsub, work, max_level)
        Fnew, finite = _forces(KERNEL_SUMS, model, plant.C, plant.D, w1, P, Yc, Unew)
        status = jnp.where(failed, NO_CONVERGENCE, jnp.where(finite, OK, NONFINITE))
        keep = lambda new, old: jnp.where(failed, old, new)  # noqa: E731
        return status, keep(Yc, Y), keep(Unew, U), keep(Fnew, Fz), used, nsub_next, work
    level = max(0, int(round(math.log2(substeps))))
    h = dt / substeps
    lv = _level_plant(plant, level)
    sums = MATRIX_SUMS
    inputs = sums.inputs(plant.D, lv.Bbar, w0, w1)
    stage = _stage_fixed(model, P, newton_iterations)
    Yc, Fc = Y, Fz
    with fast_power():
        for sidx in range(substeps):
            _, Yc, Fc, _, u2, at2, _ = _sdirk_step(sums, model, lv, P, lag, cmds, Yc, U, Fc, inputs, sidx * h, h,
                                                   dt, stage, None)
            Yc = _project(sums, model, lv.C, lv.D, P, Yc, u2, at2)
        Fnew, finite = _forces(sums, model, plant.C, plant.D, inputs(1.0), P, Yc, Unew)
    status = jnp.where(finite, OK, NONFINITE)
    used = jnp.asarray(substeps)
    return status, Yc, Unew, Fnew, used, used, work
