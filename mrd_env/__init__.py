"""mrd-env: Gymnasium environments, damper models and identification tools for MR dampers."""
from .dampers import available_dampers, make_damper
from .plants.registry import register_envs
from .errors import SimulationDivergedError

register_envs()  # makes gymnasium.make("mrd_env/QuarterCarPhysical-v0") etc. work after `import mrd_env`

__version__ = "0.1.0"
__all__ = ["available_dampers", "make_damper", "register_envs", "SimulationDivergedError", "__version__"]
