"""Bouc–Wen model with command-dependent coefficients, review eqs. (7)–(9).

    F = c0 ẋ + k0 (x − x0) + α z                                          (7)
    ż = −γ |ẋ| z |z|^(n−1) − β ẋ |z|^n + A ẋ                              (8)
    α = αa + αb u,  c0 = c0a + c0b u,  k0 = k0a + k0b u                     (9)

(eq. (9)'s frequency/amplitude dependence of the coefficients is left to the user: fit one set per test
condition). State: z (m).

As in eq. (7), k0b multiplies (x − x0): with an accumulator preload x0 larger than the stroke, a k0b > 0 adds
−k0b·x0·u, a force that falls with the command. Every preset has k0b = 0; a fit that frees k0b and x0 can
find such a model: check a fitted one's energy per cycle over the command range on the rig, as
``tests/dampers/test_dampers_physics.py`` does for the presets.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import (DamperModel, DamperParams, FIXED_SCALING, FIXED_SHAPE, Preset, param, PROTOTYPE_COMMAND,
                   AUTOMOTIVE_COMMAND)
from .hysteresis import BoucWenSaturation, bouc_wen_partials, bouc_wen_zdot, clip_to_saturation
from .registry import register


@dataclass(frozen=True)
class BoucWenParams(DamperParams):
    c0a: float = param(unit="N·s/m", lo=0.0, doc="viscous coefficient c0, command-independent part")
    c0b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c0 per unit command")
    k0a: float = param(unit="N/m", lo=0.0, doc="stiffness k0, command-independent part")
    k0b: float = param(unit="N/(m·cmd)", lo=0.0, doc="k0 per unit command")
    x0: float = param(unit="m", doc="initial displacement of the spring k0")
    alpha_a: float = param(unit="N/m", lo=0.0, doc="hysteretic gain α, command-independent part")
    alpha_b: float = param(unit="N/(m·cmd)", lo=0.0, doc="α per unit command")
    gamma: float = param(unit="1/m^n", lo=0.0, doc="shape parameter γ")
    beta: float = param(unit="1/m^n", doc="shape parameter β")
    A: float = param(unit="-", lo=0.0, lo_open=True, doc="Bouc–Wen parameter A", fixed=FIXED_SCALING)
    n: float = param(unit="-", lo=1.0, hi=10.0, doc="exponent n", fixed=FIXED_SHAPE)

    def check(self) -> None:
        if self.beta + self.gamma <= 0.0:
            raise ValueError(f"{type(self).__name__}: beta + gamma = {self.beta + self.gamma:g} must be > 0 "
                             "(otherwise z has no saturation)")


# the index of each parameter in p, in field order (BoucWenParams.index_constants();
# tests/dampers/test_param_indices.py)
P_C0A, P_C0B, P_K0A, P_K0B, P_X0, P_ALPHA_A, P_ALPHA_B, P_GAMMA, P_BETA, P_A, P_N = range(11)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    ds[0] = bouc_wen_zdot(s[0], xd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return ((p[P_C0A] + p[P_C0B] * u) * xd + (p[P_K0A] + p[P_K0B] * u) * (x - p[P_X0])
            + (p[P_ALPHA_A] + p[P_ALPHA_B] * u) * s[0])


@nb.njit(cache=True)
def _partials(p, s, x, xd, xdd, u, J, work):
    dz, dv = bouc_wen_partials(s[0], xd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])
    J[0, 0] = dz
    J[0, 1] = 0.0
    J[0, 2] = dv
    J[1, 0] = p[P_ALPHA_A] + p[P_ALPHA_B] * u
    J[1, 1] = p[P_K0A] + p[P_K0B] * u
    J[1, 2] = p[P_C0A] + p[P_C0B] * u


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[0] = clip_to_saturation(s[0], p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


# Prototype scale (derived, not published): the Spencer–Dyke prototype's hysteretic part (α(u), A, β, γ,
# n, k1, x0) with c0 equal to that set's large-velocity damping c0 c1/(c0 + c1) at 0 V and 2.25 V, so that
# the two models share force levels; what Bouc–Wen lacks is the roll-off near zero velocity.
PROTOTYPE = BoucWenParams(c0a=1955.0, c0b=298.2, k0a=500.0, k0b=0.0, x0=0.143,
                          alpha_a=14000.0, alpha_b=69500.0, gamma=3.63e6, beta=3.63e6, A=301.0, n=2.0)

# Automotive scale, derived the same way from the automotive Spencer–Dyke set (0 V and 2 V).
AUTOMOTIVE = BoucWenParams(c0a=744.1, c0b=1714.0, k0a=840.0, k0b=0.0, x0=0.0245,
                           alpha_a=12441.0, alpha_b=38430.0, gamma=136320.0, beta=2059020.0, A=58.0, n=2.0)


@register
class BoucWen(BoucWenSaturation, DamperModel):
    name = "bouc_wen"
    Params = BoucWenParams
    state_names = ("z",)
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "derived from the Spencer et al. (1997) prototype Spencer–Dyke set "
                              "(see module source)", verified=False),
        "automotive": Preset(AUTOMOTIVE, AUTOMOTIVE_COMMAND,
                             "derived from the automotive Spencer–Dyke set (see module source)",
                             verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    partials = _partials
    project = _project
