"""Dominguez model (Dominguez, Sedaghati & Stiharu 2004, 2006), review eqs. (14)–(20).

A Bouc–Wen-based model whose force depends on the current I and, through a scaling law, on the
excitation's frequency ω and amplitude x_max::

    F = (d1 ω^d2)(d3 x_max^d4) · [c0(I) ẋ + k0(I) x + α(I) z]                          (14)

    c0(I)   = c1 + c2 (1 − exp(−c3 (I − I_c)))              for I > I_c                (15)
            = c4 + (c1 − c4) I/I_c                          for I ≤ I_c
    α(I)    = α1 + α2 (1 − exp(−α3 (I − I_c)))              for I > I_c                (16)
            = α4 + (α1 − α4) I/I_c                          for I ≤ I_c
    F_z0(I) = F_z01 + F_z02 (1 − exp(−F_z03 (I − I_c)))     for I > I_c                (17)
            = F_z04 + (F_z01 − F_z04) I/I_c                 for I ≤ I_c
    k0(I)   = k1 + k2 I                                                                (18)
    γ(I)    = γ1 − γ2 I                                                                (19)

    z = (1/√γ) tanh(√γ ẋ + b · artanh(√γ F_z0 / α)),   b = sgn(x), smoothed over x_s   (20)

The model, as published, needs the excitation known a priori: ω (rad/s) and x_max (m) are parameters of the
preset, not measured online, and the branch of eq. (20) is chosen by the sign of the displacement, which
identifies the loading/unloading half of a zero-mean harmonic stroke (x > 0 ⇔ ẍ < 0). Outside harmonic
excitation about x = 0 the model has no meaning; use the Bouc–Wen family there.

Choices where the review's text is ambiguous or inconsistent (stated, common literature form):

* eq. (14) prints |c0 ẋ + k0 x + α z|; the bars are read as brackets (an absolute value would make the force
  one-signed and the damper non-dissipative in the usual sense).
* eq. (20) is the closed-form solution, branch by branch, of the n = 2, β = 0 Bouc–Wen-type evolution in
  the velocity, dz/dẋ = 1 − γ z² (A = 1), each branch passing through z = ±F_z0/α at ẋ = 0 — so F_z0 is the
  hysteretic force at zero velocity, α/√γ its saturation, c0 + α the pre-yield slope. The closed form is
  implemented as it stands: it is the exact solution, needs no acceleration input (which is 0 when coupled
  to a plant) and no state; as a function of (ẋ, x) the model is memoryless, with z in m/s, α in N·s/m and
  γ in s²/m². The branch switches at x = 0, where |ẋ| is largest and both tanh branches are saturated
  (for √γ ω x_max ≫ 1). A displacement-driven evolution such as ż = (1 − γ z²) ẋ is not what eq. (20)
  solves: it is reversible (z a function of x alone: no hysteresis, and no role for F_z0).
  The review prints +artanh(…) for x < 0; that orientation makes the force lead the velocity (the loop
  runs the wrong way round and the zero-velocity force has the opposite sign of the preceding motion). The
  physical orientation (force lags velocity, as in the measured loops and the Bouc–Wen models, and as in the
  hyperbolic-tangent model of Kwok et al. 2006, z = tanh(β ẋ + δ sgn x)) is used: +artanh for x > 0.
  sgn(x) is smoothed as tanh(x/x_s) (x_s = 0: exact sign).
* eqs. (15)–(17) as printed are discontinuous at I = I_c (e.g. (15) gives 2 c4 − c1 from below and c1 from
  above); the continuous form is used: linear from p4 at I = 0 to p1 at I = I_c, then the exponential
  approach to p1 + p2.
* Constraints over the command range (checked when the damper is built): α > 0, γ > 0, c0 ≥ 0, F_z0 ≥ 0
  and F_z0 < α/√γ (the artanh argument below 1).

Command unit: current (A).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from .base import (CommandSpec, DamperParams, FIXED_SMOOTHING, FIXED_TEST_CONDITION, Preset, no_projection,
                   no_states_rhs, param, smooth_sign)
from .bi_viscous import CommandRangeChecked, command_grid
from .registry import register


@dataclass(frozen=True)
class DominguezParams(DamperParams):
    c1: float = param(unit="N·s/m", lo=0.0, doc="c0 at the critical current I_c, eq. (15)")
    c2: float = param(unit="N·s/m", doc="c0 rise above I_c (c0 → c1 + c2), eq. (15)")
    c3: float = param(unit="1/A", lo=0.0, doc="c0 exponential rate above I_c, eq. (15)")
    c4: float = param(unit="N·s/m", lo=0.0, doc="c0 at zero current, eq. (15)")
    k1: float = param(unit="N/m", doc="k0 at zero current, eq. (18)")
    k2: float = param(unit="N/(m·A)", doc="k0 per ampere, eq. (18)")
    alpha1: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="α at I_c, eq. (16)")
    alpha2: float = param(unit="N·s/m", doc="α rise above I_c, eq. (16)")
    alpha3: float = param(unit="1/A", lo=0.0, doc="α exponential rate above I_c, eq. (16)")
    alpha4: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="α at zero current, eq. (16)")
    gamma1: float = param(unit="s²/m²", lo=0.0, lo_open=True, doc="γ at zero current, eq. (19)")
    gamma2: float = param(unit="s²/(m²·A)", doc="γ decrease per ampere, eq. (19)")
    fz01: float = param(unit="N", lo=0.0, doc="F_z0 (hysteretic force at zero velocity) at I_c, eq. (17)")
    fz02: float = param(unit="N", doc="F_z0 rise above I_c, eq. (17)")
    fz03: float = param(unit="1/A", lo=0.0, doc="F_z0 exponential rate above I_c, eq. (17)")
    fz04: float = param(unit="N", lo=0.0, doc="F_z0 at zero current, eq. (17)")
    i_c: float = param(unit="A", lo=0.0, lo_open=True, doc="critical current I_c")
    d1: float = param(unit="(rad/s)^-d2", lo=0.0, lo_open=True, doc="frequency factor d1 ω^d2, eq. (14)")
    d2: float = param(unit="-", doc="frequency exponent, eq. (14)")
    d3: float = param(unit="m^-d4", lo=0.0, lo_open=True, doc="amplitude factor d3 x_max^d4, eq. (14)")
    d4: float = param(unit="-", doc="amplitude exponent, eq. (14)")
    omega: float = param(unit="rad/s", lo=0.0, lo_open=True, doc="excitation frequency ω (known a priori)",
                         fixed=FIXED_TEST_CONDITION)
    x_max: float = param(unit="m", lo=0.0, lo_open=True, doc="excitation amplitude x_max (known a priori)",
                         fixed=FIXED_TEST_CONDITION)
    x_s: float = param(1e-4, unit="m", lo=0.0, doc="displacement over which the branch sgn(x) is smoothed",
                       fixed=FIXED_SMOOTHING)


# the index of each parameter in p, in field order (DominguezParams.index_constants();
# tests/dampers/test_param_indices.py)
(P_C1, P_C2, P_C3, P_C4, P_K1, P_K2, P_ALPHA1, P_ALPHA2, P_ALPHA3, P_ALPHA4, P_GAMMA1, P_GAMMA2, P_FZ01, P_FZ02,
 P_FZ03, P_FZ04, P_I_C, P_D1, P_D2, P_D3, P_D4, P_OMEGA, P_X_MAX, P_X_S) = range(24)


@nb.njit(cache=True)
def current_law(I, p1, p2, p3, p4, i_c):
    """Eqs. (15)–(17), continuous form: p4 + (p1 − p4) I/I_c up to I_c, then p1 + p2 (1 − e^(−p3 (I − I_c)))
    (I_c > 0)."""
    if I > i_c:
        return p1 + p2 * (1.0 - math.exp(-p3 * (I - i_c)))
    return p4 + (p1 - p4) * I / i_c


@nb.njit(cache=True)
def scaling_factor(p):
    """(d1 ω^d2)(d3 x_max^d4) of eq. (14)."""
    return p[P_D1] * p[P_OMEGA] ** p[P_D2] * p[P_D3] * p[P_X_MAX] ** p[P_D4]


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    i_c = p[P_I_C]
    c0 = current_law(u, p[P_C1], p[P_C2], p[P_C3], p[P_C4], i_c)
    k0 = p[P_K1] + p[P_K2] * u
    alpha = current_law(u, p[P_ALPHA1], p[P_ALPHA2], p[P_ALPHA3], p[P_ALPHA4], i_c)
    gamma = p[P_GAMMA1] - p[P_GAMMA2] * u
    fz0 = current_law(u, p[P_FZ01], p[P_FZ02], p[P_FZ03], p[P_FZ04], i_c)
    sg = math.sqrt(gamma)
    r = min(sg * fz0 / alpha, 1.0 - 1e-12)  # the range check keeps it below 1; guard the artanh anyway
    z = math.tanh(sg * xd + smooth_sign(x, p[P_X_S]) * math.atanh(r)) / sg
    return scaling_factor(p) * (c0 * xd + k0 * x + alpha * z)


# Derived preset (not published): least-squares fit of eqs. (14)–(20) to the steady force records of the
# Spencer–Dyke prototype set at 1.5 cm / 2.5 Hz (ten command levels 0–2.25 V, simulated at 0.1 ms), with
# the command mapped to a current I = v / 2.25 V·A (0–1 A, the continuous rating of commercial current-driven
# dampers) and the preload k1 x0 = 71.5 N removed (the model has no offset); force RMS residual 16 N, peak
# forces 0.55–1.63 kN. The scaling law is neutral (d2 = d4 = 0, d1 = d3 = 1): least-squares scale factors
# of the fitted model against the prototype at 1.25 and 5 Hz and at 0.75 and 3 cm are 0.97–1.005, i.e.
# d2, d4 ≈ 0.01 — this prototype's frequency/amplitude dependence is carried by the velocity already.
# Command lag η = 50 1/s: the 15–25 ms response of current-driven dampers (unverified datasheet values).
PROTOTYPE = DominguezParams(c1=2054.0, c2=1200.0, c3=0.8279, c4=1919.0, k1=4428.0, k2=-661.3,
                            alpha1=21790.0, alpha2=17540.0, alpha3=2.408, alpha4=5681.0,
                            gamma1=3416.0, gamma2=2182.0, fz01=84.65, fz02=-105.6, fz03=1.154, fz04=49.93,
                            i_c=0.3352, d1=1.0, d2=0.0, d3=1.0, d4=0.0, omega=2 * math.pi * 2.5, x_max=0.015)


@register
class Dominguez(CommandRangeChecked):
    name = "dominguez"
    Params = DominguezParams
    state_names = ()
    presets = {
        "prototype_scale": Preset(PROTOTYPE, CommandSpec("A", 0.0, 1.0, 50.0),
                                  "fit to the Spencer–Dyke prototype's loops at 1.5 cm / 2.5 Hz, 0–2.25 V "
                                  "mapped to 0–1 A (derived, see module source)", verified=False),
    }
    default_preset = "prototype_scale"
    rhs = no_states_rhs
    force_law = _force
    project = no_projection

    def coefficients(self, I):
        """(c0, k0, α, γ, F_z0) at current(s) I, eqs. (15)–(19)."""
        p = self.params
        I = np.atleast_1d(np.asarray(I, dtype=np.float64))
        law = np.vectorize(lambda i, a, b, c, d: current_law(i, a, b, c, d, p.i_c))
        return (law(I, p.c1, p.c2, p.c3, p.c4), p.k1 + p.k2 * I, law(I, p.alpha1, p.alpha2, p.alpha3, p.alpha4),
                p.gamma1 - p.gamma2 * I, law(I, p.fz01, p.fz02, p.fz03, p.fz04))

    def scaling(self) -> float:
        """(d1 ω^d2)(d3 x_max^d4), eq. (14)."""
        p = self.params
        return p.d1 * p.omega ** p.d2 * p.d3 * p.x_max ** p.d4

    def check_command_range(self) -> None:
        c = self.command
        c0, _, alpha, gamma, fz0 = self.coefficients(command_grid(c))
        rng = f"over the command range [{c.v_min:g}, {c.v_max:g}] {c.unit}"
        if np.any(alpha <= 0.0):
            raise ValueError(f"DominguezParams: alpha(I) (alpha1..alpha4) must be > 0 {rng}")
        if np.any(gamma <= 0.0):
            raise ValueError(f"DominguezParams: gamma(I) = gamma1 − gamma2·I must be > 0 {rng} "
                             f"(min {gamma.min():g} s²/m²)")
        if np.any(c0 < 0.0):
            raise ValueError(f"DominguezParams: c0(I) (c1..c4) must be >= 0 {rng}")
        if np.any(fz0 < 0.0):
            raise ValueError(f"DominguezParams: F_z0(I) (fz01..fz04) must be >= 0 {rng}")
        if np.any(fz0 * np.sqrt(gamma) >= alpha):
            raise ValueError(f"DominguezParams: F_z0(I) (fz01..fz04) must stay below the saturation force "
                             f"alpha(I)/sqrt(gamma(I)) {rng}")
