"""Template of the inverses' compiled one-step routines (see :mod:`mrd_env.inverse.observer`).

Not imported as such: :func:`mrd_env.inverse.observer.onestep_module` writes, for each damper model, a module
importing ``macro_step``, ``workspace_views`` and ``ns`` from that model's compiled stepping kernel
(:func:`mrd_env.stepping.codegen.kernel_module`; the ``# injected`` lines below stand for that import) followed by
this text, so that every step below is the project's stepping routine (SDIRK2 with error control, the command lag
integrated exactly) on the virtual rig: no plant, the damper driven by its stroke, velocity and acceleration
w = (x, ẋ, ẍ), interpolated linearly inside the step.

Arguments shared by the functions (the records of :mod:`mrd_env.stepping.layout`): ``plant``, the rig's system
arrays and level matrices (``PlantArrays``, :meth:`mrd_env.stepping.SystemMatrices.levels`); ``damper``, the
parameter vector P (1, n_params) and the command dynamics lag (1, 3) (η_rise, η_fall, τ; the delay τ is not
modelled here) (``DamperArrays``); ``state``, the dampers' internal states Y (N, ns), effective commands U (N, 1)
and forces F (N, 1) (``SystemState``); ``control``, the step dt, the finest sub-step level and the tolerances
(``StepControl``); and scratch buffers wf, wi (one system's workspace).
"""
import math

import numba as nb
import numpy as np

from mrd_env.stepping._kernel_template import macro_step, workspace_views  # injected
from mrd_env.stepping.injected import ns  # injected
from mrd_env.stepping.layout import VD_TS, VD_VA, VD_VB, SystemState


@nb.njit(cache=True)
def advance(plant, damper, state, W, V, x1, v1, control, nsub, wf, wi, status):
    """Advance N dampers by one step with the commands V[b] held, from their motion W[b] = (x, ẋ, ẍ) to the
    measured x1[b], v1[b] (ẍ: the backward difference of the velocities): the state and W in place; status[b]
    is the kernel's (0: OK)."""
    Y, U, F = state
    dt = control.dt
    m = ns + 1
    w1 = np.empty(3)
    ws = workspace_views(wf, wi, plant.C.shape[2], 1, Y.shape[1], plant.D.shape[2])
    Vd = ws.Vd
    for b in range(Y.shape[0]):
        wi[m] = -1  # the Newton matrix of another system is not reused
        hold(Vd, V[b])
        w1[0] = x1[b]
        w1[1] = v1[b]
        w1[2] = (v1[b] - W[b, 1]) / dt
        st, used, nxt = macro_step(plant, damper, SystemState(Y[b], U[b], F[b]), W[b], w1, control, nsub[b], ws)
        nsub[b] = nxt
        status[b] = st
        for i in range(3):
            W[b, i] = w1[i]


@nb.njit(inline='always')
def hold(Vd, v):
    """The command v held over the whole step, in the kernel's rows of the step's commands (before and after
    the switch time, which is 0): the inverses' one-step models leave out the command delay."""
    Vd[VD_VA, 0] = v
    Vd[VD_VB, 0] = v
    Vd[VD_TS, 0] = 0.0


@nb.njit(inline='always')
def extrapolate(w0, dt, w1):
    """w1 = the motion (x, ẋ, ẍ) one step after w0 at constant acceleration."""
    w1[0] = w0[0] + dt * w0[1] + 0.5 * dt * dt * w0[2]
    w1[1] = w0[1] + dt * w0[2]
    w1[2] = w0[2]


@nb.njit(cache=True)
def step_force(plant, damper, state, v, w0, w1, control, wf, wi, scratch):
    """The force at the end of one step from the ``state`` (Y, U, F) of one damper with the command v held and
    the motion w0 → w1, leaving that state unchanged (NaN if the step fails); ``scratch``: a ``SystemState`` of
    the same shapes to step."""
    Y, U, F = state
    Ys, Us, Fs = scratch
    for i in range(Y.shape[0]):
        Ys[i] = Y[i]
    Us[0] = U[0]
    Fs[0] = F[0]
    ws = workspace_views(wf, wi, plant.C.shape[2], 1, Y.shape[0], plant.D.shape[2])
    hold(ws.Vd, v)
    nsub = np.ones(1, dtype=np.int64)  # an int64, not the literal 1: the call then shares the driver's compilation
    wi[ns + 1] = -1
    st, used, nxt = macro_step(plant, damper, scratch, w0, w1, control, nsub[0], ws)
    if st != 0:
        return math.nan
    return Fs[0]


@nb.njit(cache=True)
def nearest_commands(plant, damper, state, W, target, grid, n_refine, control, wf, wi, out, predicted):
    """For each damper b, the command whose force at the end of the next step — the motion extrapolated from
    W[b] at constant acceleration — is nearest ``target[b]``: the forces of
    the ``grid`` commands, then ``n_refine`` Illinois (regula falsi) steps inside the grid interval that brackets
    the target next to the best grid point (none if no interval brackets it: the target is out of reach and the
    best grid command, an end of the range when the force is monotone in the command, is kept)."""
    Y, U, F = state
    K = grid.shape[0]
    scratch = SystemState(np.empty(Y.shape[1]), np.empty(1), np.empty(1))
    Fk = np.empty(K)
    w1 = np.empty(3)
    for b in range(Y.shape[0]):
        f = target[b]
        one = SystemState(Y[b], U[b], F[b])
        extrapolate(W[b], control.dt, w1)
        best = -1
        for k in range(K):
            Fk[k] = step_force(plant, damper, one, grid[k], W[b], w1, control, wf, wi, scratch)
            if math.isfinite(Fk[k]) and (best < 0 or abs(Fk[k] - f) < abs(Fk[best] - f)):
                best = k
        if best < 0:  # every prediction failed: keep the lowest command
            out[b] = grid[0]
            predicted[b] = math.nan
            continue
        c_best = grid[best]
        F_best = Fk[best]
        lo = -1
        for k in (best - 1, best):  # the interval on either side of the best grid point
            if 0 <= k < K - 1 and (Fk[k] - f) * (Fk[k + 1] - f) <= 0.0 and Fk[k] != Fk[k + 1]:
                lo = k
                break
        if lo >= 0:  # Illinois: regula falsi halving the value kept at an end that stays twice in a row
            s, fs = grid[lo], Fk[lo] - f
            t, ft = grid[lo + 1], Fk[lo + 1] - f
            side = 0
            for it in range(n_refine):
                if fs == ft:
                    break
                r = (s * ft - t * fs) / (ft - fs)
                fr = step_force(plant, damper, one, r, W[b], w1, control, wf, wi, scratch)
                if not math.isfinite(fr):
                    break
                if abs(fr - f) < abs(F_best - f):
                    c_best = r
                    F_best = fr
                fr -= f
                if fr * ft > 0.0:
                    t, ft = r, fr
                    if side == -1:
                        fs *= 0.5
                    side = -1
                elif fr * fs > 0.0:
                    s, fs = r, fr
                    if side == 1:
                        ft *= 0.5
                    side = 1
                else:
                    break
        out[b] = c_best
        predicted[b] = F_best


@nb.njit(cache=True)
def step_forces(plant, damper, state, W, W1, V, control, wf, wi, out):
    """out[b, k]: damper b's force at the end of one step with the command V[b, k] held and the motion going
    from W[b] to W1[b], from its current state (left unchanged; NaN where the step fails)."""
    Y, U, F = state
    scratch = SystemState(np.empty(Y.shape[1]), np.empty(1), np.empty(1))
    for b in range(Y.shape[0]):
        one = SystemState(Y[b], U[b], F[b])
        for k in range(V.shape[1]):
            out[b, k] = step_force(plant, damper, one, V[b, k], W[b], W1[b], control, wf, wi, scratch)
