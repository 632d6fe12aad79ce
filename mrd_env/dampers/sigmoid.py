"""Sigmoid-function model, a function-based dynamic parametric model of the review's Table 4
("function-based models: ... sigmoid"); form of the current-dependent sigmoid model of Ma, Rakheja & Su
(2007) J. Intell. Mater. Syst. Struct. 18:487–502 (attribution and sign convention unverified)::

    F = F_y · (1 − e^{−β (ẋ − v_h sgn(ẍ))}) / (1 + e^{−β (ẋ − v_h sgn(ẍ))}) + c ẋ + f0
    F_y = F_ya + F_yb u,   c = c_a + c_b u

F_y is the yield force, β (s/m) the steepness of the sigmoid and v_h ≥ 0 the hysteresis half-width in
velocity: while the piston accelerates (ẍ > 0) the sigmoid term crosses zero at ẋ = +v_h, while it
decelerates at ẋ = −v_h, so the force lags the velocity as measured MR-damper loops do. The review gives
no equation: the form above, with F_y and c affine in the command (β, v_h, f0 command independent), is the
one chosen.
The sigmoid is evaluated as tanh(y/2), the same function without overflow for large |y|.

sgn(ẍ) is not taken from the ẍ argument of ``force`` (the plants pass ẍ = 0 there): it comes from an
internal filtered-velocity state v_f and is held, as the branch state σ, over each integration step
(:mod:`.acceleration_branch`: a continuous σ makes the coupled plant's equations unstable at the switch),

    v̇_f = (ẋ − v_f) / τ,    ẍ ≈ (ẋ − v_f) / τ,    σ ← tanh(((ẋ − v_f)/τ) / a_s) between steps

(a first-order lag of time constant τ; a_s = 0 gives the exact sign). The estimate lags ẍ by about τ and
is smoothed over accelerations of order a_s; the switch of sgn(ẍ) happens at the velocity extremes,
where the sigmoid is saturated, so both matter little. At constant velocity ẍ = 0 and the force settles
to the closed form F_y S(β ẋ) + c ẋ + f0 (S the sigmoid); for |ẋ| → ∞, F → ±F_y + c ẋ + f0.
States: v_f (m/s) and σ, zero at rest.

Preset ``spencer1997`` (derived, ``verified=False``): a least-squares fit (scipy ``least_squares``) of
F_ya, F_yb, c_a, c_b, β, v_h, f0 to the steady loops of the Spencer–Dyke prototype model at 1.5 cm,
2.5 Hz and 0, 0.75, 1.5, 2.25 V (τ = 2 ms and a_s = 0.5 m/s² fixed); force NRMSE of the fit 4.9 %;
peak forces within 12 N of the Spencer–Dyke ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb

from .acceleration_branch import branch, filter_rhs
from .base import DamperModel, DamperParams, FIXED_FILTER, FIXED_SMOOTHING, Preset, param, PROTOTYPE_COMMAND
from .registry import register


@dataclass(frozen=True)
class SigmoidParams(DamperParams):
    Fy_a: float = param(unit="N", lo=0.0, doc="yield force F_y, command-independent part")
    Fy_b: float = param(unit="N/cmd", lo=0.0, doc="F_y per unit command")
    c_a: float = param(unit="N·s/m", lo=0.0, doc="post-yield damping c, command-independent part")
    c_b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c per unit command")
    beta: float = param(unit="s/m", lo=0.0, lo_open=True, doc="steepness of the sigmoid (slope at 0: F_y β/2)")
    v_h: float = param(unit="m/s", lo=0.0, doc="hysteresis half-width in velocity")
    f0: float = param(unit="N", doc="force offset")
    tau: float = param(0.002, unit="s", lo=0.0, lo_open=True, doc="time constant of the velocity filter",
                       fixed=FIXED_FILTER)
    a_s: float = param(0.5, unit="m/s^2", lo=0.0, doc="acceleration over which sgn(ẍ) is smoothed (0 = exact)",
                       fixed=FIXED_SMOOTHING)


# the index of each parameter in p, in field order (SigmoidParams.index_constants();
# tests/dampers/test_param_indices.py)
P_FY_A, P_FY_B, P_C_A, P_C_B, P_BETA, P_V_H, P_F0, P_TAU, P_A_S = range(9)


@nb.njit(cache=True)
def sigmoid(y):
    """(1 − e^{−y}) / (1 + e^{−y}), evaluated as tanh(y/2)."""
    return math.tanh(0.5 * y)


@nb.njit(cache=True)
def _rhs(p, s, x, xd, u, ds):
    ds[0] = filter_rhs(xd, s[0], p[P_TAU])
    ds[1] = 0.0  # the branch is held over the step


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return ((p[P_FY_A] + p[P_FY_B] * u) * sigmoid(p[P_BETA] * (xd - p[P_V_H] * s[1]))
            + (p[P_C_A] + p[P_C_B] * u) * xd + p[P_F0])


@nb.njit(cache=True)
def _project(p, s, x, xd, u):
    s[1] = branch(xd, s[0], p[P_TAU], p[P_A_S])


PROTOTYPE = SigmoidParams(Fy_a=123.3, Fy_b=398.3, c_a=1766.0, c_b=340.6, beta=73.85, v_h=0.00464, f0=-71.94,
                          tau=0.002, a_s=0.5)


@register
class Sigmoid(DamperModel):
    name = "sigmoid"
    Params = SigmoidParams
    state_names = ("v_f", "sigma")
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "least-squares fit to the Spencer-Dyke prototype loops at 1.5 cm / 2.5 Hz "
                              "(derived, see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = _rhs
    force_law = _force
    project = _project
