"""Model registry: every ``DamperModel`` subclass decorated with ``@register`` is selectable by name."""
from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from .preset_file import NEURAL_MODEL, is_preset_file, preset_model, read_preset

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
    _load_all()
    if is_preset_file(name):
        model = preset_model(name)  # a model name: a preset naming a preset file is resolved to its model
        if model not in _MODELS:
            raise ValueError(f"{name}: \"model\" {model!r} is not a damper model; available: {sorted(_MODELS)}")
        return _MODELS[model]
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


def load_damper_preset(path: str | Path):
    """The parametric :class:`~.base.DamperModel` of a preset file, parameters exactly as saved.

    ``ValueError`` for an unknown model, missing or extra parameters, a unit that differs from the model's
    declared SI unit, or a neural forward model (a network, read by :func:`mrd_env.identification.load_preset`,
    not a damper model of the environments).
    """
    from .base import CommandSpec

    path = Path(path)
    doc = read_preset(path)  # its structure checked (types, the model file it names), with the file in the errors
    if doc.get("model") == NEURAL_MODEL:
        raise ValueError(f"{path} holds a neural forward model (mrd_env.identification.load_preset reads it): the "
                         "environments, the rig and the inverses need a parametric damper model (fit one with "
                         "mrd-env identify --model <name>)")
    cls = damper_class(path)
    units = cls.Params.units()
    pars = doc["parameters"]
    missing = [k for k in units if k not in pars]
    extra = [k for k in pars if k not in units]
    if missing or extra:
        raise ValueError(f"{path}: parameters of {cls.name!r} do not match (missing {missing}, unknown {extra})")
    values = {}
    for k, entry in pars.items():
        if entry["unit"] != units[k]:
            raise ValueError(f"{path}: parameter {k!r} is in {entry['unit']!r}, expected {units[k]!r} (SI)")
        values[k] = float(entry["value"])
    c = doc["command"]
    fall = c.get("eta_fall")
    try:
        command = CommandSpec(c["unit"], float(c["v_min"]), float(c["v_max"]), float(c["eta"]),
                              None if fall is None else float(fall), float(c.get("delay_s", 0.0)))
    except ValueError as exc:
        raise ValueError(f"{path}: \"command\": {exc}") from None
    try:
        params = cls.Params(**values)
    except ValueError as exc:
        raise ValueError(f"{path}: \"parameters\": {exc}") from None
    return cls(params, command)
