"""Preset files: a damper's model, SI parameters with units and command channel as JSON (the format
:func:`mrd_env.identification.save_preset` writes after a fit).

A preset file is accepted wherever a model name is (:func:`~.registry.make_damper`, ``gym.make(...,
damper="fitted.json")``, the ``--model``/``--damper`` options of the commands), so that a fitted damper is usable
everywhere a published one is.
"""
from __future__ import annotations

import json
from pathlib import Path

PRESET_FORMAT = "mrd-env-preset"
#: The model name a preset of the neural forward model carries (a network, not a parametric model).
NEURAL_MODEL = "neural"


def is_preset_file(spec) -> bool:
    """Whether ``spec`` names a preset file (a path ending in .json) rather than a model."""
    return isinstance(spec, (str, Path)) and str(spec).lower().endswith(".json")


def read_preset(path: str | Path) -> dict:
    """The JSON document of a preset file (checked for the format marker)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a JSON preset ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict) or doc.get("format") != PRESET_FORMAT:
        raise ValueError(f"{path}: not an mrd-env preset file (missing \"format\": \"{PRESET_FORMAT}\")")
    return doc


def preset_model(path: str | Path) -> str:
    """The model name a preset file holds."""
    return str(read_preset(path).get("model", ""))


def load_damper_preset(path: str | Path):
    """The parametric :class:`~.base.DamperModel` of a preset file, parameters exactly as saved.

    ``ValueError`` for an unknown model, missing or extra parameters, a unit that differs from the model's
    declared SI unit, or a neural forward model (a network, read by :func:`mrd_env.identification.load_preset`,
    not a damper model of the environments).
    """
    from .base import CommandSpec
    from .registry import damper_class

    path = Path(path)
    doc = read_preset(path)
    if doc.get("model") == NEURAL_MODEL:
        raise ValueError(f"{path} holds a neural forward model (mrd_env.identification.load_preset reads it): the "
                         "environments, the rig and the inverses need a parametric damper model (fit one with "
                         "mrd-env identify --model <name>)")
    cls = damper_class(doc.get("model", ""))
    units = cls.Params.units()
    pars = doc.get("parameters", {})
    missing = [k for k in units if k not in pars]
    extra = [k for k in pars if k not in units]
    if missing or extra:
        raise ValueError(f"{path}: parameters of {cls.name!r} do not match (missing {missing}, unknown {extra})")
    values = {}
    for k, entry in pars.items():
        if entry.get("unit") != units[k]:
            raise ValueError(f"{path}: parameter {k!r} is in {entry.get('unit')!r}, expected {units[k]!r} (SI)")
        values[k] = float(entry["value"])
    c = doc.get("command", {})
    try:
        fall = c.get("eta_fall")
        command = CommandSpec(c["unit"], float(c["v_min"]), float(c["v_max"]), float(c["eta"]),
                              None if fall is None else float(fall), float(c.get("delay_s", 0.0)))
    except KeyError as exc:
        raise ValueError(f"{path}: command channel lacks {exc}") from None
    return cls(cls.Params(**values), command)
