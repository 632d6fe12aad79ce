"""The mechanics every plant shares: a linear plant coupled to MR dampers (:class:`LinearPlant`,
:class:`CoupledPlant`), parameter presets with overrides, and the exact response of a linear plant to sampled
inputs (:func:`foh_response`). A plant's own matrices and parameter sets live in its folder,
``mrd_env/plants/<plant>/physics.py``.

:func:`foh_response` is imported on first use (it compiles with numba and needs scipy.linalg), so that
``import mrd_env`` stays cheap."""
from .plant import CoupledPlant, LinearPlant, preset_with_overrides


def __getattr__(name: str):
    if name == "foh_response":
        from .response import foh_response

        return foh_response
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["CoupledPlant", "LinearPlant", "preset_with_overrides", "foh_response"]
