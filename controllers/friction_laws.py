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


class DecentralizedBangBang(Controller):
    """Decentralised bang-bang (McClamroch & Gavin 1995, as compared by Jansen & Dyke 2000): each damper at full
    command when its force takes energy out of the structure's total vibratory energy, V = ½ xᵀK x + ½ ẋ_aᵀ M ẋ_a
    (ẋ_a = ẋ + 1·ẋ_g the floors' absolute velocities), else at u_min. With M ẍ_a + C ẋ + K x = −Sᵀ F the term of
    damper j in dV/dt is −(S_j ẋ_a)·F_j, so

        u_j = u_max·H((S_j ẋ_a)·f_j)  (the Lyapunov law's H(−z_aᵀ P B_j f_j) with P = ½ diag(K, M) in absolute
        coordinates),

    f_j the damper's force beyond its preload and S_j ẋ_a its stroke rate seen from the ground-fixed frame: the stroke
    rate plus the ground velocity for a damper on the ground (S_j·1 = 1), the stroke rate alone between two floors —
    there the law is :class:`MaximumEnergyDissipation`'s (which uses the energy relative to the ground). Each damper
    uses its own measurements only, and the ground velocity, integrated here from the measured ground acceleration
    (trapezoids at the control step, from rest at the episode's start). The absolute-energy form is derived here;
    the paper's equations were not available to check it against."""

    name = "decentralized_bang_bang"
    needs_roles = ("damper_velocity", "damper_force")
    requires = ("ground_acc",)

    def __init__(self, env):
        super().__init__(env)
        S = np.asarray(self.env.linear_plant.S, dtype=float)
        #: S_j·1: how much of the ground's velocity damper j's absolute stroke rate holds (1 on the ground, else 0)
        self.on_ground = S @ np.ones(S.shape[1])

    def allocate(self, n_rows):
        super().allocate(n_rows)
        self._ground_vel = np.zeros(n_rows)
        self._last_acc = np.zeros(n_rows)
        self._fresh = np.ones(n_rows, bool)

    def reset_rows(self, mask):
        self._ground_vel[mask] = 0.0
        self._fresh[mask] = True

    def command(self, obs):
        acc = self.sensor(obs, "ground_acc")[:, 0]
        step = np.where(self._fresh, 0.0, 0.5 * (acc + self._last_acc) * self.control_dt)
        self._ground_vel = self._ground_vel + step
        self._last_acc, self._fresh = acc, np.zeros_like(self._fresh)
        rate = self.role(obs, "damper_velocity") + self._ground_vel[:, None] * self.on_ground[None, :]
        return self.on_off(rate * self.dynamic_force(obs) > 0.0)
