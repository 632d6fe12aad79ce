"""Velocity-feedback semi-active laws: skyhook, groundhook and hybrid (reference page section 7).

Quarter car: ż_s sprung velocity (sensor ``sprung_vel``), ż_u unsprung velocity (``unsprung_vel``),
v_rel = ż_s − ż_u across the damper (``travel_rate``). Building analogue of skyhook: the velocity of the
floor above each damper relative to the ground (``floor_vel``) stands for ż_s and ``damper_velocity``
for v_rel.
"""
from __future__ import annotations

import numpy as np

from .base import Controller


def _is_building(env) -> bool:
    """Ground-motion-driven plants (shear buildings) take the structural analogue of the laws."""
    return tuple(env.linear_plant.input_names) == ("xg_ddot",)


class _VelocityLaw(Controller):
    def required_sensors(self, env):
        if _is_building(env):
            return ("floor_vel", "damper_velocity")
        return self.requires

    def body_velocity(self, obs):
        """ż_s: sprung (or the damper's upper floor) velocity, one per damper."""
        if "sprung_vel" in self.layout:
            return self.sensor(obs, "sprung_vel")
        floors = np.asarray(self.env.plant_params.damper_floors) - 1
        return self.sensor(obs, "floor_vel")[floors]

    def relative_velocity(self, obs):
        if "travel_rate" in self.layout:
            return self.sensor(obs, "travel_rate")
        return self.sensor(obs, "damper_velocity")


class SkyhookOnOff(_VelocityLaw):
    """On–off skyhook (Karnopp, Crosby & Harwood 1974): u = u_max if ż_s·v_rel ≥ 0 else u_min."""

    name = "skyhook_on_off"
    requires = ("sprung_vel", "travel_rate")

    def command(self, obs):
        return self.on_off(self.body_velocity(obs) * self.relative_velocity(obs) >= 0.0)


class SkyhookContinuous(_VelocityLaw):
    """Continuous skyhook: u = clip(c_sky |ż_s| / κ) if ż_s·v_rel ≥ 0 else u_min, with κ (N per command
    unit) the damper's force gain per unit command, so the damper aims at the skyhook force c_sky ż_s.

    ``c_sky`` in N·s/m (default 1000: on ISO random roads the Wk weighting favours low damping above the
    body mode, so a mild skyhook gain keeps the 4–8 Hz band soft); ``force_per_command`` κ defaults to an
    estimate from the damper model (steady force difference between u_max and u_min at 0.1 m/s).
    """

    name = "skyhook_continuous"
    requires = ("sprung_vel", "travel_rate")

    def __init__(self, env, c_sky: float = 1000.0, force_per_command: float | None = None):
        super().__init__(env)
        if not c_sky > 0:
            raise ValueError(f"c_sky must be > 0 N·s/m, got {c_sky}")
        self.c_sky = float(c_sky)
        self.kappa = float(force_per_command) if force_per_command else force_gain(self.env.damper)

    def command(self, obs):
        zs = self.body_velocity(obs)
        u = np.clip(self.v_min + self.c_sky * np.abs(zs) / self.kappa, self.v_min, self.v_max)
        return np.where(zs * self.relative_velocity(obs) >= 0.0, u, self.v_min)


class Groundhook(Controller):
    """On–off groundhook (Valášek et al. 1997): u = u_max if −ż_u·v_rel ≥ 0 else u_min (tyre load)."""

    name = "groundhook"
    requires = ("unsprung_vel", "travel_rate")

    def command(self, obs):
        return self.on_off(-self.sensor(obs, "unsprung_vel") * self.sensor(obs, "travel_rate") >= 0.0)


class Hybrid(Controller):
    """Hybrid skyhook–groundhook (Ahmadian 2000): σ = α ż_s − (1 − α) ż_u, u = u_max if σ·v_rel ≥ 0."""

    name = "hybrid"
    requires = ("sprung_vel", "unsprung_vel", "travel_rate")

    def __init__(self, env, alpha: float = 0.6):
        super().__init__(env)
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {alpha}")
        self.alpha = float(alpha)

    def command(self, obs):
        sigma = self.alpha * self.sensor(obs, "sprung_vel") - (1 - self.alpha) * self.sensor(obs, "unsprung_vel")
        return self.on_off(sigma * self.sensor(obs, "travel_rate") >= 0.0)


def force_gain(damper, velocity: float = 0.1) -> float:
    """κ = (F(u_max) − F(u_min)) / (u_max − u_min) at a steady velocity (N per command unit)."""
    from mrd_env.rig import simulate

    c = damper.command
    n = 400
    dt = 1e-3
    t = np.arange(n) * dt
    res = simulate(damper, np.tile(velocity * t, (2, 1)), np.array([[c.v_min], [c.v_max]]) * np.ones((1, n)), dt,
                   v=np.full((2, n), velocity), a=np.zeros((2, n)))
    dF = res[1].force[-1] - res[0].force[-1]
    if not dF > 0:
        raise ValueError(f"damper {damper.name!r} shows no force increase with command at {velocity} m/s")
    return float(dF / (c.v_max - c.v_min))
