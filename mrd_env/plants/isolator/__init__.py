"""The single-degree-of-freedom MR isolator: a payload on a spring, an MR damper between it and a moving base
(a suspension seat on a cab floor, an equipment isolator on a machine frame).

Its folder holds every fact about it: ``physics.py`` (the equation and the parameter set), ``env.py`` (the
environment: base motions, signals, reward, episode metrics, the nominal reference), ``render.py`` and
``profile.py`` (what the experiments run on it)."""
from ..spec import PlantSpec
from .physics import ISOLATOR_PRESETS, IsolatorParams, isolator

SPEC = PlantSpec(
    name="isolator", id_name="Isolator", title="MR isolator",
    summary="a payload on a spring with one MR damper on a moving base (a suspension seat), random and harmonic "
            "base motions")

__all__ = ["SPEC", "ISOLATOR_PRESETS", "IsolatorParams", "isolator"]
