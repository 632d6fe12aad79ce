"""Ali & Ramaswamy model: Bouc–Wen with amplitude- and current-dependent coefficients, review eq. (21)
(review ref. [44]; Ali & Ramaswamy (2009) J. Dyn. Syst. Meas. Control 131 — attribution unverified)::

    F = c ẋ + k x + α z + f0                                                (7), (21)
    ż = −γ |ẋ| z |z|^(n−1) − β ẋ |z|^n + A ẋ                                (8)
    c = (c1 + c2 x_a + c3 x_a²) + (c4 + c5 x_a + c6 x_a²) i_c
    k = (k1 + k2 x_a + k3 x_a²) + (k4 + k5 x_a + k6 x_a²) i_c                (21)
    α = (α1 + α2 x_a + α3 x_a²) + (α4 + α5 x_a + α6 x_a²) i_c

x_a is the stroke amplitude of the excitation, known a priori (a parameter of the configured damper: build
one damper per test amplitude, e.g. ``make_damper("ali_ramaswamy", x_a=0.01)``); i_c is the effective
command current u (A). The identification constraints c(x_a, 0) ≥ 0, k(x_a, 0) ≥ 0 and α(x_a, 0) ≥ 0 are
checked on construction (``AliRamaswamyParams.check``); the individual polynomial coefficients may have
either sign. f0 (the accumulator preload) is an addition to eq. (7): it keeps the preload independent of
the amplitude- and current-dependent k. State: z (m).

Preset ``spencer1997`` (derived, ``verified=False``): the ``bouc_wen`` prototype set with the command
rescaled to a current of 0–1 A (2.25 V ↔ 1 A, so per-ampere gains are 2.25 × the per-volt ones:
c = 1955 + 670.95 i N·s/m, α = 14000 + 156375 i N/m, k = 500 N/m, f0 = −k1 x0 = −71.5 N) at the
reference amplitude 1.5 cm, and amplitude factors chosen to follow the trends reported for large
dampers (review section 3.5: c and k decrease with x_a, α increases with x_a), each equal to 1 at 1.5 cm:

    c, k:  1.2025 − 15 x_a + 100 x_a²    (decreasing up to 7.5 cm, minimum 0.64)
    α:     0.7225 + 20 x_a − 100 x_a²    (increasing up to 10 cm; α(x_a, 0) < 0 beyond 23.1 cm)

so the preset satisfies the constraints for x_a up to 23 cm. η = 190 s⁻¹ as the prototype.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import (CommandSpec, DamperModel, DamperParams, FIXED_SCALING, FIXED_SHAPE, FIXED_TEST_CONDITION, Preset,
                   param)
from .hysteresis import BoucWenSaturation, bouc_wen_zdot, clip_to_saturation
from .registry import register


def _coef(doc: str, unit: str):
    return param(unit=unit, doc=doc)


@dataclass(frozen=True)
class AliRamaswamyParams(DamperParams):
    c1: float = _coef("c(x_a, 0): constant term", "N·s/m")
    c2: float = _coef("c(x_a, 0): x_a term", "N·s/m²")
    c3: float = _coef("c(x_a, 0): x_a² term", "N·s/m³")
    c4: float = _coef("c per ampere: constant term", "N·s/(m·A)")
    c5: float = _coef("c per ampere: x_a term", "N·s/(m²·A)")
    c6: float = _coef("c per ampere: x_a² term", "N·s/(m³·A)")
    k1: float = _coef("k(x_a, 0): constant term", "N/m")
    k2: float = _coef("k(x_a, 0): x_a term", "N/m²")
    k3: float = _coef("k(x_a, 0): x_a² term", "N/m³")
    k4: float = _coef("k per ampere: constant term", "N/(m·A)")
    k5: float = _coef("k per ampere: x_a term", "N/(m²·A)")
    k6: float = _coef("k per ampere: x_a² term", "N/(m³·A)")
    alpha1: float = _coef("α(x_a, 0): constant term", "N/m")
    alpha2: float = _coef("α(x_a, 0): x_a term", "N/m²")
    alpha3: float = _coef("α(x_a, 0): x_a² term", "N/m³")
    alpha4: float = _coef("α per ampere: constant term", "N/(m·A)")
    alpha5: float = _coef("α per ampere: x_a term", "N/(m²·A)")
    alpha6: float = _coef("α per ampere: x_a² term", "N/(m³·A)")
    x_a: float = param(unit="m", lo=0.0, lo_open=True, hi=1.0, doc="stroke amplitude of the excitation",
                       fixed=FIXED_TEST_CONDITION)
    f0: float = param(unit="N", doc="force offset (accumulator preload)")
    gamma: float = param(unit="1/m^n", lo=0.0, doc="Bouc–Wen shape parameter γ")
    beta: float = param(unit="1/m^n", doc="Bouc–Wen shape parameter β")
    A: float = param(unit="-", lo=0.0, lo_open=True, doc="Bouc–Wen parameter A", fixed=FIXED_SCALING)
    n: float = param(unit="-", lo=1.0, hi=10.0, doc="Bouc–Wen exponent n", fixed=FIXED_SHAPE)

    def coefficients(self, i_c: float = 0.0) -> tuple[float, float, float]:
        """(c, k, α) of eq. (21) at the amplitude x_a and current i_c (N·s/m, N/m, N/m)."""
        a = self.x_a
        c = self.c1 + self.c2 * a + self.c3 * a * a + (self.c4 + self.c5 * a + self.c6 * a * a) * i_c
        k = self.k1 + self.k2 * a + self.k3 * a * a + (self.k4 + self.k5 * a + self.k6 * a * a) * i_c
        al = (self.alpha1 + self.alpha2 * a + self.alpha3 * a * a
              + (self.alpha4 + self.alpha5 * a + self.alpha6 * a * a) * i_c)
        return c, k, al

    def check(self) -> None:
        if self.beta + self.gamma <= 0.0:
            raise ValueError(f"AliRamaswamyParams: beta + gamma = {self.beta + self.gamma:g} must be > 0 "
                             "(otherwise z has no saturation)")
        c, k, al = self.coefficients(0.0)
        bad = [f"{name}(x_a, 0) = {name}1 + {name}2 x_a + {name}3 x_a² = {val:g} {unit}"
               for name, val, unit in (("c", c, "N·s/m"), ("k", k, "N/m"), ("alpha", al, "N/m")) if val < 0.0]
        if bad:
            raise ValueError("AliRamaswamyParams violates the constraints of review eq. (21) "
                             "c(x_a, 0) >= 0, k(x_a, 0) >= 0, alpha(x_a, 0) >= 0 at "
                             f"x_a = {self.x_a:g} m: " + "; ".join(bad))


# the index of each parameter in p, in field order (AliRamaswamyParams.index_constants();
# tests/dampers/test_param_indices.py)
(P_C1, P_C2, P_C3, P_C4, P_C5, P_C6, P_K1, P_K2, P_K3, P_K4, P_K5, P_K6, P_ALPHA1, P_ALPHA2, P_ALPHA3, P_ALPHA4,
 P_ALPHA5, P_ALPHA6, P_X_A, P_F0, P_GAMMA, P_BETA, P_A, P_N) = range(24)


@nb.njit(cache=True)
def _quad(p, o, a, u):
    return p[o] + p[o + 1] * a + p[o + 2] * a * a + (p[o + 3] + p[o + 4] * a + p[o + 5] * a * a) * u


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    ds[0] = bouc_wen_zdot(s[0], xd, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    a = p[P_X_A]
    return _quad(p, P_C1, a, u) * xd + _quad(p, P_K1, a, u) * x + _quad(p, P_ALPHA1, a, u) * s[0] + p[P_F0]


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[0] = clip_to_saturation(s[0], p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


def _poly(value_at_ref: float, factor: tuple[float, float, float]) -> tuple[float, float, float]:
    return tuple(round(value_at_ref * f, 6) for f in factor)


_DECREASING = (1.2025, -15.0, 100.0)   # 1 at x_a = 1.5 cm, minimum 0.64 at 7.5 cm
_INCREASING = (0.7225, 20.0, -100.0)   # 1 at x_a = 1.5 cm, maximum 1.7225 at 10 cm
_c = _poly(1955.0, _DECREASING) + _poly(298.2 * 2.25, _DECREASING)
_k = _poly(500.0, _DECREASING) + (0.0, 0.0, 0.0)
_al = _poly(14000.0, _INCREASING) + _poly(69500.0 * 2.25, _INCREASING)

PROTOTYPE = AliRamaswamyParams(
    **{f"c{i + 1}": v for i, v in enumerate(_c)}, **{f"k{i + 1}": v for i, v in enumerate(_k)},
    **{f"alpha{i + 1}": v for i, v in enumerate(_al)},
    x_a=0.015, f0=-71.5, gamma=3.63e6, beta=3.63e6, A=301.0, n=2.0)


@register
class AliRamaswamy(BoucWenSaturation, DamperModel):
    name = "ali_ramaswamy"
    Params = AliRamaswamyParams
    state_names = ("z",)
    presets = {
        "spencer1997": Preset(PROTOTYPE, CommandSpec("A", 0.0, 1.0, 190.0),
                              "derived from the bouc_wen prototype set (command rescaled to 0-1 A) with "
                              "illustrative amplitude factors (see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = _project

    def coefficients(self, i_c: float = 0.0) -> tuple[float, float, float]:
        """(c, k, α) of eq. (21) at this damper's amplitude x_a and current i_c."""
        return self.params.coefficients(i_c)
