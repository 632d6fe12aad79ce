"""Bi-viscous model (Stanway et al.; Wereley, Pang & Kamath 1998), review eqs. (5)–(6).

The force–velocity curve has a pre-yield branch of slope c_pre and two post-yield branches of slope c_ps::

    F = c_ps ẋ + F_yield        ẋ ≥ v_yield
    F = c_pre ẋ                 −v_yield ≤ ẋ ≤ v_yield                      (5)
    F = c_ps ẋ − F_yield        ẋ ≤ −v_yield

    v_yield = F_yield / (c_pre − c_ps)                                       (6)

which is continuous at ±v_yield (c_pre v_yield = c_ps v_yield + F_yield) and is implemented in the
equivalent clipped form F = c_ps ẋ + clip((c_pre − c_ps) ẋ, −F_yield, F_yield) + f0 (no division, so
F_yield = 0 is the Newtonian limit F = c_ps ẋ). No internal states.

Where the review is silent (common literature form, stated here):

* command dependence — linear in the effective command u, as for the Bingham model:
  F_yield = fy_a + fy_b u, c_ps = c_ps_a + c_ps_b u, c_pre = c_pre_a + c_pre_b u; the model requires
  c_pre(u) > c_ps(u) over the whole command range, checked when the damper is built;
* a force offset f0 (the accumulator preload, as in the Bingham model eq. (2)); eq. (5) has none, so
  f0 = 0 gives eq. (5) exactly.

Shared helpers defined here: :func:`bi_viscous_curve` (the clipped three-segment curve with a velocity shift,
also used by :mod:`.hysteretic_bi_viscous`), and :class:`CommandRangeChecked` with :func:`command_grid`
(constraints that depend on the command, checked over the preset's command range; also used by
:mod:`.hysteretic_bi_viscous` and :mod:`.dominguez`).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numba as nb
import numpy as np

from .base import CommandSpec, DamperModel, DamperParams, Preset, no_projection, no_states_rhs, param, PROTOTYPE_COMMAND
from .registry import register


# the index of each parameter in p, in field order (BiViscousParams.index_constants();
# tests/dampers/test_param_indices.py)
P_FY_A, P_FY_B, P_C_PS_A, P_C_PS_B, P_C_PRE_A, P_C_PRE_B, P_F0 = range(7)


@nb.njit(cache=True)
def bi_viscous_curve(v, c_pre, c_ps, f_yield, v_shift):
    """c_ps v + clip((c_pre − c_ps) v − c_pre v_shift, −F_yield, F_yield).

    v_shift = 0: the bi-viscous curve, eq. (5). v_shift = ±v0: the pre-yield line c_pre (v − v_shift) of the
    hysteretic bi-viscous model, which meets the post-yield lines c_ps v ± F_yield where it is clipped.
    """
    r = (c_pre - c_ps) * v - c_pre * v_shift
    if r > f_yield:
        r = f_yield
    elif r < -f_yield:
        r = -f_yield
    return c_ps * v + r


def command_grid(command: CommandSpec, n: int = 201) -> np.ndarray:
    """Commands at which range-dependent parameter constraints are checked (the whole preset range)."""
    return np.linspace(command.v_min, command.v_max, n)


@dataclass(frozen=True)
class BiViscousParams(DamperParams):
    fy_a: float = param(unit="N", lo=0.0, doc="yield force F_yield, command-independent part")
    fy_b: float = param(unit="N/cmd", doc="F_yield per unit command")
    c_ps_a: float = param(unit="N·s/m", lo=0.0, doc="post-yield damping c_ps, command-independent part")
    c_ps_b: float = param(unit="N·s/(m·cmd)", doc="c_ps per unit command")
    c_pre_a: float = param(unit="N·s/m", lo=0.0, lo_open=True, doc="pre-yield damping c_pre, command-independent part")
    c_pre_b: float = param(unit="N·s/(m·cmd)", doc="c_pre per unit command")
    f0: float = param(0.0, unit="N", doc="force offset (accumulator); 0 in eq. (5)")

    def check(self) -> None:
        if self.c_pre_a <= self.c_ps_a:
            raise ValueError(f"BiViscousParams: c_pre_a = {self.c_pre_a:g} must be > c_ps_a = {self.c_ps_a:g} "
                             "(pre-yield damping above post-yield damping, eq. (6))")


@nb.njit(cache=True)
def _force(p, s, x, xd, xdd, u):
    return bi_viscous_curve(xd, p[P_C_PRE_A] + p[P_C_PRE_B] * u, p[P_C_PS_A] + p[P_C_PS_B] * u,
                            p[P_FY_A] + p[P_FY_B] * u, 0.0) + p[P_F0]


# Derived preset (not published): least-squares fit of the linear-in-command eq. (5) to the steady force
# record of the Spencer–Dyke prototype set (one cycle each at 1.5 cm / 2.5 Hz, 0, 0.75, 1.5 and 2.25 V,
# simulated at 0.1 ms), with f0 fixed to that set's preload −k1 x0 = −71.5 N; force RMS residual 50 N (the
# bi-viscous curve has no hysteresis); peak forces 478 ... 1549 N (prototype: 478 ... 1548 N).
PROTOTYPE = BiViscousParams(fy_a=79.8, fy_b=407.6, c_ps_a=1994.0, c_ps_b=289.3, c_pre_a=24330.0, c_pre_b=1679.0,
                            f0=-71.5)


class CommandRangeChecked(DamperModel, ABC):
    """A model whose parameter constraints depend on the command (e.g. c_pre(u) > c_ps(u)): they are checked
    over the whole command range once the damper is built (the parameter dataclass does not know the range).
    Subclasses implement :meth:`check_command_range`, raising ``ValueError`` that names the fields."""

    def __init__(self, params=None, command=None, preset=None):
        super().__init__(params, command, preset)
        self.check_command_range()

    @abstractmethod
    def check_command_range(self) -> None:
        """Implemented by each subclass."""


@register
class BiViscous(CommandRangeChecked):
    name = "bi_viscous"
    Params = BiViscousParams
    state_names = ()
    presets = {
        "spencer1997": Preset(PROTOTYPE, PROTOTYPE_COMMAND,
                              "fit of eq. (5) to the Spencer–Dyke prototype's loops at 1.5 cm / 2.5 Hz "
                              "(derived, see module source)", verified=False),
    }
    default_preset = "spencer1997"
    rhs = no_states_rhs
    force_law = _force
    project = no_projection

    def coefficients(self, u):
        """(F_yield, c_ps, c_pre) at effective command(s) u."""
        p = self.params
        u = np.asarray(u, dtype=np.float64)
        return p.fy_a + p.fy_b * u, p.c_ps_a + p.c_ps_b * u, p.c_pre_a + p.c_pre_b * u

    def yield_velocity(self, u):
        """v_yield = F_yield / (c_pre − c_ps), eq. (6) (m/s)."""
        fy, cps, cpre = self.coefficients(u)
        return fy / (cpre - cps)

    def check_command_range(self) -> None:
        fy, cps, cpre = self.coefficients(command_grid(self.command))
        c = self.command
        if np.any(fy < 0.0):
            raise ValueError(f"BiViscousParams: fy_a + fy_b·u must be >= 0 over the command range "
                             f"[{c.v_min:g}, {c.v_max:g}] {c.unit} (min {fy.min():g} N)")
        if np.any(cps < 0.0):
            raise ValueError(f"BiViscousParams: c_ps_a + c_ps_b·u must be >= 0 over the command range "
                             f"[{c.v_min:g}, {c.v_max:g}] {c.unit} (min {cps.min():g} N·s/m)")
        if np.any(cpre <= cps):
            raise ValueError(f"BiViscousParams: c_pre (c_pre_a + c_pre_b·u) must be > c_ps (c_ps_a + c_ps_b·u) "
                             f"over the command range [{c.v_min:g}, {c.v_max:g}] {c.unit}")
