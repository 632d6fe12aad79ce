"""Non-symmetrical Bouc–Wen model, review eqs. (22)–(24) (review ref. [45], parameters identified there by
a genetic algorithm)::

    F = c0 ẋ + k0 (x − x0) + α z                                             (7)
    ż = (A − (β + γ sgn(z ṽ)) |z|^n) ṽ,   ṽ = ẋ − μ sgn(x)                    (22)–(24)
    α = αa + αb u,  c0 = c0a + c0b u,  k0 = k0a + k0b u                       (9)

The review's eq. (23) is garbled (it reads "ẋ = (ẋ − μ sgn(x))"): it defines the shifted velocity ṽ that
drives the hysteresis, which is what eq. (24) uses. Eq. (22) is eq. (8) written differently
(γ |ṽ| z |z|^(n−1) = γ sgn(z ṽ) |z|^n ṽ), so the shared Bouc–Wen machinery is used with ṽ in place of
ẋ, and z keeps the saturation z_s = (A/(β+γ))^(1/n).

What μ does: z reverses where ṽ = 0, i.e. at ẋ = μ sgn(x) instead of at ẋ = 0. With this library's
signs (x positive in extension, F positive resisting it), μ > 0 makes the hysteretic force fall before the
stroke reverses (on the x > 0 side once ẋ < μ) — it mimics the force roll-off near zero velocity — and
μ < 0 delays its reversal until the piston moves back faster than |μ| (a larger lag). The force–velocity
loop is thereby shifted by μ near zero velocity (the "shifted hysteresis" of the review); because sgn is
odd the loop stays point-symmetric, F(−x, −ẋ) = −F(x, ẋ) for x0 = 0. μ = 0 gives the ``bouc_wen``
model. Caution when coupling to a plant: for |ẋ| < |μ| the term μ sgn(x) keeps driving z, so the model
is not passive near standstill — with μ > 0 a damper held off centre builds up a force of up to α z_s
pushing it further off centre (a spurious static force), with μ < 0 one pulling it back to x = 0.

sgn(x) is smoothed as tanh(x / x_s) with the displacement scale x_s (m; x_s = 0 gives the exact,
discontinuous sign): the shift fades in over |x| ≲ x_s around mid-stroke, which keeps ż continuous for the
implicit stepping routine. The review leaves the command dependence out: the affine form of eq. (9)
(command-independent β, γ, A, n, μ) is used. State: z (m).

Preset ``spencer1997`` (derived, ``verified=False``): the ``bouc_wen`` prototype set with x_s = 1 mm and
μ = 0.009 m/s, the value that minimises the force NRMSE against the Spencer–Dyke prototype's steady loops
at 1.5 cm, 2.5 Hz and 0, 0.75, 1.5, 2.25 V with everything else fixed (12.5 %, against 13.8 % for μ = 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from .base import DamperModel, FIXED_SMOOTHING, Preset, param, smooth_sign, PROTOTYPE_COMMAND
from .hysteresis import BoucWenSaturation, bouc_wen_zdot
from .bouc_wen import BoucWen, BoucWenParams
from .registry import register
from ..validation import check_scalar


@dataclass(frozen=True)
class NonsymmetricBoucWenParams(BoucWenParams):
    """The Bouc–Wen parameters of eqs. (7)–(9) plus the velocity shift of eq. (24)."""

    mu: float = param(unit="m/s", doc="velocity shift μ of eq. (24): z reverses at ẋ = μ sgn(x)")
    x_s: float = param(0.001, unit="m", lo=0.0, doc="displacement over which sgn(x) is smoothed (0 = exact)",
                       fixed=FIXED_SMOOTHING)



# the index of each parameter in p, in field order (checked by tests/dampers/test_param_indices.py)
P_C0A, P_C0B, P_K0A, P_K0B, P_X0, P_ALPHA_A, P_ALPHA_B, P_GAMMA, P_BETA, P_A, P_N, P_MU, P_X_S = range(13)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    v = xd - p[P_MU] * smooth_sign(x, p[P_X_S])
    ds[0] = bouc_wen_zdot(s[0], v, p[P_A], p[P_BETA], p[P_GAMMA], p[P_N])


# force law (eq. 7) and saturation of z are those of the plain Bouc–Wen model
_force = BoucWen.force_law
_project = BoucWen.project


PROTOTYPE = NonsymmetricBoucWenParams(
    c0a=1955.0, c0b=298.2, k0a=500.0, k0b=0.0, x0=0.143, alpha_a=14000.0, alpha_b=69500.0,
    gamma=3.63e6, beta=3.63e6, A=301.0, n=2.0, mu=0.009, x_s=0.001)


@register
class NonsymmetricBoucWen(BoucWenSaturation, DamperModel):
    name = "nonsymmetric_bouc_wen"
    Params = NonsymmetricBoucWenParams
    state_names = ("z",)
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "derived from the bouc_wen prototype set with the velocity shift mu fitted to "
                              "the Spencer-Dyke prototype loops (see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = _project

    def rest_state(self, x: float) -> np.ndarray:
        """At ẋ = 0 the shift ṽ = −μ sgn(x) keeps driving z off centre (the model is not passive near standstill):
        ż = 0 only at the saturation z = z_s sgn(ṽ), which z reaches and keeps; z = 0 where ṽ = 0 (x = 0)."""
        p = self.params
        v = -p.mu * float(smooth_sign(check_scalar("x", x, unit="m"), p.x_s))
        return np.array([float(np.sign(v)) * self.saturation()])
