"""The controllers by name: ``CONTROLLERS`` (every law), ``VARIANTS`` (laws with options) and
:func:`make_controller`, the one place a name becomes a controller (the package re-exports them)."""
from __future__ import annotations

from .base import Controller, PassiveOff, PassiveOn, RandomCommand
from .friction_laws import DecentralizedBangBang, MaximumEnergyDissipation, ModulatedHomogeneousFriction
from .model_based import ClippedOptimal, Lyapunov
from .mpc import MPC
from .nmpc import NonlinearMPC
from .velocity_laws import Groundhook, Hybrid, SkyhookContinuous, SkyhookOnOff

CONTROLLERS = {c.name: c for c in (RandomCommand, PassiveOff, PassiveOn, SkyhookOnOff, SkyhookContinuous, Groundhook, Hybrid,
                                   ClippedOptimal, MPC, NonlinearMPC, Lyapunov, MaximumEnergyDissipation,
                                   ModulatedHomogeneousFriction, DecentralizedBangBang)}


#: name → (controller, options): clipped-optimal control with an inverse model turning f_c into the command; and
#: ``clipped_optimal_reward``, clipped-optimal designed for the environment's own reward (``weights="reward"``) as
#: the sampled-data LQR of the control step (``design="sampled"``: MPC with the reward's cost at horizon 1). On the
#: building at 10 ms it scores −0.691 on the validation episodes against the default's −0.745 (docs/rl-agents.md).
VARIANTS = {**{f"clipped_optimal+{inv}": ("clipped_optimal", {"inverse": inv}) for inv in ("sid", "model", "neural")},
            "clipped_optimal_reward": ("clipped_optimal", {"weights": "reward", "design": "sampled"})}


def available_controllers() -> list[str]:
    """Names accepted by :func:`make_controller`."""
    return sorted(CONTROLLERS) + sorted(VARIANTS)


def make_controller(name: str, env, **options) -> Controller:
    """A controller by name (see ``CONTROLLERS`` and ``VARIANTS``) for ``env``, with its options."""
    if name in VARIANTS:
        name, fixed = VARIANTS[name]
        options = {**fixed, **options}
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; available: {available_controllers()}")
    return CONTROLLERS[name](env, **options)
