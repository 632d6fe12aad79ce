"""MR-damper models behind one interface (see :mod:`mrd_env.dampers.base`)."""
from .base import CommandSpec, DamperModel, DamperParams, Preset
from .registry import available_dampers, damper_class, make_damper, register

__all__ = ["CommandSpec", "DamperModel", "DamperParams", "Preset", "available_dampers", "damper_class",
           "make_damper", "register"]
