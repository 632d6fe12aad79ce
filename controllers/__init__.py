"""Semi-active control laws behind one interface (``predict``/``reset``, as Stable-Baselines3 agents).

Build a controller from the environment it drives: ``SkyhookOnOff(env)``; ``make_controller(name, env)``
by name (``"mpc"``: linear model-predictive control, :mod:`.mpc`, needs OSQP; ``"nmpc"``: nonlinear MPC on the
damper model, :mod:`.nmpc`, needs CasADi and a C compiler, not real time). ``CONTROLLERS`` lists the names;
``VARIANTS`` names laws with options (clipped-optimal control with each inverse model: ``"clipped_optimal+model"``
is ``ClippedOptimal(env, inverse="model")``).
"""
from .agents import TrainedAgent, load_agent, shipped_agents
from .base import AgentController, Controller, PassiveOff, PassiveOn, RandomCommand
from .friction_laws import MaximumEnergyDissipation, ModulatedHomogeneousFriction
from .model_based import ClippedOptimal, KalmanEstimator, LinearDesign, Lyapunov
from .mpc import MPC
from .nmpc import NonlinearMPC
from .velocity_laws import Groundhook, Hybrid, SkyhookContinuous, SkyhookOnOff, force_gain

CONTROLLERS = {c.name: c for c in (RandomCommand, PassiveOff, PassiveOn, SkyhookOnOff, SkyhookContinuous, Groundhook, Hybrid,
                                   ClippedOptimal, MPC, NonlinearMPC, Lyapunov, MaximumEnergyDissipation,
                                   ModulatedHomogeneousFriction)}


#: name → (controller, options): clipped-optimal control with an inverse model turning f_c into the command
VARIANTS = {f"clipped_optimal+{inv}": ("clipped_optimal", {"inverse": inv}) for inv in ("sid", "model", "neural")}


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


__all__ = ["NonlinearMPC", "AgentController", "CONTROLLERS", "ClippedOptimal", "Controller", "Groundhook", "Hybrid",
           "KalmanEstimator", "LinearDesign", "Lyapunov", "MPC", "MaximumEnergyDissipation",
           "ModulatedHomogeneousFriction", "PassiveOff", "PassiveOn", "RandomCommand", "SkyhookContinuous", "SkyhookOnOff",
           "TrainedAgent", "VARIANTS", "available_controllers", "force_gain", "load_agent", "make_controller",
           "shipped_agents"]
