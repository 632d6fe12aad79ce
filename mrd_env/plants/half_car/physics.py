"""Half car (pitch plane) with MR dampers at the front and rear suspensions.

Coordinates q = [z_s, θ, z_uf, z_ur]: heave of the body's centre of mass (up), pitch (rad, positive nose down:
the body above the front axle is at z_s − aθ), front and rear unsprung displacements. The suspension strokes are x_f = z_s − a θ − z_uf and x_r = z_s + b θ − z_ur
(a, b the distances of the front and rear axles from the centre of mass; extension positive)::

    m_s z̈_s   = −Σ (k_s,i x_i + c_p,i ẋ_i + F_i)
    I_y θ̈     = a (k_s,f x_f + c_p,f ẋ_f + F_f) − b (k_s,r x_r + c_p,r ẋ_r + F_r)
    m_u,i z̈_u,i = k_s,i x_i + c_p,i ẋ_i + F_i − k_t,i (z_u,i − z_r,i)

The road inputs are w = [z_rf, ż_rf, z_rr, ż_rr]; the rear wheel meets the front wheel's road (a + b)/speed later.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...constants import GRAVITY
from ...validation import check_scalar
from ...mechanics import LinearPlant, preset_with_overrides


@dataclass(frozen=True)
class HalfCarParams:
    m_s: float     # body mass, kg
    I_y: float     # body pitch inertia, kg·m²
    m_uf: float    # front unsprung mass, kg
    m_ur: float    # rear unsprung mass, kg
    k_sf: float    # front suspension stiffness, N/m
    k_sr: float    # rear suspension stiffness, N/m
    k_tf: float    # front tyre stiffness, N/m
    k_tr: float    # rear tyre stiffness, N/m
    a: float       # centre of mass to front axle, m
    b: float       # centre of mass to rear axle, m
    c_pf: float = 0.0  # passive damping beside the front MR damper, N·s/m
    c_pr: float = 0.0  # passive damping beside the rear MR damper, N·s/m
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("m_s", "I_y", "m_uf", "m_ur", "k_sf", "k_sr", "k_tf", "k_tr", "a", "b"):
            check_scalar(f"HalfCarParams.{name}", getattr(self, name), 0.0, lo_open=True)
        for name in ("c_pf", "c_pr"):
            check_scalar(f"HalfCarParams.{name}", getattr(self, name), 0.0)

    @property
    def wheelbase(self) -> float:
        return self.a + self.b

    @property
    def static_tyre_loads(self) -> np.ndarray:
        """(front, rear) static tyre loads, N."""
        g = GRAVITY
        return np.array([self.m_s * g * self.b / self.wheelbase + self.m_uf * g,
                         self.m_s * g * self.a / self.wheelbase + self.m_ur * g])

    def plant(self) -> LinearPlant:
        # strokes x = S q; suspension forces act along the strokes, the tyres on the unsprung masses
        S = np.array([[1.0, -self.a, -1.0, 0.0], [1.0, self.b, 0.0, -1.0]])
        Ks = np.diag([self.k_sf, self.k_sr])
        Cs = np.diag([self.c_pf, self.c_pr])
        Kt = np.zeros((4, 4))
        Kt[2, 2], Kt[3, 3] = self.k_tf, self.k_tr
        E = np.zeros((4, 4))
        E[2, 0], E[3, 2] = self.k_tf, self.k_tr
        return LinearPlant(M=np.diag([self.m_s, self.I_y, self.m_uf, self.m_ur]), C=S.T @ Cs @ S,
                           K=S.T @ Ks @ S + Kt, S=S, E=E, input_names=("z_rf", "zdot_rf", "z_rr", "zdot_rr"),
                           dof_names=("z_s", "theta", "z_uf", "z_ur"),
                           mass_names=("m_s", "I_y", "m_uf", "m_ur"))


#: A mid-size passenger car in the pitch plane (illustrative values of the vehicle-dynamics literature,
#: unverified attribution).
HALF_CAR_PRESETS = {
    "sedan": HalfCarParams(m_s=690.0, I_y=1222.0, m_uf=40.0, m_ur=45.0, k_sf=18000.0, k_sr=22000.0,
                           k_tf=192000.0, k_tr=192000.0, a=1.3, b=1.5, source="illustrative sedan (unverified)"),
}


def half_car(preset: str = "sedan", **overrides) -> HalfCarParams:
    """A half-car parameter set by name, with optional overrides (SI)."""
    return preset_with_overrides(HALF_CAR_PRESETS, preset, "half-car", overrides)
