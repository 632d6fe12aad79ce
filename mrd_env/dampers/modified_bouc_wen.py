"""Modified Bouc–Wen model for large-scale MR dampers (Yang, Spencer, Jung, Carlson & Sain 2002),
review eqs. (10)–(11) with the hysteresis of eq. (8)::

    F    = m ẍ + c(ẋ) ẋ + k (x − x0) + α z                               (10)
    c(ẋ) = a1 exp(−(a2 |ẋ|)^p)                                              (11)
    ż    = −γ |ẋ| z |z|^(n−1) − β ẋ |z|^n + A ẋ                             (8)
    α = αa + αb u,   a1 = a1a + a1b u,   k = ka + kb u

c(ẋ) is the post-yield damping with the MR fluid's shear thinning (it decreases with |ẋ|); m is the
inertia of the fluid driven through the valve plus the stiction effect. The review does not give the
command dependence: the common literature form (affine in the effective command u, as in eq. (9)) is used
for α, a1 and k; a2, p and the Bouc–Wen shape parameters are command independent. x0 (the accumulator
spring's rest position) is an addition for consistency with the ``bouc_wen`` model (x0 = 0 gives eq. (10)).

The inertial term: ``force`` returns the whole of eq. (10) including m·ẍ (exact on the rig, which supplies
ẍ); :meth:`ModifiedBoucWen.inertance` returns m, which plants add to their mass matrix instead (they pass
ẍ = 0 to ``force``).

Presets (both derived, ``verified=False``; the identified 20-ton damper values of Yang et al. are not on
the project's reference page and are not reproduced here):

* ``spencer1997`` — prototype scale: the ``bouc_wen`` prototype set (α(u), A, β, γ, n, k = 500 N/m,
  x0 = 0.143 m) with a shear-thinning c(ẋ) that equals that set's c0(u) = 1955 + 298.2 u N·s/m at the
  peak velocity of the 1.5 cm / 2.5 Hz test (0.2356 m/s): a2 = 0.5 s/m, p = 0.6, so
  a1 = c0 · exp((0.5 · 0.2356)^0.6) = 1.3194 c0. m = 0: the fluid inertia of a damper this size is of
  order 1 kg (ρ L A_p²/A_gap), a few newtons at these accelerations.
* ``large_scale`` — an illustrative 200 kN-class set (0–2 A): yield force α z_s = 15 kN at 0 A and
  170 kN at 2 A with z_s = 2 mm (A = 1, β = γ = 1.25e5 m⁻²), post-yield force c(ẋ)ẋ ≈ 5–25 kN at
  0.1 m/s (a2 = 0.5 s/m, p = 0.6), accumulator stiffness 50 kN/m and a fluid inertia m = 300 kg (the order
  of ρ L A_p²/A_gap for a 20 cm piston and a 1 mm annular gap), so that the peak force at 0.1 m/s and
  2 A is about 200 kN; η = 50 s⁻¹ (a current-driven coil settling in about 60 ms — unverified
  recollection). Design values, not an identification.

With a2 = 0.5 s/m and p = 0.6, c(ẋ)ẋ keeps increasing with |ẋ| up to |ẋ| = (1/p)^(1/p)/a2 ≈ 4.7 m/s
(beyond it eq. (11) makes the viscous force decrease). State: z (m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb

from .base import CommandSpec, DamperModel, DamperParams, FIXED_SCALING, FIXED_SHAPE, Preset, param, PROTOTYPE_COMMAND
from .hysteresis import BoucWenSaturation, bouc_wen_zdot, clip_to_saturation
from .registry import register


@dataclass(frozen=True)
class ModifiedBoucWenParams(DamperParams):
    m: float = param(unit="kg", lo=0.0, doc="inertia of the fluid and stiction effect (the m ẍ term)")
    a1a: float = param(unit="N·s/m", lo=0.0, doc="zero-velocity post-yield damping a1, command-independent part")
    a1b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="a1 per unit command")
    a2: float = param(unit="s/m", lo=0.0, doc="shear-thinning velocity scale a2 (c = a1 exp(−(a2|ẋ|)^p))")
    p: float = param(unit="-", lo=0.0, lo_open=True, hi=10.0, doc="shear-thinning exponent p")
    ka: float = param(unit="N/m", lo=0.0, doc="accumulator stiffness k, command-independent part")
    kb: float = param(unit="N/(m·cmd)", lo=0.0, doc="k per unit command")
    x0: float = param(unit="m", doc="rest position of the accumulator spring")
    alpha_a: float = param(unit="N/m", lo=0.0, doc="hysteretic gain α, command-independent part")
    alpha_b: float = param(unit="N/(m·cmd)", lo=0.0, doc="α per unit command")
    gamma: float = param(unit="1/m^n", lo=0.0, doc="Bouc–Wen shape parameter γ")
    beta: float = param(unit="1/m^n", doc="Bouc–Wen shape parameter β")
    A: float = param(unit="-", lo=0.0, lo_open=True, doc="Bouc–Wen parameter A", fixed=FIXED_SCALING)
    n: float = param(unit="-", lo=1.0, hi=10.0, doc="Bouc–Wen exponent n", fixed=FIXED_SHAPE)

    def check(self) -> None:
        if self.beta + self.gamma <= 0.0:
            raise ValueError(f"ModifiedBoucWenParams: beta + gamma = {self.beta + self.gamma:g} must be > 0 "
                             "(otherwise z has no saturation)")


# the index of each parameter in p, in field order (checked by tests/dampers/test_param_indices.py)
P_M, P_A1A, P_A1B, P_A2, P_P, P_KA, P_KB, P_X0, P_ALPHA_A, P_ALPHA_B, P_GAMMA, P_BETA, P_A, P_N = range(14)


@nb.njit(cache=True)
def shear_thinning_damping(a1, a2, p, v):
    """Review eq. (11): c(ẋ) = a1 exp(−(a2 |ẋ|)^p) (N·s/m)."""
    return a1 * math.exp(-((a2 * abs(v)) ** p))


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    ds[0] = bouc_wen_zdot(s[0], xd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    c = shear_thinning_damping(p[P_A1A] + p[P_A1B] * u, p[P_A2], p[P_P], xd)
    return p[P_M] * xdd + c * xd + (p[P_KA] + p[P_KB] * u) * (x - p[P_X0]) + (p[P_ALPHA_A] + p[P_ALPHA_B] * u) * s[0]


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[0] = clip_to_saturation(s[0], p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


_A2, _P = 0.5, 0.6
_STRETCH = math.exp((_A2 * 0.015 * 2.0 * math.pi * 2.5) ** _P)  # c0 at 0.2356 m/s ↔ a1

PROTOTYPE = ModifiedBoucWenParams(
    m=0.0, a1a=round(1955.0 * _STRETCH, 1), a1b=round(298.2 * _STRETCH, 1), a2=_A2, p=_P, ka=500.0, kb=0.0,
    x0=0.143, alpha_a=14000.0, alpha_b=69500.0, gamma=3.63e6, beta=3.63e6, A=301.0, n=2.0)

LARGE_SCALE = ModifiedBoucWenParams(
    m=300.0, a1a=6.0e4, a1b=1.2e5, a2=_A2, p=_P, ka=5.0e4, kb=0.0, x0=0.0,
    alpha_a=7.5e6, alpha_b=3.875e7, gamma=1.25e5, beta=1.25e5, A=1.0, n=2.0)


@register
class ModifiedBoucWen(BoucWenSaturation, DamperModel):
    name = "modified_bouc_wen"
    Params = ModifiedBoucWenParams
    state_names = ("z",)
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "derived from the Spencer et al. (1997) prototype via the bouc_wen set, with a "
                              "shear-thinning c(ẋ) equal to its c0 at 0.236 m/s (see module source)",
                              verified=False),
        "large_scale": Preset(LARGE_SCALE, CommandSpec("A", 0.0, 2.0, 50.0),
                              "illustrative 200 kN-class design values in the spirit of Yang et al. (2002) "
                              "Eng. Struct. 24:309-323 (not their identified values; see module source)",
                              verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = _project

    def inertance(self) -> float:
        """m of the m ẍ term of eq. (10) (kg)."""
        return self.params.m
