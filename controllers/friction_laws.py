"""Structural semi-active laws from the comparison of Jansen & Dyke (2000) that need only local signals."""
from __future__ import annotations

import numpy as np

from .base import Controller


class MaximumEnergyDissipation(Controller):
    """Maximum energy dissipation (Jansen & Dyke 2000, after McClamroch & Gavin 1995): full command when
    the damper force dissipates energy, u = u_max·H(f·ẋ_d) (f positive resisting extension, ẋ_d the damper
    velocity), otherwise u_min — it switches off where the hysteresis would push energy back in. f is the
    force beyond the damper's static preload."""

    name = "max_energy_dissipation"
    needs_roles = ("damper_velocity", "damper_force")

    def command(self, obs):
        return self.on_off(self.dynamic_force(obs) * self.role(obs, "damper_velocity") > 0.0)


class ModulatedHomogeneousFriction(Controller):
    """Modulated homogeneous friction (Inaudi 1997; Jansen & Dyke 2000): u = u_max·H(g|P[Δ]| − |f|),
    P[Δ] the damper deformation at its most recent local extremum, g a gain in N/m (default: the stiffness
    scale of the plant, the largest diagonal entry of K over 10: 1.4·10⁵ N/m for the lab building, 2·10⁴ N/m
    for a quarter car)."""

    name = "modulated_friction"
    needs_roles = ("damper_stroke", "damper_velocity", "damper_force")

    def __init__(self, env, gain: float | None = None):
        super().__init__(env)
        K = self.env.linear_plant.K
        default = float(np.max(np.diag(K))) / 10.0
        self.gain = float(default if gain is None else gain)
        if not self.gain > 0:
            raise ValueError(f"gain must be > 0 N/m, got {gain}")

    def allocate(self, n_rows):
        super().allocate(n_rows)
        self._extremum = np.zeros((n_rows, self.n_dampers))
        self._last_rate = np.zeros((n_rows, self.n_dampers))

    def reset_rows(self, mask):
        self._extremum[mask] = 0.0
        self._last_rate[mask] = 0.0

    def command(self, obs):
        x = self.role(obs, "damper_stroke")
        v = self.role(obs, "damper_velocity")
        turned = (v * self._last_rate < 0.0) | (self._last_rate == 0.0)
        self._extremum = np.where(turned, x, self._extremum)
        self._last_rate = v
        return self.on_off(self.gain * np.abs(self._extremum) - np.abs(self.dynamic_force(obs)) > 0.0)
