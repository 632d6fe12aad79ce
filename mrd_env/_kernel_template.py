"""Template of the compiled stepping routine (see :mod:`mrd_env.integrator`).

Not imported as such: :func:`mrd_env.integrator.kernel_for` writes, for each damper model, a module made of
a short header binding ``rhs``, ``force``, ``project`` (the model's numba functions) and ``ns`` (its number of
internal states) followed by this text. Each model thus gets its own module-level kernel with those
functions as compile-time constants, and numba can cache it on disk across processes.
"""
import math

import numba as nb
import numpy as np

from mrd_env.integrator import GAMMA, NO_CONVERGENCE, NONFINITE, OK, _lu_factor, _lu_solve


@nb.njit(cache=True)
def _eval(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Y, u, w, F, dY):
    """F_j and dY/dt at state Y, effective commands u and input w."""
    for j in range(nd):
        x = 0.0
        xd = 0.0
        xdd = 0.0
        for i in range(nq):
            x += Cx[j, i] * Y[i]
            xd += Cv[j, i] * Y[i]
        for m in range(w.shape[0]):
            x += Dx[j, m] * w[m]
            xd += Dv[j, m] * w[m]
            xdd += Da[j, m] * w[m]
        o = nq + j * ns
        s = Y[o:o + ns]
        F[j] = force(P[j], s, x, xd, xdd, u[j])
        rhs(P[j], s, x, xd, u[j], dY[o:o + ns])
    for i in range(nq):
        acc = 0.0
        for k in range(nq):
            acc += A[i, k] * Y[k]
        for j in range(nd):
            acc += BF[i, j] * F[j]
        for m in range(w.shape[0]):
            acc += Bw[i, m] * w[m]
        dY[i] = acc


@nb.njit(cache=True)
def _stage_matrix(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Z, u, w, hg,
                  F, f0, ftmp, M, piv):
    """M = I − hγ ∂f/∂Y at Z (finite differences), LU-factorised in place."""
    n = Z.shape[0]
    _eval(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Z, u, w, F, f0)
    for c in range(n):
        zc = Z[c]
        d = 1.0e-7 * max(abs(zc), 1.0e-3)
        Z[c] = zc + d
        _eval(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Z, u, w, F, ftmp)
        Z[c] = zc
        for r in range(n):
            M[r, c] = -hg * (ftmp[r] - f0[r]) / d
        M[c, c] += 1.0
    return _lu_factor(M, piv)


@nb.njit(cache=True)
def _solve_stage(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, R, u, w, hg,
                 Z, F, fz, ftmp, G, M, piv, atol, rtol, max_iter, reuse):
    """Solve Z = R + hγ f(Z) by Newton's method (Jacobian refreshed while convergence is slow).

    ``reuse``: start from the factorised matrix already in M (both stages share I − hγJ)."""
    n = Z.shape[0]
    fresh = reuse
    prev = math.inf
    for it in range(max_iter):
        if not fresh:
            if not _stage_matrix(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Z, u, w, hg,
                                 F, fz, ftmp, M, piv):
                return False
            fresh = True
        else:
            _eval(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Z, u, w, F, fz)
        for i in range(n):
            G[i] = -(Z[i] - R[i] - hg * fz[i])
        _lu_solve(M, piv, G)
        err = 0.0
        for i in range(n):
            Z[i] += G[i]
            e = abs(G[i]) / (atol + rtol * abs(Z[i]))
            if e > err:
                err = e
        if not math.isfinite(err):
            return False
        if err <= 1.0:
            return True
        if err > 0.25 * prev or it % 4 == 3:
            fresh = False  # slow contraction (a kink was crossed) or a stale Jacobian: refresh it
        prev = err
    return False


@nb.njit(cache=True)
def _sdirk_step(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Y, u0, v, eta,
                w0, w1, tau0, h, H, atol, rtol, max_iter, ws, F, f1, fz, ftmp, G, M, piv, R, Z1, Z2, est,
                u1, u2, Mh):
    """One SDIRK2 step of length h starting at τ0 (relative to the macro step of length H).

    ``Mh[0]`` is the step length M was last factorised for: a matrix from an earlier step of the same
    length starts the Newton iterations (refreshed as soon as convergence slows).
    Returns (converged, error estimate in units of the tolerance). Y is updated only on success.
    """
    n = Y.shape[0]
    hg = h * GAMMA
    # stage 1 at τ0 + γh
    t1 = tau0 + GAMMA * h
    for m in range(w0.shape[0]):
        ws[m] = w0[m] + (w1[m] - w0[m]) * (t1 / H)
    for j in range(nd):
        u1[j] = v[j] + (u0[j] - v[j]) * math.exp(-eta[j] * t1)
    for i in range(n):
        R[i] = Y[i]
        Z1[i] = Y[i]
    reuse = Mh[0] == h
    Mh[0] = h
    if not _solve_stage(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, R, u1, ws, hg,
                        Z1, F, fz, ftmp, G, M, piv, 1e-3 * atol, 1e-3 * rtol, max_iter, reuse):
        Mh[0] = 0.0
        return False, math.inf
    for i in range(n):
        f1[i] = (Z1[i] - Y[i]) / hg  # stage derivative without re-evaluating f (exact for stiff parts)
    # stage 2 at τ0 + h (stiffly accurate: its value is the step's result)
    t2 = tau0 + h
    for m in range(w0.shape[0]):
        ws[m] = w0[m] + (w1[m] - w0[m]) * (t2 / H)
    for j in range(nd):
        u2[j] = v[j] + (u0[j] - v[j]) * math.exp(-eta[j] * t2)
    for i in range(n):
        R[i] = Y[i] + h * (1.0 - GAMMA) * f1[i]
        Z2[i] = Z1[i]
    if not _solve_stage(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, R, u2, ws, hg,
                        Z2, F, fz, ftmp, G, M, piv, 1e-3 * atol, 1e-3 * rtol, max_iter, True):
        Mh[0] = 0.0
        return False, math.inf
    # local error: SDIRK2 minus the embedded backward-Euler-like solution Y + h f(Z1),
    # filtered by (I − hγJ)^-1 so that it stays bounded for the stiff components
    for i in range(n):
        est[i] = Z2[i] - (Y[i] + h * f1[i])
    _lu_solve(M, piv, est)
    err = 0.0
    for i in range(n):
        e = abs(est[i]) / (atol + rtol * max(abs(Y[i]), abs(Z2[i])))
        if e > err:
            err = e
        Y[i] = Z2[i]
    # stage values may leave the invariant set (z beyond ±z_s) but the step's result must not; discrete
    # modes (a branch chosen by the sign of the acceleration) switch here, between steps
    for j in range(nd):
        x = 0.0
        xd = 0.0
        for i in range(nq):
            x += Cx[j, i] * Y[i]
            xd += Cv[j, i] * Y[i]
        for m in range(ws.shape[0]):  # ws holds the input at the step's end (stage 2)
            x += Dx[j, m] * ws[m]
            xd += Dv[j, m] * ws[m]
        o = nq + j * ns
        project(P[j], Y[o:o + ns], x, xd, u2[j])
    return True, err


@nb.njit(cache=True)
def advance(A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, eta, Y, U, V, W, dt,
            max_substeps, rtol, atol, F_out, Y_out, nsub_out):
    """Advance a batch of systems over ``V.shape[1]`` steps of ``dt``.

    Shapes: P (N, nd, n_params), eta (N, nd), Y (N, n) with n = nq + nd·ns, U (N, nd) effective
    commands, V (N, n_steps, nd) commands held over each step, W (N, n_steps + 1, nw) inputs at the grid
    points. Y and U are updated in place; F_out (N, n_steps, nd) and Y_out (N, n_steps, n) receive the
    force and state at the end of every step, nsub_out (N, n_steps) the sub-steps used.

    Returns (status, system index, step index): status 0 = ok, 1 = non-finite state, 2 = Newton failed
    even at the smallest sub-step.
    """
    N = Y.shape[0]
    n = Y.shape[1]
    nq = A.shape[0]
    nd = V.shape[2]
    nw = W.shape[2]
    n_steps = V.shape[1]
    nmax = max(n, nd, 1)
    F = np.zeros(max(nd, 1))
    f1 = np.zeros(nmax)
    fz = np.zeros(nmax)
    ftmp = np.zeros(nmax)
    G = np.zeros(nmax)
    R = np.zeros(nmax)
    Z1 = np.zeros(nmax)
    Z2 = np.zeros(nmax)
    est = np.zeros(nmax)
    u1 = np.zeros(max(nd, 1))
    u2 = np.zeros(max(nd, 1))
    M = np.zeros((n, n))
    piv = np.zeros(n, dtype=np.int64)
    ws = np.zeros(nw)
    Ysave = np.zeros(n)
    u0 = np.zeros(nd)
    max_iter = 12
    Mh = np.zeros(1)
    for b in range(N):
        nsub = 1
        Mh[0] = 0.0
        for k in range(n_steps):
            for i in range(n):
                Ysave[i] = Y[b, i]
            for j in range(nd):
                u0[j] = U[b, j]
            w0 = W[b, k]
            w1 = W[b, k + 1]
            vk = V[b, k]
            etab = eta[b]
            # start from half the previous splitting so the step count can come back down
            nsub = max(1, nsub // 2)
            while True:
                h = dt / nsub
                ok = True
                worst = 0.0
                for i in range(n):
                    Y[b, i] = Ysave[i]
                for sidx in range(nsub):
                    if n == 0:
                        break
                    # sub-steps restart the command lag from its exact value at their start
                    good, err = _sdirk_step(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da,
                                            P[b], Y[b], u0, vk, etab, w0, w1, sidx * h, h, dt, atol, rtol,
                                            max_iter, ws, F, f1, fz, ftmp, G, M, piv, R, Z1, Z2, est, u1, u2, Mh)
                    if not good:
                        ok = False
                        break
                    if err > worst:
                        worst = err
                if ok and (worst <= 1.0 or nsub >= max_substeps):
                    break
                if nsub >= max_substeps:
                    for i in range(n):
                        Y[b, i] = Ysave[i]
                    return NO_CONVERGENCE, b, k
                nsub *= 2
            # exact command lag over the whole step
            for j in range(nd):
                U[b, j] = vk[j] + (u0[j] - vk[j]) * math.exp(-etab[j] * dt)
            _eval(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P[b], Y[b], U[b], w1, F, fz)
            for j in range(nd):
                F_out[b, k, j] = F[j]
                if not math.isfinite(F[j]):
                    return NONFINITE, b, k
            for i in range(n):
                Y_out[b, k, i] = Y[b, i]
                if not math.isfinite(Y[b, i]):
                    return NONFINITE, b, k
            nsub_out[b, k] = nsub
    return OK, -1, -1
