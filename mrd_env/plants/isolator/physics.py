"""Single-degree-of-freedom MR isolator: a payload on a spring with an MR damper, on a moving base.

    m ẍ = −k (x − z_b) − c_p (ẋ − ż_b) − F,      stroke x_d = x − z_b (extension positive)

x the payload's absolute displacement from static equilibrium (up), z_b the base's (the floor of a cab, a
machine frame), F the damper force (positive resisting extension), c_p an optional viscous damper in parallel
with the MR damper. The damper acts between the payload and the base, so its stroke is a difference of the
payload's motion and an input; the plant is written, as the shear building is, in the coordinate relative to the
base, the stroke itself, driven by the base's acceleration::

    m ẍ_d + c_p ẋ_d + k x_d = −F − m z̈_b

(:class:`~mrd_env.mechanics.CoupledPlant` maps a damper's stroke from the coordinates alone, S q). The inputs are
w = (z_b, ż_b, z̈_b): the acceleration drives the plant, the base's displacement and velocity ride along (zero
columns of E) so that the payload's absolute motion x = x_d + z_b, ẋ = ẋ_d + ż_b and the base's velocity are
signals. The damper's static preload (an accumulator's k1·x0) is balanced by the spring's static deflection.

The linear limit — F = c ẋ_d, a plain dashpot — is the textbook base-excited oscillator: with ω_n = √(k/m),
ζ = (c + c_p) / (2 √(k m)) and r = ω/ω_n, the payload's displacement (and absolute acceleration) follows a
harmonic base motion with the transmissibility T(r) = √((1 + (2ζr)²) / ((1 − r²)² + (2ζr)²)), below 1 only above
r = √2 (``tests/plants/test_isolator.py`` checks the environment against it).

The parameter set "seat" is illustrative, not a published one: a suspension seat of a truck or an off-road
machine, carrying 100 kg (the seat's suspended frame and cushion with the part of the occupant's mass the seat
carries), on a spring tuned to 1.5 Hz — below the 4–8 Hz band where ISO 2631-1's Wk weighting is highest, so that
the seat can isolate there, and in the range suspension seats are usually tuned to (about 1.5–2 Hz). The damping
is left to the MR damper (c_p = 0).

The environment's default damper is the "automotive" Spencer–Dyke set (0–2 V, the cars' damper; its attribution
is unverified, see :mod:`mrd_env.dampers.spencer_dyke`). On the virtual rig at 1 cm and 1.5 Hz it gives about
140 N at 0 V and 830 N at 2 V — 0.14 and 0.85 times the payload's weight. Its yield force, α z_s with
z_s = √(A/(β + γ)), is about 64 N at 0 V and 460 N at 2 V: at full command the damper holds the payload to the base
for base accelerations up to about 4.6 m/s² (it can lock the isolator, not absurdly beyond what a seat meets);
at zero command up to about 0.6 m/s², the off-state friction MR seat dampers are known for. The prototype set
("spencer1997", 0–2.25 V) is stiffer still at 0 V (about 270 N at 1 cm and 1.5 Hz), too much for 100 kg.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...mechanics import LinearPlant, preset_with_overrides
from ...validation import check_scalar


@dataclass(frozen=True)
class IsolatorParams:
    m: float           # payload mass, kg
    k: float           # spring stiffness, N/m
    c_p: float = 0.0   # passive damper in parallel with the MR damper, N·s/m
    source: str = ""

    def __post_init__(self) -> None:
        check_scalar("IsolatorParams.m", self.m, 0.0, lo_open=True, unit="kg")
        check_scalar("IsolatorParams.k", self.k, 0.0, lo_open=True, unit="N/m")
        check_scalar("IsolatorParams.c_p", self.c_p, 0.0, unit="N·s/m")

    @property
    def natural_frequency(self) -> float:
        """f_n = √(k/m) / 2π, Hz."""
        return math.sqrt(self.k / self.m) / (2.0 * math.pi)

    def damping_ratio(self, c: float = 0.0) -> float:
        """ζ of the payload on its spring with a dashpot c (N·s/m) beside c_p."""
        return (c + self.c_p) / (2.0 * math.sqrt(self.k * self.m))

    def plant(self) -> LinearPlant:
        """The stroke x_d as the one coordinate, the base's acceleration (the third input) driving it."""
        return LinearPlant(M=np.array([[self.m]]), C=np.array([[self.c_p]]), K=np.array([[self.k]]),
                           S=np.array([[1.0]]), E=np.array([[0.0, 0.0, -self.m]]),
                           input_names=("z_b", "zdot_b", "zddot_b"), dof_names=("x_d",), mass_names=("m",))


#: The isolator's parameter sets (see the module docstring for the choice).
ISOLATOR_PRESETS = {
    "seat": IsolatorParams(m=100.0, k=8883.0,
                           source="illustrative suspension seat: 100 kg, 1.5 Hz (not a published set)"),
}


def isolator(preset: str = "seat", **overrides) -> IsolatorParams:
    """An isolator parameter set by name, with optional overrides (SI)."""
    return preset_with_overrides(ISOLATOR_PRESETS, preset, "isolator", overrides)
