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
