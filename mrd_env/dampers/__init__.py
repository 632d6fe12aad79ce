"""MR-damper models behind one interface (see :mod:`mrd_env.dampers.base`).

"The review" in the docstrings of this package is "A Review on Parametric Dynamic Models of Magnetorheological
Dampers and Their Characterization Methods" (the seed review of this project); equation, table and figure
numbers are that paper's.
"""
from .base import AUTOMOTIVE_COMMAND, PROTOTYPE_COMMAND, CommandSpec, DamperModel, DamperParams, Preset, command_spec
from .preset_file import is_preset_file
from .registry import available_dampers, damper_class, load_damper_preset, make_damper, register

__all__ = ["is_preset_file", "load_damper_preset", "CommandSpec", "PROTOTYPE_COMMAND", "AUTOMOTIVE_COMMAND", "DamperModel", "DamperParams", "Preset", "command_spec", "available_dampers", "damper_class",
           "make_damper", "register"]
