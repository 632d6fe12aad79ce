"""The one fixed-step stepping routine used by the rig, the plants, the environments and identification.

It advances a batch of independent systems, each made of a linear plant coupled to ``nd`` dampers of one
model, on a fixed grid (dt = 1 ms by default)::

    q̇   = A q + B_F F + B_w w(t)                   linear plant (q may be empty: the virtual rig)
    x_j  = C_x q + D_x w,  ẋ_j = C_v q + D_v w,  ẍ_j = D_a w     kinematics across damper j
    ṡ_j  = rhs(p_j, s_j, x_j, ẋ_j, u_j)            damper internal states
    F_j  = force(p_j, s_j, x_j, ẋ_j, ẍ_j, u_j)
    u̇_j  = −η_j (u_j − v_j)                         command lag, v held over each step (zero-order hold)

The command lag is integrated exactly (an exponential). The plant and damper states are advanced together
(no lagged coupling) by the two-stage, stiffly accurate, L-stable SDIRK method of Alexander (1977),
γ = 1 − 1/√2, order 2: the Bouc–Wen variable's Jacobian reaches |∂ż/∂z| ≈ 2(β+γ) z_s |ẋ−ẏ| (≈ 10⁴ s⁻¹
at 0.1 m/s for the prototype damper), which makes explicit schemes unstable at 1 ms. Each stage is solved
by Newton's method with a finite-difference Jacobian; after every step the model's ``project`` puts the
states back in their invariant set (z within ±z_s), which stage values may leave. The exogenous input w
is interpolated linearly inside a step.

Accuracy control: each step of ``dt`` is split into 2^k equal sub-steps. Starting from half the previous
step's count, the count doubles (up to ``max_substeps``) until an a-posteriori estimate of the local error
— the SDIRK solution minus the embedded first-order one, filtered through the stage matrix as in Hairer &
Wanner, *Solving ODEs II*, IV.8 — is within ``rtol``·|state| + ``atol`` for every state (defaults 1e-2
and 1e-5 in SI units with at most 8 sub-steps: force errors below 0.03 % of a Radau reference for the
prototype damper up to 2.4 m/s, see ``tests/test_integrator_accuracy.py``). A Newton solve that does not
converge also halves the sub-step. The output grid stays fixed at ``dt`` whatever the splitting, and the
splitting depends only on the state, so runs are reproducible bit for bit.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

GAMMA = 1.0 - 1.0 / math.sqrt(2.0)

OK = 0
NONFINITE = 1
NO_CONVERGENCE = 2


@nb.njit(cache=True)
def _lu_factor(M, piv):
    """In-place LU with partial pivoting; returns False if M is singular."""
    n = M.shape[0]
    for k in range(n):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if big == 0.0 or not math.isfinite(big):
            return False
        piv[k] = p
        if p != k:
            for c in range(n):
                tmp = M[k, c]
                M[k, c] = M[p, c]
                M[p, c] = tmp
        for i in range(k + 1, n):
            M[i, k] /= M[k, k]
            f = M[i, k]
            if f != 0.0:
                for c in range(k + 1, n):
                    M[i, c] -= f * M[k, c]
    return True


@nb.njit(cache=True)
def _lu_solve(M, piv, b):
    n = M.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        for k in range(i):
            b[i] -= M[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            b[i] -= M[i, k] * b[k]
        b[i] /= M[i, i]


def _build_kernel(rhs, force, project, ns):
    """The stepping routine specialised for one model: its numba functions and ``ns`` internal states
    are compile-time constants of these closures (so numba inlines them and caches per model)."""

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
            if err > 0.25 * prev:
                fresh = False  # slow contraction: the Jacobian is stale (a kink was crossed)
            prev = err
        return False


    @nb.njit(cache=True)
    def _sdirk_step(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, Y, u0, v, eta,
                    w0, w1, tau0, h, H, atol, rtol, max_iter, ws, F, f1, fz, ftmp, G, M, piv, R, Z1, Z2, est,
                    u1, u2):
        """One SDIRK2 step of length h starting at τ0 (relative to the macro step of length H).

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
        if not _solve_stage(nq, nd, A, BF, Bw, Cx, Dx, Cv, Dv, Da, P, R, u1, ws, hg,
                            Z1, F, fz, ftmp, G, M, piv, 1e-3 * atol, 1e-3 * rtol, max_iter, False):
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
        # stage values may leave the invariant set (z beyond ±z_s) but the step's result must not
        for j in range(nd):
            o = nq + j * ns
            project(P[j], Y[o:o + ns], u2[j])
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
        for b in range(N):
            nsub = 1
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
                                                max_iter, ws, F, f1, fz, ftmp, G, M, piv, R, Z1, Z2, est, u1, u2)
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



    return advance


_KERNELS: dict = {}


def kernel_for(model_cls):
    """The compiled :func:`advance` for a damper model class (built once per process)."""
    k = _KERNELS.get(model_cls)
    if k is None:
        k = _KERNELS[model_cls] = _build_kernel(model_cls.rhs, model_cls.force, model_cls.project,
                                                len(model_cls.state_names))
    return k


class SystemMatrices:
    """The linear part of a coupled system (see the module docstring); empty plant for the rig.

    Shapes: A (nq, nq), BF (nq, nd), Bw (nq, nw), Cx/Cv (nd, nq), Dx/Dv/Da (nd, nw).
    """

    def __init__(self, nd: int, nw: int, A=None, BF=None, Bw=None, Cx=None, Dx=None, Cv=None, Dv=None, Da=None):
        nq = 0 if A is None else np.asarray(A).shape[0]

        def mat(a, shape):
            out = np.zeros(shape) if a is None else np.ascontiguousarray(a, dtype=np.float64)
            if out.shape != shape:
                raise ValueError(f"system matrix has shape {out.shape}, expected {shape}")
            return out

        self.nq, self.nd, self.nw = nq, nd, nw
        self.A = mat(A, (nq, nq))
        self.BF = mat(BF, (nq, nd))
        self.Bw = mat(Bw, (nq, nw))
        self.Cx = mat(Cx, (nd, nq))
        self.Dx = mat(Dx, (nd, nw))
        self.Cv = mat(Cv, (nd, nq))
        self.Dv = mat(Dv, (nd, nw))
        self.Da = mat(Da, (nd, nw))

    @classmethod
    def displacement_driven(cls) -> "SystemMatrices":
        """The virtual rig: no plant, one damper whose x, ẋ, ẍ are the inputs w = (x, ẋ, ẍ)."""
        e = np.eye(3)
        return cls(nd=1, nw=3, Dx=e[0:1], Dv=e[1:2], Da=e[2:3])


class Stepper:
    """Preallocated stepping of a batch of N systems for ``n_steps`` steps per call (environments).

    Holds the states ``Y`` (N, n) and effective commands ``U`` (N, nd); :meth:`step` advances them and
    returns the per-step forces (N, n_steps, nd) and states (N, n_steps, n) as views of internal buffers
    (copy them to keep them past the next call).
    """

    def __init__(self, damper, system: SystemMatrices, N: int, n_steps: int, dt: float, *, P=None,
                 max_substeps: int = 8, rtol: float = 1e-2, atol: float = 1e-5):
        from .validation import check_scalar

        self.damper = damper
        self.system = system
        self.dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
        self.max_substeps = int(check_scalar("max_substeps", max_substeps, 1, 4096))
        self.rtol = check_scalar("rtol", rtol, 0.0, lo_open=True)
        self.atol = check_scalar("atol", atol, 0.0, lo_open=True)
        nd = system.nd
        n = system.nq + nd * damper.n_states
        p = damper.params.as_array()
        self.P = np.ascontiguousarray(np.broadcast_to(p, (N, nd, p.size)) if P is None else P, dtype=np.float64)
        self.eta = np.full((N, nd), damper.command.eta)
        self.Y = np.zeros((N, n))
        self.U = np.zeros((N, nd))
        self.F_out = np.zeros((N, n_steps, nd))
        self.Y_out = np.zeros((N, n_steps, n))
        self.nsub = np.zeros((N, n_steps), dtype=np.int64)
        self._kernel = kernel_for(type(damper))
        s = system
        self._mats = (s.A, s.BF, s.Bw, s.Cx, s.Dx, s.Cv, s.Dv, s.Da)
        self.t = 0.0

    def step(self, V: np.ndarray, W: np.ndarray):
        """Advance by ``V.shape[1]`` steps with commands V (N, n_steps, nd) and inputs W (N, n_steps+1, nw)."""
        status, b, k = self._kernel(*self._mats, self.P, self.eta, self.Y, self.U, V, W, self.dt,
                                    self.max_substeps, self.rtol, self.atol, self.F_out, self.Y_out, self.nsub)
        if status != OK:
            self._fail(status, b, k)
        self.t += V.shape[1] * self.dt
        return self.F_out, self.Y_out

    def _fail(self, status, b, k):
        from .errors import SimulationDivergedError

        t_fail = self.t + (k + 1) * self.dt
        name = self.damper.name
        why = ("a non-finite state" if status == NONFINITE else
               f"no convergence of the implicit step even with {self.max_substeps} sub-steps")
        raise SimulationDivergedError(
            f"damper model {name!r}: {why} at t = {t_fail:.6g} s (batch index {b}); "
            "check the parameters and the input amplitude", model=name, time=t_fail, index=b)


def run(damper, system: SystemMatrices, Y, U, V, W, dt: float, *, t0: float = 0.0, P=None,
        max_substeps: int = 8, rtol: float = 1e-2, atol: float = 1e-5):
    """Advance a batch once (see :class:`Stepper`), raising :class:`SimulationDivergedError` on failure.

    ``damper`` is a :class:`~mrd_env.dampers.DamperModel`; Y (N, n) and U (N, nd) are updated in place;
    V (N, n_steps, nd) commands, W (N, n_steps + 1, nw) inputs; ``P`` overrides the parameter vector per
    system and damper (N, nd, n_params). Returns (F (N, n_steps, nd), Y history (N, n_steps, n),
    sub-steps used (N, n_steps)).
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    W = np.ascontiguousarray(W, dtype=np.float64)
    N, n_steps, nd = V.shape
    if W.shape[:2] != (N, n_steps + 1):
        raise ValueError(f"W must have shape (N, n_steps + 1, nw) = ({N}, {n_steps + 1}, nw), got {W.shape}")
    st = Stepper(damper, system, N, n_steps, dt, P=P, max_substeps=max_substeps, rtol=rtol, atol=atol)
    if Y.shape != st.Y.shape or U.shape != st.U.shape:
        raise ValueError(f"Y and U must have shapes {st.Y.shape} and {st.U.shape}, got {Y.shape} and {U.shape}")
    st.Y, st.U, st.t = Y, U, t0
    st.step(V, W)
    return st.F_out, st.Y_out, st.nsub
