"""Semi-active control laws behind one interface (``predict``/``reset``, as Stable-Baselines3 agents).

Build a controller from the environment it drives: ``SkyhookOnOff(env)``; ``make_controller(name, env)``
by name. ``CONTROLLERS`` lists the names.
"""
from .agents import TrainedAgent, load_agent, shipped_agents
from .base import AgentController, Controller, PassiveOff, PassiveOn, RandomCommand
from .friction_laws import MaximumEnergyDissipation, ModulatedHomogeneousFriction
from .model_based import ClippedOptimal, KalmanEstimator, LinearDesign, Lyapunov
from .velocity_laws import Groundhook, Hybrid, SkyhookContinuous, SkyhookOnOff, force_gain

CONTROLLERS = {c.name: c for c in (RandomCommand, PassiveOff, PassiveOn, SkyhookOnOff, SkyhookContinuous, Groundhook, Hybrid,
                                   ClippedOptimal, Lyapunov, MaximumEnergyDissipation,
                                   ModulatedHomogeneousFriction)}


def make_controller(name: str, env, **options) -> Controller:
    """A controller by name (see ``CONTROLLERS``) for ``env``, with its options."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; available: {sorted(CONTROLLERS)}")
    return CONTROLLERS[name](env, **options)


__all__ = ["AgentController", "CONTROLLERS", "ClippedOptimal", "Controller", "Groundhook", "Hybrid",
           "KalmanEstimator", "LinearDesign", "Lyapunov", "MaximumEnergyDissipation",
           "ModulatedHomogeneousFriction", "PassiveOff", "PassiveOn", "RandomCommand", "SkyhookContinuous", "SkyhookOnOff",
           "TrainedAgent", "force_gain", "load_agent", "make_controller", "shipped_agents"]
