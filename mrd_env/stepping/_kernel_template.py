"""Template of the compiled stepping routine (see :mod:`mrd_env.stepping`).

Not imported as such: :func:`mrd_env.stepping.codegen.kernel_module` writes, for each damper model, a module made
of a short header binding ``rhs``, ``force``, ``project`` (the model's numba functions, compiled again inline),
``partials`` (the model's analytic derivatives, or :func:`fd_partials` below) and ``ns`` (its number of internal
states) — the names this file imports from :mod:`mrd_env.stepping.injected` — followed by this text and the
driver's (``_driver_template.py``). Each model thus gets its own module-level kernel with those functions as
compile-time constants, and numba can cache it on disk across processes.

The stage equations Z = R + hγ f(Z) are solved with the linear plant eliminated (see :mod:`mrd_env.stepping`):
the unknowns are each damper's internal states s_j and its force F_j, nd·(ns + 1) of them.

Conventions of the arrays passed down (everything is inlined into one function per driver, and a call with
more than 30 arguments cannot be inlined, hence the stacking):

* C (2, nd, nq) = [C_x, C_v]; D (3, nd, nw) = [D_x, D_v, D_a]; per sub-step level: Ainv (nq, nq) = (I − hγA)⁻¹,
  Bbar (nq, nw) = hγ Ainv B_w, Mq (nq, nd) = hγ Ainv B_F, PP (2, nd, nd) = [C_x Mq, C_v Mq].
* Jd (nd, ns + 1, ns + 2): per damper, the Jacobian of (ṡ, F) with respect to (s, x, ẋ), rows 0..ns−1 for
  g = ṡ and row ns for F, columns 0..ns−1 for s, then x, then ẋ (what ``partials`` writes).
* lag (nd, 3): per damper η_rise, η_fall and the delay τ (:mod:`mrd_env.command_lag`); over a step the delayed
  command is va up to ts, then vb (rows VD_VA, VD_VB, VD_TS of Vd, :mod:`mrd_env.stepping.layout`).
* scratch: Vn (7, max(n, m)) vectors of the state length (and the Newton residual), Vd (13, nd) of the damper
  count, Vx (4, L) short vectors (q̄, ṡ, finite-difference work, the input inside a step), K (m, m) the Newton
  matrix, Iw (m + 1) its pivots and the level it was factorised for.
"""
import math

import numba as nb

from mrd_env.command_lag import delay_split as _delay_split_dispatcher, lag_value as _lag_value_dispatcher
from mrd_env.stepping.injected import force, ns, partials, project, rhs  # injected
from mrd_env.stepping.layout import VD_TS, VD_VA, VD_VB, PlantArrays, Workspace
from mrd_env.stepping.matrices import lu_factor as _lu_factor_dispatcher, lu_solve as _lu_solve_dispatcher
from mrd_env.stepping.scheme import GAMMA, NO_CONVERGENCE, NONFINITE, OK

# compiled again inline: the Newton loop makes no calls
_lu_factor = nb.njit(inline='always')(_lu_factor_dispatcher.py_func)
_lu_solve = nb.njit(inline='always')(_lu_solve_dispatcher.py_func)
_lag_value = nb.njit(inline='always')(_lag_value_dispatcher.py_func)
_delay_split = nb.njit(inline='always')(_delay_split_dispatcher.py_func)

NEWTON_TOL = 1e-2  # Newton stops when its last correction is below this fraction of the error tolerance
MAX_ITER = 12

# The entry points here and in the driver are compiled without numba's reference counting (``_nrt=False``): they
# allocate nothing (the scratch is the caller's), and with it every view of an array (Vn[0], Z[o:o + ns], ...) costs
# an atomic increment and decrement of its owner's count — half of the step's time
# (experiments/scripts/bench_physics_step).


@nb.njit(cache=True, _nrt=False)
def workspace_len(nq, nd, n, nw):
    """(floats, ints) needed by :func:`workspace_views`."""
    m = max(nd * (ns + 1), 1)
    L1 = max(n, m)
    L = max(nw, 2 * ns + 2, nq, 1)
    return 7 * L1 + 13 * nd + 4 * L + m * m + nd * (ns + 1) * (ns + 2), m + 1


@nb.njit(inline='always')
def workspace_views(wf, wi, nq, nd, n, nw):
    """The :class:`~mrd_env.stepping.layout.Workspace` (Vn, Vd, Vx, K, Iw, Jd) of one system's step as views of
    the scratch buffers wf, wi (see the module docstring); the scratch is allocated once, by the caller."""
    m = max(nd * (ns + 1), 1)
    L1 = max(n, m)
    L = max(nw, 2 * ns + 2, nq, 1)
    o = 0
    Vn = wf[o:o + 7 * L1].reshape((7, L1))
    o += 7 * L1
    Vd = wf[o:o + 13 * nd].reshape((13, nd))
    o += 13 * nd
    Vx = wf[o:o + 4 * L].reshape((4, L))
    o += 4 * L
    K = wf[o:o + m * m].reshape((m, m))
    o += m * m
    Jd = wf[o:o + nd * (ns + 1) * (ns + 2)].reshape((nd, ns + 1, ns + 2))
    return Workspace(Vn, Vd, Vx, K, wi[:m + 1], Jd)


@nb.njit(inline='always')
def fd_partials(p, s, x, xd, xdd, u, J, work):
    """The Jacobian J (ns + 1, ns + 2) of (ṡ, F) with respect to (s, x, ẋ) of one damper by forward differences
    (models without analytic ``partials``). ``work`` holds at least 2·ns values."""
    g0 = work[0:ns]
    g1 = work[ns:2 * ns]
    F0 = force(p, s, x, xd, xdd, u)
    rhs(p, s, x, xd, u, g0)
    for c in range(ns + 2):
        # column c: perturb state c, then x, then ẋ (one call site of each function keeps the kernel small)
        xc = x
        vc = xd
        if c < ns:
            sc = s[c]
            d = 1.0e-7 * max(abs(sc), 1.0e-3)
            s[c] = sc + d
        elif c == ns:
            d = 1.0e-7 * max(abs(x), 1.0e-3)
            xc = x + d
        else:
            d = 1.0e-7 * max(abs(xd), 1.0e-3)
            vc = xd + d
        F1 = force(p, s, xc, vc, xdd, u)
        rhs(p, s, xc, vc, u, g1)
        if c < ns:
            s[c] = sc
        J[ns, c] = (F1 - F0) / d
        for k in range(ns):
            J[k, c] = (g1[k] - g0[k]) / d


@nb.njit(inline='always')
def kinematics(C, D, q, w, xs, vs, As):
    """Damper strokes x_j, velocities ẋ_j and accelerations ẍ_j from plant coordinates q and inputs w."""
    nd = C.shape[1]
    nq = C.shape[2]
    for j in range(nd):
        x = 0.0
        v = 0.0
        a = 0.0
        for i in range(nq):
            x += C[0, j, i] * q[i]
            v += C[1, j, i] * q[i]
        for m in range(w.shape[0]):
            x += D[0, j, m] * w[m]
            v += D[1, j, m] * w[m]
            a += D[2, j, m] * w[m]
        xs[j] = x
        vs[j] = v
        As[j] = a


@nb.njit(inline='always')
def solve_stage(lv, P, R, u, w, hg, Z, Fz, atol, rtol, reuse, ws):
    """Solve the stage equation Z = R + hγ f(Z) with the plant eliminated (``lv``: the plant's matrices at this
    sub-step level, ``ws``: the workspace); Fz holds the forces (guess in, solution out). ``reuse``: start from
    the factorised Newton matrix already in K (the two stages of a step share it). Returns False if Newton's
    method does not converge."""
    C, D, Ainv, Bbar, Mq, PP = lv
    Vn, Vd, Vx, K, Iw, Jd = ws
    nd = C.shape[1]
    nq = C.shape[2]
    m = nd * (ns + 1)
    piv = Iw[:m]
    r = Vn[6]
    qbar = Vx[0]
    g = Vx[1]
    work = Vx[2]
    xbar = Vd[0]
    vbar = Vd[1]
    xs = Vd[2]
    vs = Vd[3]
    As = Vd[4]
    # the plant part, linear: q = q̄ + M_q F with q̄ = (I − hγA)⁻¹ R_q + hγ(I − hγA)⁻¹ B_w w
    for i in range(nq):
        acc = 0.0
        for k in range(nq):
            acc += Ainv[i, k] * R[k]
        for k in range(w.shape[0]):
            acc += Bbar[i, k] * w[k]
        qbar[i] = acc
    kinematics(C, D, qbar, w, xbar, vbar, As)
    fresh = reuse
    prev = math.inf
    for it in range(MAX_ITER):
        for j in range(nd):
            x = xbar[j]
            v = vbar[j]
            for k in range(nd):
                x += PP[0, j, k] * Fz[k]
                v += PP[1, j, k] * Fz[k]
            xs[j] = x
            vs[j] = v
        if not fresh:
            for i in range(m):
                for k in range(m):
                    K[i, k] = 0.0
            for j in range(nd):
                o = nq + j * ns
                J = Jd[j]
                partials(P[j], Z[o:o + ns], xs[j], vs[j], As[j], u[j], J, work)
                b = j * ns
                f = nd * ns + j
                for i in range(ns):
                    for k in range(ns):
                        K[b + i, b + k] = -hg * J[i, k]
                    K[b + i, b + i] += 1.0
                    K[f, b + i] = -J[ns, i]
                    for k in range(nd):
                        K[b + i, nd * ns + k] = -hg * (J[i, ns] * PP[0, j, k] + J[i, ns + 1] * PP[1, j, k])
                for k in range(nd):
                    K[f, nd * ns + k] = -(J[ns, ns] * PP[0, j, k] + J[ns, ns + 1] * PP[1, j, k])
                K[f, f] += 1.0
            if not _lu_factor(K, piv):
                return False
            fresh = True
        # residuals of the damper equations: s − R_s − hγ g(s, x, ẋ), F − φ(s, x, ẋ)
        for j in range(nd):
            o = nq + j * ns
            s = Z[o:o + ns]
            rhs(P[j], s, xs[j], vs[j], u[j], g)
            for i in range(ns):
                r[j * ns + i] = -(s[i] - R[o + i] - hg * g[i])
            r[nd * ns + j] = -(Fz[j] - force(P[j], s, xs[j], vs[j], As[j], u[j]))
        _lu_solve(K, piv, r)
        # convergence on every state: the plant's change is M_q ΔF
        err = 0.0
        for j in range(nd):
            o = nq + j * ns
            for i in range(ns):
                Z[o + i] += r[j * ns + i]
                e = abs(r[j * ns + i]) / (atol + rtol * abs(Z[o + i]))
                if e > err:
                    err = e
            Fz[j] += r[nd * ns + j]
        for i in range(nq):
            dq = 0.0
            for k in range(nd):
                dq += Mq[i, k] * r[nd * ns + k]
            e = abs(dq) / (atol + rtol * abs(qbar[i]))
            if e > err:
                err = e
        if not math.isfinite(err):
            return False
        if err <= 1.0:
            for i in range(nq):
                acc = qbar[i]
                for k in range(nd):
                    acc += Mq[i, k] * Fz[k]
                Z[i] = acc
            return True
        if err > 0.25 * prev or it % 4 == 3:
            fresh = False  # slow contraction (a kink was crossed) or a stale Jacobian: refresh it
        prev = err
    return False


@nb.njit(cache=True, _nrt=False)
def sdirk_step(lv, damper, state, w0, w1, tau0, h, control, level, ws):
    """One SDIRK2 step of length h = H/2^level starting at τ0 (relative to the macro step of length
    H = ``control.dt``), with ``lv`` the plant's matrices of this h. The states Y and the force guess Fz of
    ``state`` are updated only on success; the effective commands at the stages follow exactly from U (its
    value at τ = 0, which the macro step updates only at its end) and the delayed commands (Vd rows
    VD_VA..VD_TS).

    The factorised Newton matrix of an earlier step of the same length starts the iterations (refreshed as
    soon as convergence slows). Returns (converged, error estimate in units of the tolerance)."""
    C, D, Ainv, Bbar, Mq, PP = lv
    P, lag = damper
    Y, u0, Fz = state
    H, _, atol, rtol = control
    Vn, Vd, Vx, K, Iw, Jd = ws
    nd = C.shape[1]
    nq = C.shape[2]
    n = Y.shape[0]
    m = nd * (ns + 1)
    hg = h * GAMMA
    Z1 = Vn[0]
    Z2 = Vn[1]
    R = Vn[2]
    f1 = Vn[3]
    est = Vn[4]
    r = Vn[6]
    F1 = Vd[5]
    u1 = Vd[8]
    u2 = Vd[9]
    va = Vd[VD_VA]
    vb = Vd[VD_VB]
    ts = Vd[VD_TS]
    for i in range(n):
        R[i] = Y[i]
        Z1[i] = Y[i]
    for j in range(nd):
        F1[j] = Fz[j]
    reuse = Iw[m] == level
    Iw[m] = level
    for stage in range(2):
        # stage 1 at τ0 + γh; stage 2 at τ0 + h (stiffly accurate: its value is the step's result)
        # Newton starts from a prediction of the stage's damper states and forces: a third fewer iterations
        # than starting from Y (2.3 → 1.6 per stage on the quarter car, class-C road)
        if stage == 0:
            tau = tau0 + GAMMA * h
            Z = Z1
            u = u1
            # an explicit Euler step to τ0 + γh from the slope at the sub-step's start (with the command u0 of the
            # macro step's start: a guess, so the lag over earlier sub-steps is left out)
            w = _interpolate(w0, w1, tau0 / H, Vx[3])
            kinematics(C, D, Y, w, Vd[2], Vd[3], Vd[4])
            g = Vx[1]
            for j in range(nd):
                o = nq + j * ns
                rhs(P[j], Y[o:o + ns], Vd[2, j], Vd[3, j], u0[j], g)
                for i in range(ns):
                    Z1[o + i] = Y[o + i] + hg * g[i]
        else:
            tau = tau0 + h
            Z = Z2
            u = u2
            for i in range(n):
                f1[i] = (Z1[i] - Y[i]) / hg  # stage derivative without re-evaluating f (exact for stiff parts)
                R[i] = Y[i] + h * (1.0 - GAMMA) * f1[i]
                Z2[i] = Y[i] + h * f1[i]  # stage 1's slope carried on to τ0 + h
            for j in range(nd):
                F1[j] = Fz[j] + (F1[j] - Fz[j]) / GAMMA
        for j in range(nd):
            u[j] = _lag_value(u0[j], va[j], vb[j], ts[j], lag[j, 0], lag[j, 1], tau)
        w = _interpolate(w0, w1, tau / H, Vx[3])
        if not solve_stage(lv, P, R, u, w, hg, Z, F1, NEWTON_TOL * atol, NEWTON_TOL * rtol, reuse or stage == 1,
                           ws):
            Iw[m] = -1
            return False, math.inf
    # local error: SDIRK2 minus the embedded backward-Euler-like solution Y + h f(Z1), filtered by
    # (I − hγJ)⁻¹ (Hairer & Wanner IV.8) so that it stays bounded for the stiff components; with the plant
    # eliminated: e_q = (I − hγA)⁻¹ est_q + M_q δF and (e_s, δF) solve the last Newton matrix
    for i in range(n):
        est[i] = Z2[i] - (Y[i] + h * f1[i])
    eq0 = Vx[0]
    ex0 = Vd[2]
    ev0 = Vd[3]
    for i in range(nq):
        acc = 0.0
        for k in range(nq):
            acc += Ainv[i, k] * est[k]
        eq0[i] = acc
    for j in range(nd):
        a = 0.0
        b = 0.0
        for i in range(nq):
            a += C[0, j, i] * eq0[i]
            b += C[1, j, i] * eq0[i]
        ex0[j] = a
        ev0[j] = b
    for j in range(nd):
        o = nq + j * ns
        J = Jd[j]
        for i in range(ns):
            r[j * ns + i] = est[o + i] + hg * (J[i, ns] * ex0[j] + J[i, ns + 1] * ev0[j])
        r[nd * ns + j] = J[ns, ns] * ex0[j] + J[ns, ns + 1] * ev0[j]
    _lu_solve(K, Iw[:m], r)
    err = 0.0
    for i in range(nq):
        e = eq0[i]
        for k in range(nd):
            e += Mq[i, k] * r[nd * ns + k]
        e = abs(e) / (atol + rtol * max(abs(Y[i]), abs(Z2[i])))
        if e > err:
            err = e
    for j in range(nd):
        o = nq + j * ns
        for i in range(ns):
            e = abs(r[j * ns + i]) / (atol + rtol * max(abs(Y[o + i]), abs(Z2[o + i])))
            if e > err:
                err = e
    for i in range(n):
        Y[i] = Z2[i]
    for j in range(nd):
        Fz[j] = F1[j]
    # stage values may leave the invariant set (z beyond ±z_s) but the step's result must not; discrete
    # modes (a branch chosen by the sign of the acceleration) switch here, between steps
    xs = Vd[2]
    vs = Vd[3]
    kinematics(C, D, Y, w, xs, vs, Vd[4])
    for j in range(nd):
        o = nq + j * ns
        project(P[j], Y[o:o + ns], xs[j], vs[j], u2[j])
    return True, err


@nb.njit(inline='always')
def _interpolate(w0, w1, frac, out):
    """w0 + (w1 − w0)·frac in ``out[:len(w0)]`` (the input inside a step, linear)."""
    w = out[:w0.shape[0]]
    for k in range(w0.shape[0]):
        w[k] = w0[k] + (w1[k] - w0[k]) * frac
    return w


@nb.njit(cache=True, _nrt=False)
def macro_step(plant, damper, state, w0, w1, control, nsub, ws):
    """Advance one system by dt = ``control.dt`` (inputs w0 → w1; the delayed commands of the step in rows
    VD_VA..VD_TS of the scratch Vd, see :func:`delayed_commands`), splitting the step into 2^k sub-steps as the
    error estimate asks (k ≤ ``control.max_level``), starting from ``nsub`` sub-steps. ``plant``: the
    :class:`~mrd_env.stepping.layout.PlantArrays` (per level), ``damper``: ``DamperArrays``, ``state``:
    ``SystemState``, ``control``: ``StepControl`` (:mod:`mrd_env.stepping.layout`), ``ws``: the system's
    :func:`workspace_views` (made once per call of the driver: a view costs a numba reshape, ≈ 20 ns).

    The state's Y, U (effective commands) and Fz (forces) are updated in place. Returns (status, sub-steps
    used, sub-steps to start the next step with: half as many when the error estimate says that twice the
    sub-step — eight times the local error of this order-2 method — would still pass, else as many)."""
    C, D, Ainv, Bbar, Mq, PP = plant
    P, lag = damper
    Y, U, Fz = state
    dt, max_level, _, _ = control
    nd = C.shape[1]
    n = Y.shape[0]
    Vd = ws.Vd
    Ysave = ws.Vn[5]
    Fsave = Vd[6]  # (row 7, the commands at the step's start, is free: U itself holds them until the end)
    for i in range(n):
        Ysave[i] = Y[i]
    for j in range(nd):
        Fsave[j] = Fz[j]
    level = 0
    k = max(1, nsub)
    while k > 1:
        k //= 2
        level += 1
    while True:
        m = 1 << level
        h = dt / m
        ok = True
        worst = 0.0
        for i in range(n):
            Y[i] = Ysave[i]
        for j in range(nd):
            Fz[j] = Fsave[j]
        if n > 0:
            for sidx in range(m):
                # sub-steps restart the command lag from its exact value at their start
                lv = PlantArrays(C, D, Ainv[level], Bbar[level], Mq[level], PP[level])
                good, err = sdirk_step(lv, damper, state, w0, w1, sidx * h, h, control, level, ws)
                if not good:
                    ok = False
                    break
                if err > worst:
                    worst = err
        if ok and (worst <= 1.0 or level >= max_level):
            break
        if level >= max_level:
            for i in range(n):
                Y[i] = Ysave[i]
            for j in range(nd):
                Fz[j] = Fsave[j]
            return NO_CONVERGENCE, m, m
        level += 1
    # exact command lag over the whole step, then the forces at its end
    for j in range(nd):
        U[j] = _lag_value(U[j], Vd[VD_VA, j], Vd[VD_VB, j], Vd[VD_TS, j], lag[j, 0], lag[j, 1], dt)
    status = end_forces(C, D, P, Y, U, w1, Fz, Vd)
    used = 1 << level
    return status, used, (used // 2 if (level > 0 and 8.0 * worst < 0.8) else used)


@nb.njit(inline='always')
def end_forces(C, D, P, Y, U, w, Fz, Vd):
    """Forces Fz of one system at its current state and input w; NONFINITE if a state or force is not
    finite."""
    nd = C.shape[1]
    nq = C.shape[2]
    xs = Vd[2]
    vs = Vd[3]
    As = Vd[4]
    kinematics(C, D, Y, w, xs, vs, As)
    for j in range(nd):
        o = nq + j * ns
        Fz[j] = force(P[j], Y[o:o + ns], xs[j], vs[j], As[j], U[j])
        if not math.isfinite(Fz[j]):
            return NONFINITE
    for i in range(Y.shape[0]):
        if not math.isfinite(Y[i]):
            return NONFINITE
    return OK


@nb.njit(inline='always')
def delayed_commands(queue, pos, lag, dt, Vd):
    """The commands of the step (rows VD_VA, VD_VB, VD_TS of Vd: va until ts, then vb) from each damper's queue of past
    commands (Q, nd), the newest at ``pos``, for the delays τ = lag[j, 2] (:mod:`mrd_env.command_lag`)."""
    Q = queue.shape[0]
    for j in range(queue.shape[1]):
        m, s = _delay_split(lag[j, 2], dt)
        Vd[VD_VB, j] = queue[(pos - m) % Q, j]
        Vd[VD_VA, j] = queue[(pos - m - 1) % Q, j]
        Vd[VD_TS, j] = s
