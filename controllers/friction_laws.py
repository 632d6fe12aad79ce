"""Structural semi-active laws from the comparison of Jansen & Dyke (2000) that need only local signals."""
from __future__ import annotations

import numpy as np

from .base import Controller


def _stroke_sensors(env):
    names = {n for n, *_ in env.sensor_layout}
    if "travel" in names or "travel_rate" in names:
        return "travel", "travel_rate"
    return "damper_stroke", "damper_velocity"


class MaximumEnergyDissipation(Controller):
    """Maximum energy dissipation (Jansen & Dyke 2000, after McClamroch & Gavin 1995): full command when
    the damper force dissipates energy, u = u_max·H(f·ẋ_d) (f positive resisting extension, ẋ_d the damper
    velocity), otherwise u_min — it switches off where the hysteresis would push energy back in. f is the
    force beyond the damper's static preload."""

    name = "max_energy_dissipation"

    def required_sensors(self, env):
        return ("damper_force", _stroke_sensors(env)[1])

    def command(self, obs):
        v = self.sensor(obs, _stroke_sensors(self.env)[1])
        return self.on_off(self.dynamic_force(obs) * v > 0.0)


class ModulatedHomogeneousFriction(Controller):
    """Modulated homogeneous friction (Inaudi 1997; Jansen & Dyke 2000): u = u_max·H(g|P[Δ]| − |f|),
    P[Δ] the damper deformation at its most recent local extremum, g a gain in N/m (default: the storey
    stiffness order of 1e5 N/m for the lab building; 2e4 N/m for a quarter car)."""

    name = "modulated_friction"

    def __init__(self, env, gain: float | None = None):
        super().__init__(env)
        self.stroke, self.rate = _stroke_sensors(self.env)
        default = 2e4 if self.stroke == "travel" else 1e5
        self.gain = float(default if gain is None else gain)
        if not self.gain > 0:
            raise ValueError(f"gain must be > 0 N/m, got {gain}")
        self.reset()

    def required_sensors(self, env):
        return ("damper_force",) + _stroke_sensors(env)

    def reset(self):
        self._extremum = np.zeros(self.n_dampers)
        self._last_rate = np.zeros(self.n_dampers)

    def command(self, obs):
        x = self.sensor(obs, self.stroke)
        v = self.sensor(obs, self.rate)
        turned = (v * self._last_rate < 0.0) | (self._last_rate == 0.0)
        self._extremum = np.where(turned, x, self._extremum)
        self._last_rate = v
        return self.on_off(self.gain * np.abs(self._extremum) - np.abs(self.dynamic_force(obs)) > 0.0)
