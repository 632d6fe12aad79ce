"""Model registry: every ``DamperModel`` subclass decorated with ``@register`` is selectable by name."""
from __future__ import annotations

import importlib
import pkgutil

_MODELS: dict[str, type] = {}


def register(cls):
    if cls.name in _MODELS and _MODELS[cls.name] is not cls:
        raise ValueError(f"damper model name {cls.name!r} is registered twice")
    _MODELS[cls.name] = cls
    return cls


def _load_all() -> None:
    # one module per model: importing the package's modules fills the registry
    from . import __path__ as pkg_path, __name__ as pkg_name
    for mod in pkgutil.iter_modules(pkg_path):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{pkg_name}.{mod.name}")


def available_dampers() -> list[str]:
    """Names accepted by :func:`make_damper`."""
    _load_all()
    return sorted(_MODELS)


def damper_class(name: str):
    """The model class of a name, or of the model a preset file holds (``"fitted.json"``)."""
    from .preset_file import is_preset_file, preset_model

    _load_all()
    if is_preset_file(name):
        return damper_class(preset_model(name))
    if not isinstance(name, str) or name not in _MODELS:
        raise ValueError(f"unknown damper model {name!r}; available: {sorted(_MODELS)}")
    return _MODELS[name]


def make_damper(name: str = "spencer_dyke", preset: str | None = None, *, command=None, **overrides):
    """A damper by model name and preset, with optional parameter overrides in SI units; ``name`` may also be a
    preset file (``"fitted.json"``, as ``mrd-env identify --save-preset`` writes: no ``preset`` then).

    ``command``: the command channel — a :class:`~mrd_env.dampers.CommandSpec`, or a dict of overrides of the
    preset's channel (``{"v_max": 3.0}``, keys ``unit``, ``v_min``, ``v_max``, ``eta``).

    >>> d = make_damper("spencer_dyke", preset="spencer1997", c0a=2000.0, command={"eta": 100.0})
    """
    from .base import command_spec
    from .preset_file import is_preset_file, load_damper_preset

    if is_preset_file(name):
        if preset is not None:
            raise ValueError(f"preset {preset!r} applies to a model name; {name} is a preset file already")
        base = load_damper_preset(name)
        params = base.params.replace(**overrides) if overrides else base.params
        return type(base)(params, command_spec(command, base.command))
    cls = damper_class(name)
    base = cls.preset(preset)
    params = base.params.replace(**overrides) if overrides else base.params
    return cls(params, command_spec(command, base.command))
