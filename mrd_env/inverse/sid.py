"""Simplified inverse dynamics (SID) of the Bouc–Wen family, after Tsang, Su & Chan (2006), "Simplified inverse
dynamics models for MR fluid dampers", Engineering Structures 28(3), 327–341.

The form implemented, at each control step t_k:

1. **Observer.** The hysteretic state (z; for Spencer–Dyke also the internal displacement y) is estimated online
   by running the model's state equations along the measured stroke and velocity with the commands already sent
   (:class:`~mrd_env.inverse.observer.ObserverInverse`: the project's stepping routine, the command lag
   included), which also gives the effective command u_k.
2. **Force law solved for the effective command**, at the observed state and the current motion, for the
   desired force (less the ``force_feedback`` correction, 0 by default):

   - ``bouc_wen`` (review eq. 9, α, c0, k0 affine in u): F = F₀ + u F₁ with
     F₀ = c0a ẋ + k0a (x − x0) + αa z, F₁ = c0b ẋ + k0b (x − x0) + αb z, so u* = (f − F₀)/F₁;
   - ``modified_bouc_wen`` (review eqs. 10–11): the same with c0 ẋ replaced by a1 e^(−(a2|ẋ|)^p) ẋ and the
     inertia term m ẍ added to F₀;
   - ``spencer_dyke`` (review eq. 12): F = c1 ẏ + k1 (x − x0), ẏ = (α z + c0 ẋ + k0 (x − y))/(c0 + c1) with α,
     c0, c1 affine in u; with R = f − k1 (x − x0) and N(u) = N₀ + N₁ u = α z + c0 ẋ + k0 (x − y) the
     equation R (c0 + c1) = c1 N is the quadratic
     c1b N₁ u² + (c1a N₁ + c1b N₀ − R (c0b + c1b)) u + c1a N₀ − R (c0a + c1a) = 0.

   Of the roots inside [v_min, v_max] and the two ends of the range, the one whose force is nearest f is taken
   (the clipped solution when no root lies in the range).
3. **Non-dissipative requests** get the minimum command: when (f − F_s)·ẋ < 0, F_s the model's spring force
   at the minimum command (k1 (x − x0), k0 (x − x0) or k (x − x0)), the damper would have to push
   (``dissipative_only``).
4. **Coil lag inverted** (``invert_lag``): the command that brings the effective command from u_k to u* in one
   step of the first-order lag, v = (u* − u_k e^(−η dt))/(1 − e^(−η dt)), clipped to the range; without it v = u*.

Departures from the paper: the paper could not be consulted while writing this module, so the steps above are
the SID structure as the issue and common reproductions state it, not a transcription of its equations. In
particular the observer here integrates the full model (for Spencer–Dyke y and z together, with the command's
effect on ẏ) by the project's implicit routine rather than an explicit update of z alone, and the quadratic
of step 2 is solved exactly for Spencer–Dyke rather than simplified. The solution is instantaneous: it uses the
state and motion at t_k for the force wanted at t_{k+1} (the "simplified" part — no prediction over the step).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..stepping import ATOL, RTOL
from .base import lag_decay
from .observer import ObserverInverse

#: The damper models whose force law the SID solves in closed form.
SID_MODELS = ("bouc_wen", "spencer_dyke", "modified_bouc_wen")
_AFFINE, _SPENCER_DYKE = 0, 1


def force_law_coefficients(damper) -> tuple[int, np.ndarray]:
    """(kind, coefficients) of the damper's force law as :func:`_solve` takes them, read by parameter name.

    Affine in u (kind 0, ``bouc_wen`` and ``modified_bouc_wen``): [c_a, c_b, k_a, k_b, x0, αa, αb, m, a2, p] of
    F = m ẍ + (c_a + c_b u) e^(−(a2|ẋ|)^p) ẋ + (k_a + k_b u)(x − x0) + (αa + αb u) z (Bouc–Wen: m = a2 = 0).
    Spencer–Dyke (kind 1): [c0a, c0b, k0, c1a, c1b, k1, x0, αa, αb]."""
    name = damper.name
    p = damper.params
    if name == "bouc_wen":
        return _AFFINE, np.array([p.c0a, p.c0b, p.k0a, p.k0b, p.x0, p.alpha_a, p.alpha_b, 0.0, 0.0, 1.0])
    if name == "modified_bouc_wen":
        return _AFFINE, np.array([p.a1a, p.a1b, p.ka, p.kb, p.x0, p.alpha_a, p.alpha_b, p.m, p.a2, p.p])
    if name == "spencer_dyke":
        return _SPENCER_DYKE, np.array([p.c0a, p.c0b, p.k0, p.c1a, p.c1b, p.k1, p.x0, p.alpha_a, p.alpha_b])
    raise ValueError(f"the sid inverse supports the damper models {list(SID_MODELS)}, got {name!r}; use the "
                     "'model' inverse for any model")


@nb.njit(cache=True)
def _force(kind, c, s, x, v, a, u):
    """The force at state s, motion (x, ẋ, ẍ) and effective command u (the coefficients of
    :func:`force_law_coefficients`)."""
    if kind == _AFFINE:
        thin = math.exp(-(abs(c[8] * v) ** c[9])) * v
        return c[7] * a + (c[0] + c[1] * u) * thin + (c[2] + c[3] * u) * (x - c[4]) + (c[5] + c[6] * u) * s[0]
    c0 = c[0] + c[1] * u
    c1 = c[3] + c[4] * u
    return c1 * ((c[7] + c[8] * u) * s[1] + c0 * v + c[2] * (x - s[0])) / (c0 + c1) + c[5] * (x - c[6])


@nb.njit(cache=True)
def _solve(kind, c, s, x, v, a, f, lo, hi):
    """(u*, F_s) of :func:`effective_command` for one damper."""
    if kind == _AFFINE:
        thin = math.exp(-(abs(c[8] * v) ** c[9])) * v
        F0 = c[7] * a + c[0] * thin + c[2] * (x - c[4]) + c[5] * s[0]
        q2, q1, q0 = 0.0, c[1] * thin + c[3] * (x - c[4]) + c[6] * s[0], F0 - f
        Fs = (c[2] + c[3] * lo) * (x - c[4])
    else:
        R = f - c[5] * (x - c[6])
        N0 = c[7] * s[1] + c[0] * v + c[2] * (x - s[0])
        N1 = c[8] * s[1] + c[1] * v
        q2 = c[4] * N1
        q1 = c[3] * N1 + c[4] * N0 - R * (c[1] + c[4])
        q0 = c[3] * N0 - R * (c[0] + c[3])
        Fs = c[5] * (x - c[6])
    # candidates: the real roots (cancellation-free formula) and the ends of the range
    r1 = math.nan
    r2 = math.nan
    if abs(q2) <= 1e-12 * max(abs(q1), abs(q0), 1e-300):
        if q1 != 0.0:
            r1 = -q0 / q1
    else:
        disc = q1 * q1 - 4.0 * q2 * q0
        if disc >= 0.0:
            q = -0.5 * (q1 + math.copysign(math.sqrt(disc), q1))
            r1 = q / q2
            if q != 0.0:
                r2 = q0 / q
    best = lo
    err = abs(_force(kind, c, s, x, v, a, lo) - f)
    for u in (r1, r2, hi):
        if lo <= u <= hi:  # False for NaN
            e = abs(_force(kind, c, s, x, v, a, u) - f)
            if e < err:
                best = u
                err = e
    return best, Fs


@nb.njit(cache=True)
def _sid_commands(kind, c, Y, U, W, f, lo, hi, decay, invert, dissipative_only, out):
    """Steps 2-4 of the module docstring for N dampers: states Y (N, ns), effective commands U (N, 1), motion W
    (N, 3), target forces f (N,); commands into ``out`` (N,)."""
    for b in range(f.shape[0]):
        x, v, a = W[b, 0], W[b, 1], W[b, 2]
        u, Fs = _solve(kind, c, Y[b], x, v, a, f[b], lo, hi)
        if dissipative_only and (f[b] - Fs) * v < 0.0:
            u = lo
        if invert:
            d = decay[0] if u > U[b, 0] else decay[1]  # the rate of a rising or a falling command
            u = (u - U[b, 0] * d) / (1.0 - d)
        out[b] = min(max(u, lo), hi)


def effective_command(damper, states, x, v, a, f) -> tuple[np.ndarray, np.ndarray]:
    """(u*, F_s): the effective command in [v_min, v_max] whose force at the internal ``states`` (N, ns) and
    motion x, ẋ, ẍ (N,) is nearest the force ``f`` (N,) — exactly f when the range allows (step 2 of the module
    docstring) — and the model's spring force at the minimum command (step 3)."""
    kind, c = force_law_coefficients(damper)
    states = np.atleast_2d(np.asarray(states, dtype=np.float64))
    x, v, a, f = (np.atleast_1d(np.asarray(q, dtype=np.float64)) for q in (x, v, a, f))
    u, Fs = np.empty(f.size), np.empty(f.size)
    for b in range(f.size):
        u[b], Fs[b] = _solve(kind, c, states[b], x[b], v[b], a[b], f[b], damper.command.v_min,
                             damper.command.v_max)
    return u, Fs


class SimplifiedInverse(ObserverInverse):
    """Simplified inverse dynamics (see the module docstring) for ``bouc_wen``, ``spencer_dyke`` and
    ``modified_bouc_wen`` dampers; ``invert_lag`` and ``dissipative_only`` switch steps 4 and 3; the observer's
    options as in :class:`~mrd_env.inverse.observer.ObserverInverse`."""

    name = "sid"

    def __init__(self, damper, *, dt: float = 1e-3, invert_lag: bool = True, dissipative_only: bool = True,
                 force_feedback: float = 0.0, u0: float | None = None, max_substeps: int | None = None,
                 rtol: float = RTOL, atol: float = ATOL):
        super().__init__(damper, dt=dt, force_feedback=force_feedback, u0=u0, max_substeps=max_substeps,
                         rtol=rtol, atol=atol)
        self._kind, self._coef = force_law_coefficients(self.damper)
        for name, flag in (("invert_lag", invert_lag), ("dissipative_only", dissipative_only)):
            if not isinstance(flag, (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {flag!r}")
        self.invert_lag = bool(invert_lag)
        self.dissipative_only = bool(dissipative_only)
        self._decay = lag_decay(self.damper.command, self.dt)

    def _command(self, f_desired, x, v, f_measured):
        self._observe(x, v)
        obs = self.observer
        out = np.empty(self.N)
        _sid_commands(self._kind, self._coef, obs.Y, obs.U, obs.W, self._target(f_desired, f_measured), self.v_min,
                      self.v_max, self._decay, self.invert_lag, self.dissipative_only, out)
        return out
