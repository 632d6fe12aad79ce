"""Bingham model, review eq. (2): F = f_c sgn(ẋ) + c0 ẋ + f0.

sgn is smoothed as tanh(ẋ / v_s) with the smoothing velocity v_s (m/s; v_s = 0 gives the exact, discontinuous
sign, whose jump at zero velocity is 2 f_c). Command dependence (common literature form):
f_c = f_ca + f_cb u, c0 = c0a + c0b u. No internal states.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb

from .base import (DamperModel, DamperParams, FIXED_SMOOTHING, Preset, no_projection, no_states_rhs, param, smooth_sign,
                   PROTOTYPE_COMMAND)
from .registry import register


@dataclass(frozen=True)
class BinghamParams(DamperParams):
    fc_a: float = param(unit="N", lo=0.0, doc="friction (yield) force f_c, command-independent part")
    fc_b: float = param(unit="N/cmd", lo=0.0, doc="f_c per unit command")
    c0a: float = param(unit="N·s/m", lo=0.0, doc="post-yield damping c0, command-independent part")
    c0b: float = param(unit="N·s/(m·cmd)", lo=0.0, doc="c0 per unit command")
    f0: float = param(unit="N", doc="force offset (accumulator)")
    v_s: float = param(0.01, unit="m/s", lo=0.0, doc="velocity over which sgn(ẋ) is smoothed (0 = exact sign)",
                       fixed=FIXED_SMOOTHING)


# the index of each parameter in p, in field order (BinghamParams.index_constants();
# tests/dampers/test_param_indices.py)
P_FC_A, P_FC_B, P_C0A, P_C0B, P_F0, P_V_S = range(6)


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return (p[P_FC_A] + p[P_FC_B] * u) * smooth_sign(xd, p[P_V_S]) + (p[P_C0A] + p[P_C0B] * u) * xd + p[P_F0]


# Large-velocity asymptote of the Spencer–Dyke prototype: f_c = α(u) z_s with z_s = (A/(β+γ))^(1/2) =
# 6.439 mm, c0 = c0 c1/(c0 + c1) at 0 and 2.25 V, f0 = −k1 x0 (derived, not published).
PROTOTYPE = BinghamParams(fc_a=90.15, fc_b=447.5, c0a=1955.0, c0b=298.2, f0=-71.5, v_s=0.01)


@register
class Bingham(DamperModel):
    name = "bingham"
    Params = BinghamParams
    state_names = ()
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "large-velocity asymptote of the Spencer–Dyke prototype set (derived)",
                              verified=False),
    }
    default_preset = "spencer1997"
    rhs = no_states_rhs
    force_law = _force
    project = no_projection
