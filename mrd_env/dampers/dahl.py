"""Dahl friction-operator model of an MR damper (Zhou, Qu et al. 2006 — attribution unverified), one of the
hysteresis-operator-based dynamic parametric models of the review's Table 4 ("Bouc–Wen, Dahl, LuGre")::

    F = c0 ẋ + k0 x + f_d z + f0
    ż = σ (ẋ − |ẋ| z)
    c0 = c0a + c0b u,   f_d = f_da + f_db u

z is the dimensionless Dahl friction state; from rest it stays in [−1, 1] (at z = ±1, ż = 0 when
moving outwards), so f_d is the Coulomb (yield) force and 1/σ the displacement over which it builds up
after a reversal: at constant velocity v > 0 from z = z(0), z = 1 − (1 − z(0)) e^{−σ (x − x(0))} and the
steady sliding force is c0 v + k0 x + f_d + f0. The command dependence (c0, f_d affine in u; σ, k0
command independent) and the offset f0 are the common form in the literature; the review gives no
equation.

The Dahl operator is the Bouc–Wen equation (8) with n = 1, β = 0, γ = A = σ (saturation 1), so the
shared Bouc–Wen machinery advances it and keeps z in [−1, 1] after each step. State: z (–).

Preset ``spencer1997`` (derived, ``verified=False``): a least-squares fit (scipy ``least_squares``) of
c0a, c0b, k0, f_da, f_db, σ, f0 to the steady loops of the Spencer–Dyke prototype model at 1.5 cm,
2.5 Hz and 0, 0.75, 1.5, 2.25 V; force NRMSE of the fit 8.4 % (peak forces within 55 N). The fitted
build-up length 1/σ = 9 µm is the displacement over which the prototype's force reverses at this
frequency.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import DamperModel, DamperParams, Preset, param, PROTOTYPE_COMMAND
from .hysteresis import bouc_wen_zdot, clip_to_saturation
from .registry import register


@dataclass(frozen=True)
class DahlParams(DamperParams):
    c0a: float = param(unit="N·s/m", lo=0.0, doc="viscous coefficient c0, command-independent part")
    c0b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c0 per unit command")
    k0: float = param(unit="N/m", lo=0.0, doc="stiffness (accumulator)")
    fd_a: float = param(unit="N", lo=0.0, doc="Dahl (Coulomb) force f_d, command-independent part")
    fd_b: float = param(unit="N/cmd", lo=0.0, doc="f_d per unit command")
    sigma: float = param(unit="1/m", lo=0.0, lo_open=True, doc="Dahl shape parameter σ (1/σ: build-up length)")
    f0: float = param(unit="N", doc="force offset")


# the index of each parameter in p, in field order (DahlParams.index_constants(); tests/dampers/test_param_indices.py)
P_C0A, P_C0B, P_K0, P_FD_A, P_FD_B, P_SIGMA, P_F0 = range(7)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    # ż = σ(ẋ − |ẋ| z): eq. (8) with A = γ = σ, β = 0, n = 1
    ds[0] = bouc_wen_zdot(s[0], xd, p[P_SIGMA], 0.0, p[P_SIGMA], 1.0)


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return (p[P_C0A] + p[P_C0B] * u) * xd + p[P_K0] * x + (p[P_FD_A] + p[P_FD_B] * u) * s[0] + p[P_F0]


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[0] = clip_to_saturation(s[0], p[P_SIGMA], 0.0, p[P_SIGMA], 1.0)


PROTOTYPE = DahlParams(c0a=1839.0, c0b=831.9, k0=3303.0, fd_a=109.2, fd_b=305.3, sigma=1.1e5, f0=-72.01)


@register
class Dahl(DamperModel):
    name = "dahl"
    Params = DahlParams
    state_names = ("z",)
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "least-squares fit to the Spencer-Dyke prototype loops at 1.5 cm / 2.5 Hz "
                              "(derived, see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = _project

    def saturation(self) -> float:
        """The bound of the Dahl state: |z| ≤ 1."""
        return 1.0
