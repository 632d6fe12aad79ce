"""Hyperbolic-tangent model (Kwok, Ha, Nguyen, Li & Samali 2006, Sensors and Actuators A 132:441–451 —
volume and pages unverified),
a function-based dynamic parametric model of the review's Table 4 ("function-based models: hyperbolic
tangent")::

    F = c ẋ + k x + α tanh(β ẋ + δ sgn(x)) + f0
    c = c_a + c_b u,   α = α_a + α_b u

α tanh(·) is the hysteretic (yield) force, c ẋ the post-yield viscous force, k x the accumulator spring and
f0 the force offset; δ sgn(x) shifts the tanh curve by δ/β in velocity with the sign of the displacement,
which opens the force–velocity loop without an internal state (for δ > 0 the force lags the velocity:
on the branch leaving x = −X the force crosses zero at ẋ = +δ/β). The review gives no equation: the form
above is Kwok et al.'s, with the command dependence in the common literature form (c and α affine in u;
β, δ, k, f0 command independent). sgn(x) is smoothed as tanh(x / x_s) (x_s = 0: exact sign). No internal
states. At constant velocity and |x| ≫ x_s the force is the closed form above; for |ẋ| → ∞ it tends to
c ẋ + k x ± α + f0. At standstill off centre the δ term leaves a force α tanh(δ) sgn(x) pulling towards
x = 0 (a property of the model's position-dependent hysteresis).

Preset ``spencer1997`` (derived, ``verified=False``): a least-squares fit (scipy ``least_squares``) of
c_a, c_b, α_a, α_b, β, δ, k, f0 to the steady loops of the Spencer–Dyke prototype model at 1.5 cm,
2.5 Hz and 0, 0.75, 1.5, 2.25 V (x_s fixed at 1 mm); force NRMSE of the fit 2.6 %. The fit puts most of
the loop opening into k = 4230 N/m (close to the prototype's k0 = 4690 N/m) and leaves a small shift
δ/β = 1.3 mm/s; peak forces are within 10 N of the Spencer–Dyke ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb

from .base import (DamperModel, DamperParams, FIXED_SMOOTHING, Preset, no_projection, no_states_rhs, param, smooth_sign,
                   PROTOTYPE_COMMAND)
from .registry import register


@dataclass(frozen=True)
class HyperbolicTangentParams(DamperParams):
    c_a: float = param(unit="N·s/m", lo=0.0, doc="post-yield damping c, command-independent part")
    c_b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c per unit command")
    k: float = param(unit="N/m", lo=0.0, doc="stiffness (accumulator)")
    alpha_a: float = param(unit="N", lo=0.0, doc="hysteretic force amplitude α, command-independent part")
    alpha_b: float = param(unit="N/cmd", lo=0.0, doc="α per unit command")
    beta: float = param(unit="s/m", lo=0.0, lo_open=True, doc="velocity scale of the tanh (its slope at 0 is αβ)")
    delta: float = param(unit="-", lo=0.0, doc="hysteresis shift δ (loop half-width in velocity δ/β)")
    f0: float = param(unit="N", doc="force offset")
    x_s: float = param(0.001, unit="m", lo=0.0, doc="displacement over which sgn(x) is smoothed (0 = exact)",
                       fixed=FIXED_SMOOTHING)


# the index of each parameter in p, in field order (checked by tests/dampers/test_param_indices.py)
P_C_A, P_C_B, P_K, P_ALPHA_A, P_ALPHA_B, P_BETA, P_DELTA, P_F0, P_X_S = range(9)


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return ((p[P_C_A] + p[P_C_B] * u) * xd + p[P_K] * x
            + (p[P_ALPHA_A] + p[P_ALPHA_B] * u) * math.tanh(p[P_BETA] * xd + p[P_DELTA] * smooth_sign(x, p[P_X_S]))
            + p[P_F0])


PROTOTYPE = HyperbolicTangentParams(c_a=1811.0, c_b=337.2, k=4230.0, alpha_a=114.9, alpha_b=398.8, beta=37.92,
                                    delta=0.0481, f0=-71.95, x_s=0.001)


@register
class HyperbolicTangent(DamperModel):
    name = "hyperbolic_tangent"
    Params = HyperbolicTangentParams
    state_names = ()
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "least-squares fit to the Spencer-Dyke prototype loops at 1.5 cm / 2.5 Hz "
                              "(derived, see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = no_states_rhs
    force_law = _force
    project = no_projection
