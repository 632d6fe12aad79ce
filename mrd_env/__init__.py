"""mrd-env: Gymnasium environments, damper models and identification tools for MR dampers."""
from .dampers import available_dampers, make_damper
from .errors import SimulationDivergedError

__version__ = "0.1.0"
__all__ = ["available_dampers", "make_damper", "SimulationDivergedError", "__version__"]
