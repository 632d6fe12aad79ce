"""The mechanics every plant shares: a linear plant coupled to MR dampers (:class:`LinearPlant`,
:class:`CoupledPlant`), parameter presets with overrides, and the exact response of a linear plant to sampled
inputs (:func:`foh_response`). A plant's own matrices and parameter sets live in its folder,
``mrd_env/plants/<plant>/physics.py``."""
from .plant import CoupledPlant, LinearPlant, preset_with_overrides
from .response import foh_response

__all__ = ["CoupledPlant", "LinearPlant", "preset_with_overrides", "foh_response"]
