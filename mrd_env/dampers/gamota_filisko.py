"""Gamota–Filisko (extended Bingham) model (Gamota & Filisko 1991), review eq. (4).

A Bingham element (Coulomb friction f_c in parallel with a dashpot c0) in series with the viscoelastic
three-parameter solid — a Kelvin–Voigt element (k1 ∥ c1) in series with a spring k2 — plus the offset f0.
With x1 the displacement of the Bingham element, x2 that of the Kelvin–Voigt/k2 junction and x3 = x the
damper stroke, eq. (4) reads::

    F = k1 (x2 − x1) + c1 (ẋ2 − ẋ1) + f0 = c0 ẋ1 + f_c sgn(ẋ1) + f0 = k2 (x − x2) + f0   |F − f0| > f_c
    F = k1 (x2 − x1) + c1 ẋ2 + f0 = k2 (x − x2) + f0,   ẋ1 = 0                         |F − f0| ≤ f_c

(the review writes |F| ≷ f_c; the Bingham element carries F − f0, which is what is compared with f_c here).

Regularisation: none is needed. The set-valued Bingham law P = c0 ẋ1 + f_c sgn(ẋ1) (P = F − f0, with
ẋ1 = 0 whenever |P| ≤ f_c, the stick phase) has, for c0 > 0, the exact single-valued inverse

    ẋ1 = sgn(P) · max(|P| − f_c, 0) / c0                  (a dead zone: continuous, Lipschitz 1/c0)

States: the two spring forces (N), not the displacements — the force is k2 (x − x2) with k2 up to ~10⁷ N/m,
so a displacement state would need a tolerance of 10⁻⁹ m to give the force to 1 %, while force states are
scaled like the output. With f2 = k2 (x − x2) = F − f0 (series spring) and f1 = k1 (x2 − x1) (Kelvin–Voigt
spring), eq. (4) is the ODE::

    ẋ1  = sgn(f2) max(|f2| − f_c, 0) / c0                 (Bingham element)
    ḟ1  = k1 (f2 − f1) / c1                               (Kelvin–Voigt: c1 (ẋ2 − ẋ1) = f2 − f1)
    ḟ2  = k2 (ẋ − ẋ1 − (f2 − f1) / c1)                    (series spring: ẋ2 = ẋ1 + (f2 − f1)/c1)
    F   = f2 + f0

and the internal displacements follow as x2 = x − f2/k2, x1 = x2 − f1/k1. Both springs are unstretched at
rest (f1 = f2 = 0 at x = 0: the stroke origin is the rest position; the accumulator preload is f0). The ODE
is stiff (eigenvalues down to about −k2 (1/c0 + 1/c1) while sliding, −k2/c1 while stuck); the shared
stepping routine is L-stable, so that costs accuracy control only, not stability.

Command dependence (the review says the parameters are fitted per frequency, amplitude and current; the
common literature form, as for the Bingham model): f_c = fc_a + fc_b u, c0 = c0a + c0b u, and optionally
the springs k1 = k1a + k1b u, k2 = k2a + k2b u (set the *_b parts to 0 for command-independent springs);
c1 is command-independent. With command-dependent springs the spring forces are advanced in the rate form
above (ḟ = k(u) × deflection rate): a change of command changes the stiffness, not the force the spring
carries at that instant. At constant command this is eq. (4) exactly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import DamperModel, DamperParams, Preset, no_projection, param, PROTOTYPE_COMMAND
from .registry import register


@dataclass(frozen=True)
class GamotaFiliskoParams(DamperParams):
    fc_a: float = param(unit="N", lo=0.0, doc="Bingham friction (yield) force f_c, command-independent part")
    fc_b: float = param(unit="N/cmd", lo=0.0, doc="f_c per unit command")
    c0a: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="Bingham damping c0, command-independent part")
    c0b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c0 per unit command")
    k1a: float = param(unit="N/m", lo=0.0, doc="Kelvin–Voigt stiffness k1, command-independent part")
    k1b: float = param(unit="N/(m·cmd)", lo=0.0, doc="k1 per unit command")
    c1: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="Kelvin–Voigt damping c1")
    k2a: float = param(unit="N/m", lo=0.0, lo_open=True, doc="series stiffness k2, command-independent part")
    k2b: float = param(unit="N/(m·cmd)", lo=0.0, doc="k2 per unit command")
    f0: float = param(unit="N", doc="force offset (accumulator)")


# the index of each parameter in p, in field order (GamotaFiliskoParams.index_constants();
# tests/dampers/test_param_indices.py)
P_FC_A, P_FC_B, P_C0A, P_C0B, P_K1A, P_K1B, P_C1, P_K2A, P_K2B, P_F0 = range(10)


@nb.njit(cache=True)
def bingham_element_velocity(P, f_c, c0):
    """Velocity of a Bingham element (f_c, c0 > 0) carrying the force P: the exact inverse of
    P = c0 v + f_c sgn(v), i.e. v = 0 while |P| ≤ f_c (stick)."""
    if P > f_c:
        return (P - f_c) / c0
    if P < -f_c:
        return (P + f_c) / c0
    return 0.0


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    v1 = bingham_element_velocity(s[1], p[P_FC_A] + p[P_FC_B] * u, p[P_C0A] + p[P_C0B] * u)
    kelvin = (s[1] - s[0]) / p[P_C1]  # ẋ2 − ẋ1
    ds[0] = (p[P_K1A] + p[P_K1B] * u) * kelvin
    ds[1] = (p[P_K2A] + p[P_K2B] * u) * (xd - v1 - kelvin)


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return s[1] + p[P_F0]


# Derived preset (not published), mapped from the Spencer–Dyke prototype set, whose Bouc–Wen element is
# replaced by its elastic–perfectly-plastic limit (a spring with the Bouc–Wen pre-yield stiffness α(u)·A in
# series with a friction element yielding at α(u)·z_s): k2 = α(u) A = 4.214e6 + 2.092e7 u N/m,
# f_c = α(u) z_s = 90.15 + 447.5 u N (z_s = (A/(β+γ))^(1/2) = 6.439 mm), c0 = the prototype's c0 =
# 2100 + 350 u N·s/m, c1 = its roll-off dashpot c1a = 28300 N·s/m, k1 = its k0 = 4690 N/m (relaxation time
# c1/k1 = 6 s: at test frequencies the Kelvin–Voigt element acts as the series dashpot c1), f0 = −k1 x0 =
# −71.5 N. At 1.5 cm / 2.5 Hz, 0–2.25 V, peak forces are within 7 N and the energy per cycle within 0.3 % of
# the prototype's (checked in tests/dampers/test_models_batch_a.py).
PROTOTYPE = GamotaFiliskoParams(fc_a=90.15, fc_b=447.5, c0a=2100.0, c0b=350.0, k1a=4690.0, k1b=0.0,
                                c1=28300.0, k2a=4.214e6, k2b=2.092e7, f0=-71.5)


@register
class GamotaFilisko(DamperModel):
    name = "gamota_filisko"
    Params = GamotaFiliskoParams
    state_names = ("f1", "f2")
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "mapped from the Spencer–Dyke prototype set (derived, see module source)",
                              verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = no_projection
