"""Semi-active control laws behind one interface (``predict``/``reset``, as Stable-Baselines3 agents).

Build a controller from the environment it drives: ``SkyhookOnOff(env)``; ``make_controller(name, env)``
by name (``"mpc"``: linear model-predictive control, :mod:`.mpc`, needs OSQP; ``"nmpc"``: nonlinear MPC on the
damper model, :mod:`.nmpc`, needs CasADi and a C compiler, not real time). ``CONTROLLERS`` lists the names;
``VARIANTS`` names laws with options (clipped-optimal control with each inverse model: ``"clipped_optimal+model"``
is ``ClippedOptimal(env, inverse="model")``; ``"clipped_optimal_reward"`` is ``ClippedOptimal(env, weights="reward",
design="sampled")``, designed for the environment's reward at its control step).
``ControllerProtocol`` (:mod:`.protocol`): what any controller, yours too, must be to be scored on a benchmark suite
(``mrd-env score``).
"""
from .agents import TrainedAgent, load_agent, shipped_agents
from .base import AgentController, Controller, PassiveOff, PassiveOn, RandomCommand
from .friction_laws import DecentralizedBangBang, MaximumEnergyDissipation, ModulatedHomogeneousFriction
from .model_based import ClippedOptimal, KalmanEstimator, LinearDesign, Lyapunov
from .mpc import MPC
from .nmpc import NonlinearMPC
from .protocol import ControllerProtocol, build_controller, import_object
from .registry import CONTROLLERS, VARIANTS, available_controllers, make_controller
from .velocity_laws import Groundhook, Hybrid, SkyhookContinuous, SkyhookOnOff, force_gain


__all__ = ["NonlinearMPC", "AgentController", "CONTROLLERS", "ClippedOptimal", "Controller", "ControllerProtocol",
           "DecentralizedBangBang", "Groundhook", "Hybrid", "KalmanEstimator", "LinearDesign", "Lyapunov", "MPC", "MaximumEnergyDissipation",
           "ModulatedHomogeneousFriction", "PassiveOff", "PassiveOn", "RandomCommand", "SkyhookContinuous", "SkyhookOnOff",
           "TrainedAgent", "VARIANTS", "available_controllers", "build_controller", "force_gain", "import_object",
           "load_agent", "make_controller", "shipped_agents"]
