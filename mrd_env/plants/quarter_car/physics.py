"""Quarter-car model with an MR damper between sprung and unsprung masses.

    m_s z̈_s = −k_s (z_s − z_u) − c_p (ż_s − ż_u) − F
    m_u z̈_u =  k_s (z_s − z_u) + c_p (ż_s − ż_u) + F − k_t (z_u − z_r) − c_t (ż_u − ż_r)

z_s, z_u absolute vertical displacements from static equilibrium, z_r the road; damper stroke
x = z_s − z_u (extension positive). c_p is an optional passive damper in parallel with the MR damper,
c_t the tyre damping.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...constants import GRAVITY
from ...validation import check_scalar
from ...mechanics import LinearPlant, preset_with_overrides


@dataclass(frozen=True)
class QuarterCarParams:
    m_s: float   # sprung mass, kg
    m_u: float   # unsprung mass, kg
    k_s: float   # suspension stiffness, N/m
    k_t: float   # tyre stiffness, N/m
    c_t: float = 0.0   # tyre damping, N·s/m
    c_p: float = 0.0   # passive damper in parallel with the MR damper, N·s/m
    passive_c: float = 0.0  # the set's reference passive damping (for comparisons), N·s/m
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("m_s", "m_u", "k_s", "k_t"):
            check_scalar(f"QuarterCarParams.{name}", getattr(self, name), 0.0, lo_open=True,
                         unit="kg" if name.startswith("m") else "N/m")
        for name in ("c_t", "c_p", "passive_c"):
            check_scalar(f"QuarterCarParams.{name}", getattr(self, name), 0.0, unit="N·s/m")

    @property
    def static_tyre_load(self) -> float:
        """(m_s + m_u)·g in N."""
        return (self.m_s + self.m_u) * GRAVITY

    def plant(self) -> LinearPlant:
        ms, mu, ks, kt, ct, cp = self.m_s, self.m_u, self.k_s, self.k_t, self.c_t, self.c_p
        return LinearPlant(
            M=np.diag([ms, mu]),
            C=np.array([[cp, -cp], [-cp, cp + ct]]),
            K=np.array([[ks, -ks], [-ks, ks + kt]]),
            S=np.array([[1.0, -1.0]]),
            E=np.array([[0.0, 0.0], [kt, ct]]),
            input_names=("z_r", "zdot_r"),
            dof_names=("z_s", "z_u"),
            mass_names=("m_s", "m_u"),
        )


#: The three parameter sets of MR-suspension studies on the reference page (section 3).
QUARTER_CAR_PRESETS = {
    "set_a": QuarterCarParams(320.0, 40.0, 22000.0, 190000.0, passive_c=1500.0, source="reference set A"),
    "set_b": QuarterCarParams(250.0, 20.0, 20000.0, 140000.0, passive_c=1000.0, source="reference set B"),
    "set_c": QuarterCarParams(240.0, 36.0, 16000.0, 160000.0, passive_c=1000.0, source="reference set C"),
}


def quarter_car(preset: str = "set_a", **overrides) -> QuarterCarParams:
    """A quarter-car parameter set by name, with optional overrides (SI)."""
    return preset_with_overrides(QUARTER_CAR_PRESETS, preset, "quarter-car", overrides)
