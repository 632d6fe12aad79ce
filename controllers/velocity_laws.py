"""Velocity-feedback semi-active laws: skyhook, groundhook and hybrid (reference page section 7).

The laws read the signals the environment declares for their roles (``env.roles``): ``body_velocity`` ż_s (the
sprung mass, absolute; the building declares none, its floor velocities being relative to the ground),
``wheel_velocity`` ż_u (the unsprung mass) and ``damper_velocity`` v_rel across the damper.
"""
from __future__ import annotations

import numpy as np

from .base import Controller


class SkyhookOnOff(Controller):
    """On–off skyhook (Karnopp, Crosby & Harwood 1974): u = u_max if ż_s·v_rel ≥ 0 else u_min."""

    name = "skyhook_on_off"
    needs_roles = ("body_velocity", "damper_velocity")

    def command(self, obs):
        return self.on_off(self.role(obs, "body_velocity") * self.role(obs, "damper_velocity") >= 0.0)


class SkyhookContinuous(Controller):
    """Continuous skyhook: u = clip(c_sky |ż_s| / κ) if ż_s·v_rel ≥ 0 else u_min, with κ (N per command
    unit) the damper's force gain per unit command, so the damper aims at the skyhook force c_sky ż_s.

    ``c_sky`` in N·s/m (default 1000: on ISO random roads the Wk weighting favours low damping above the
    body mode, so a mild skyhook gain keeps the 4–8 Hz band soft); ``force_per_command`` κ defaults to an
    estimate from the damper model (steady force difference between u_max and u_min at 0.1 m/s).
    """

    name = "skyhook_continuous"
    needs_roles = ("body_velocity", "damper_velocity")

    def __init__(self, env, c_sky: float = 1000.0, force_per_command: float | None = None):
        super().__init__(env)
        if not c_sky > 0:
            raise ValueError(f"c_sky must be > 0 N·s/m, got {c_sky}")
        self.c_sky = float(c_sky)
        self.kappa = command_gain(self.env.damper, force_per_command)

    def command(self, obs):
        zs = self.role(obs, "body_velocity")
        u = np.clip(self.v_min + self.c_sky * np.abs(zs) / self.kappa, self.v_min, self.v_max)
        return np.where(zs * self.role(obs, "damper_velocity") >= 0.0, u, self.v_min)


class Groundhook(Controller):
    """On–off groundhook (Valášek et al. 1997): u = u_max if −ż_u·v_rel ≥ 0 else u_min (tyre load)."""

    name = "groundhook"
    needs_roles = ("wheel_velocity", "damper_velocity")

    def command(self, obs):
        return self.on_off(-self.role(obs, "wheel_velocity") * self.role(obs, "damper_velocity") >= 0.0)


class Hybrid(Controller):
    """Hybrid skyhook–groundhook (Goncalves & Ahmadian 2003): the damper aims at F = G [α σ_sky + (1 − α) σ_gnd]
    with σ_sky = ż_s where ż_s·v_rel ≥ 0 (else 0) and σ_gnd = −ż_u where −ż_u·v_rel ≥ 0 (else 0), each term
    gated on its own; u = clip(u_min + |F| / κ). α = 1 is continuous skyhook with c_sky = G, α = 0 continuous
    groundhook.

    (The reference page's one-switch form, σ = α ż_s − (1 − α) ż_u and u = u_max if σ·v_rel ≥ 0, which this law
    followed until 2026-11-25, is σ·v_rel = α ż_s² − ż_s ż_u + (1 − α) ż_u²: negative only while ż_s/ż_u lies
    between (1 − α)/α and 1, never at α = 0.5, so it ran at u_max on 84 % of a class-C road's steps: passive-on.)
    ``gain`` G in N·s/m (default 1000, continuous skyhook's c_sky); ``force_per_command`` κ as for it.
    """

    name = "hybrid"
    needs_roles = ("body_velocity", "wheel_velocity", "damper_velocity")

    def __init__(self, env, alpha: float = 0.6, gain: float = 1000.0, force_per_command: float | None = None):
        super().__init__(env)
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {alpha}")
        if not gain > 0:
            raise ValueError(f"gain must be > 0 N·s/m, got {gain}")
        self.alpha = float(alpha)
        self.gain = float(gain)
        self.kappa = command_gain(self.env.damper, force_per_command)

    def command(self, obs):
        zs = self.role(obs, "body_velocity")
        zu = self.role(obs, "wheel_velocity")
        v = self.role(obs, "damper_velocity")
        sky = np.where(zs * v >= 0.0, zs, 0.0)
        ground = np.where(-zu * v >= 0.0, -zu, 0.0)
        F = self.gain * (self.alpha * sky + (1.0 - self.alpha) * ground)
        return np.clip(self.v_min + np.abs(F) / self.kappa, self.v_min, self.v_max)


def command_gain(damper, force_per_command: float | None) -> float:
    """κ (N per command unit) of a force-tracking law: ``force_per_command`` as given (> 0), or, when None, the
    damper model's estimate :func:`force_gain`."""
    if force_per_command is None:
        return force_gain(damper)
    if not force_per_command > 0:  # a κ ≤ 0 would leave the law at u_min whatever the force it aims at
        raise ValueError(f"force_per_command must be > 0 N per command unit (or None: estimated from the damper), "
                         f"got {force_per_command}")
    return float(force_per_command)


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
