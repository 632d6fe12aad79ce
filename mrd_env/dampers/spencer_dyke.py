"""Spencer–Dyke phenomenological model (Spencer, Dyke, Sain & Carlson 1997), review eq. (12).

A Bouc–Wen element (α z) in parallel with a dashpot c0 and spring k0, in series with a dashpot c1, plus
the accumulator spring k1::

    F  = c1 ẏ + k1 (x − x0)          (= α z + c0 (ẋ − ẏ) + k0 (x − y) + k1 (x − x0))
    ẏ  = (α z + c0 ẋ + k0 (x − y)) / (c0 + c1)
    ż  = −γ |ẋ − ẏ| z |z|^(n−1) − β (ẋ − ẏ) |z|^n + A (ẋ − ẏ)
    α  = αa + αb u,   c0 = c0a + c0b u,   c1 = c1a + c1b u

States: y (internal displacement, m) and z (Bouc–Wen variable, m). The review's δ is A here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from .base import (DamperModel, DamperParams, FIXED_SCALING, FIXED_SHAPE, Preset, param, PROTOTYPE_COMMAND,
                   AUTOMOTIVE_COMMAND)
from .hysteresis import BoucWenSaturation, bouc_wen_partials, bouc_wen_zdot, clip_to_saturation
from .registry import register
from ..validation import check_scalar


@dataclass(frozen=True)
class SpencerDykeParams(DamperParams):
    c0a: float = param(unit="N·s/m", lo=0.0, doc="viscous damping at large velocity, command-independent part")
    c0b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c0 per unit command")
    k0: float = param(unit="N/m", lo=0.0, doc="stiffness at large velocity")
    c1a: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="roll-off dashpot, command-independent part")
    c1b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c1 per unit command")
    k1: float = param(unit="N/m", lo=0.0, doc="accumulator stiffness")
    x0: float = param(unit="m", doc="initial displacement of spring k1")
    alpha_a: float = param(unit="N/m", lo=0.0, doc="Bouc–Wen gain α, command-independent part")
    alpha_b: float = param(unit="N/(m·cmd)", lo=0.0, doc="α per unit command")
    gamma: float = param(unit="1/m^n", lo=0.0, doc="Bouc–Wen shape parameter γ")
    beta: float = param(unit="1/m^n", doc="Bouc–Wen shape parameter β")
    A: float = param(unit="-", lo=0.0, lo_open=True, doc="Bouc–Wen parameter A (the review's δ)", fixed=FIXED_SCALING)
    n: float = param(unit="-", lo=1.0, hi=10.0, doc="Bouc–Wen exponent n", fixed=FIXED_SHAPE)

    def check(self) -> None:
        if self.beta + self.gamma <= 0.0:
            raise ValueError(f"SpencerDykeParams: beta + gamma = {self.beta + self.gamma:g} must be > 0 "
                             "(otherwise z has no saturation)")


# the index of each parameter in p, in field order (SpencerDykeParams.index_constants();
# tests/dampers/test_param_indices.py)
P_C0A, P_C0B, P_K0, P_C1A, P_C1B, P_K1, P_X0, P_ALPHA_A, P_ALPHA_B, P_GAMMA, P_BETA, P_A, P_N = range(13)


@nb.njit(cache=True)
def _ydot(p, s, x, xd, u):
    c0 = p[P_C0A] + p[P_C0B] * u
    c1 = p[P_C1A] + p[P_C1B] * u
    alpha = p[P_ALPHA_A] + p[P_ALPHA_B] * u
    return (alpha * s[1] + c0 * xd + p[P_K0] * (x - s[0])) / (c0 + c1)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    yd = _ydot(p, s, x, xd, u)
    ds[0] = yd
    ds[1] = bouc_wen_zdot(s[1], xd - yd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return (p[P_C1A] + p[P_C1B] * u) * _ydot(p, s, x, xd, u) + p[P_K1] * (x - p[P_X0])


@nb.njit(cache=True)
def _partials(p, s, x, xd, xdd, u, J, work):
    c0 = p[P_C0A] + p[P_C0B] * u
    c1 = p[P_C1A] + p[P_C1B] * u
    alpha = p[P_ALPHA_A] + p[P_ALPHA_B] * u
    den = c0 + c1
    yd = (alpha * s[1] + c0 * xd + p[P_K0] * (x - s[0])) / den
    # ẏ and its derivatives in (y, z, x, ẋ); F = c1 ẏ + k1 (x − x0); ż = BW(z, ẋ − ẏ)
    dy, dz, dx, dv = -p[P_K0] / den, alpha / den, p[P_K0] / den, c0 / den
    J[0, 0] = dy
    J[0, 1] = dz
    J[0, 2] = dx
    J[0, 3] = dv
    bz, bw = bouc_wen_partials(s[1], xd - yd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])
    J[1, 0] = -bw * dy
    J[1, 1] = bz - bw * dz
    J[1, 2] = -bw * dx
    J[1, 3] = bw * (1.0 - dv)
    J[2, 0] = c1 * dy
    J[2, 1] = c1 * dz
    J[2, 2] = c1 * dx + p[P_K1]
    J[2, 3] = c1 * dv


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[1] = clip_to_saturation(s[1], p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


PROTOTYPE = SpencerDykeParams(
    c0a=2100.0, c0b=350.0, k0=4690.0, c1a=28300.0, c1b=295.0, k1=500.0, x0=0.143,
    alpha_a=14000.0, alpha_b=69500.0, gamma=3.63e6, beta=3.63e6, A=301.0, n=2.0)

AUTOMOTIVE = SpencerDykeParams(
    c0a=784.0, c0b=1803.0, k0=3610.0, c1a=14649.0, c1b=34622.0, k1=840.0, x0=0.0245,
    alpha_a=12441.0, alpha_b=38430.0, gamma=136320.0, beta=2059020.0, A=58.0, n=2.0)


@register
class SpencerDyke(BoucWenSaturation, DamperModel):
    name = "spencer_dyke"
    Params = SpencerDykeParams
    state_names = ("y", "z")
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "Spencer, Dyke, Sain & Carlson (1997) J. Eng. Mech. 123(3):230-238, "
                              "prototype damper (cm-based values converted to SI)"),
        "automotive": Preset(AUTOMOTIVE, AUTOMOTIVE_COMMAND,
                             "vehicle-suspension set commonly attributed to Yao et al. (2002) "
                             "Mechatronics 12:963 (attribution unverified)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    partials = _partials
    project = _project

    def rest_state(self, x: float) -> np.ndarray:
        """ẏ = 0 and ż = 0 at ẋ = 0: α z + k0 (x − y) = 0; the hysteresis at z = 0 gives y = x."""
        return np.array([check_scalar("x", x, unit="m"), 0.0])
