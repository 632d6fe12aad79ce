"""LuGre friction-operator model of an MR damper (Jiménez & Álvarez-Icaza 2005, Struct. Control Health
Monit. 12:91–116 — form as recalled, attribution of the details unverified), one of the
hysteresis-operator-based dynamic parametric models of the review's Table 4 ("Bouc–Wen, Dahl, LuGre")::

    ż = ẋ − σ0 a0 |ẋ| z
    F = (σ0 + σ0b u) z + σ1 ż + (σ2a + σ2b u) ẋ + f0

z (m) is the mean deflection of the LuGre bristles, σ0 their stiffness (N/m), σ1 the bristle damping and
σ2 the viscous damping. The bristle equation has no Stribeck term (a0 is the inverse of the Coulomb force,
1/N): from rest z stays inside ±z_max with z_max = 1/(σ0 a0), and at constant velocity v the force settles
to the closed form (1 + (σ0b/σ0) u) sgn(v) / a0 + (σ2a + σ2b u) v + f0. As in Jiménez & Álvarez-Icaza,
the command scales the bristle force in the force equation while the bristle dynamics stay command
independent; the affine form (σ0 + σ0b u), which keeps a field-off yield force, the command-dependent
viscous term and the offset f0 are the choices made here (the review gives no equation).

The bristle equation is the Bouc–Wen equation (8) with n = 1, β = 0, A = 1, γ = σ0 a0, so the shared
Bouc–Wen machinery advances it and keeps z within ±z_max after each step. State: z (m).

Preset ``spencer1997`` (derived, ``verified=False``): a least-squares fit (scipy ``least_squares``) of
σ0, σ0b, a0, σ1, σ2a, σ2b, f0 to the steady loops of the Spencer–Dyke prototype model at 1.5 cm,
2.5 Hz and 0, 0.75, 1.5, 2.25 V; force NRMSE of the fit 9.0 % (peak forces within 50 N). Fitted:
Coulomb force 1/a0 = 120 N at 0 V rising by 308 N/V, z_max = 22 µm, and a bristle damping σ1 = 14 kN·s/m
that plays the part of the prototype's series dashpot near the reversals.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import DamperModel, DamperParams, Preset, param, PROTOTYPE_COMMAND
from .hysteresis import bouc_wen_zdot, clip_to_saturation
from .registry import register


@dataclass(frozen=True)
class LuGreParams(DamperParams):
    sigma0: float = param(unit="N/m", lo=0.0, lo_open=True, doc="bristle stiffness σ0 (at zero command)")
    sigma0b: float = param(unit="N/(m·cmd)", lo=0.0, doc="bristle stiffness in the force, per unit command")
    a0: float = param(unit="1/N", lo=0.0, lo_open=True, doc="inverse Coulomb force at zero command")
    sigma1: float = param(unit="N·s/m", lo=0.0, doc="bristle damping σ1")
    sigma2a: float = param(unit="N·s/m", lo=0.0, doc="viscous damping σ2, command-independent part")
    sigma2b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="σ2 per unit command")
    f0: float = param(unit="N", doc="force offset")


# the index of each parameter in p, in field order (LuGreParams.index_constants(); tests/dampers/test_param_indices.py)
P_SIGMA0, P_SIGMA0B, P_A0, P_SIGMA1, P_SIGMA2A, P_SIGMA2B, P_F0 = range(7)


@nb.njit(cache=True)
def _zdot(p, z, xd):
    # ż = ẋ − σ0 a0 |ẋ| z: eq. (8) with A = 1, β = 0, γ = σ0 a0, n = 1
    return bouc_wen_zdot(z, xd, 1.0, 0.0, p[P_SIGMA0] * p[P_A0], 1.0)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    ds[0] = _zdot(p, s[0], xd)


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return ((p[P_SIGMA0] + p[P_SIGMA0B] * u) * s[0] + p[P_SIGMA1] * _zdot(p, s[0], xd)
            + (p[P_SIGMA2A] + p[P_SIGMA2B] * u) * xd + p[P_F0])


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[0] = clip_to_saturation(s[0], 1.0, 0.0, p[P_SIGMA0] * p[P_A0], 1.0)


PROTOTYPE = LuGreParams(sigma0=5.39e6, sigma0b=1.388e7, a0=8.363e-3, sigma1=14040.0, sigma2a=1782.0, sigma2b=819.5,
                        f0=-72.01)


@register
class LuGre(DamperModel):
    name = "lugre"
    Params = LuGreParams
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
        """z_max = 1/(σ0 a0) in m: the bound of the bristle deflection."""
        return 1.0 / (self.params.sigma0 * self.params.a0)
