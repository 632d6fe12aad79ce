"""Preset files: a damper's model, SI parameters with units and command channel as JSON (the format
:func:`mrd_env.identification.save_preset` writes after a fit).

A preset file is accepted wherever a model name is (:func:`~.registry.make_damper`, ``gym.make(...,
damper="fitted.json")``, the ``--model``/``--damper`` options of the commands), so that a fitted damper is usable
everywhere a published one is.

Its structure is checked when it is read (:func:`read_preset`), so that a shared file that is not what it claims
gives one ``ValueError`` naming the file and the field, never an ``AttributeError`` or a ``RecursionError``:

- ``"format"``: ``"mrd-env-preset"``; ``"model"``: a model name (a string), ``"neural"`` (then ``"network"`` is an
  object), or the name of another preset file in the same folder whose model this one uses — one level only: that
  file must name a model itself, not a file, and a preset cannot name itself. The name is resolved inside the
  preset's folder (:func:`mrd_env.storage.inside`: no absolute path, no ``..``, no link leaving it).
- ``"parameters"``: an object ``{name: {"value": number, "unit": text}}``; ``"command"``: an object with
  ``unit`` (text), ``v_min``, ``v_max``, ``eta`` (numbers) and optionally ``eta_fall`` (a number or null),
  ``delay_s`` (a number), ``eta_unit`` (text); both required for a parametric model.
- ``"source"`` text, ``"version"`` an integer, ``"provenance"`` an object, where present.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from .. import storage

PRESET_FORMAT = "mrd-env-preset"
#: The model name a preset of the neural forward model carries (a network, not a parametric model).
NEURAL_MODEL = "neural"
#: The largest preset file read (a neural model's weights included): a larger one is no preset.
MAX_PRESET_BYTES = 64 * 1024 ** 2
#: The command channel's fields: required and optional, with their types.
COMMAND_FIELDS = {"unit": str, "v_min": float, "v_max": float, "eta": float}
COMMAND_OPTIONAL = {"eta_fall": float, "delay_s": float, "eta_unit": str}


def is_preset_file(spec) -> bool:
    """Whether ``spec`` names a preset file (a path ending in .json) rather than a model."""
    return isinstance(spec, (str, Path)) and str(spec).lower().endswith(".json")


def _load(path: Path) -> dict:
    """The JSON object of a preset file, checked for the format marker (no structure check)."""
    from ..storage import read_limited

    data = read_limited(path, MAX_PRESET_BYTES, what="preset file")  # a regular file only: never a FIFO or device
    try:
        doc = json.loads(data.decode("utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a JSON preset ({exc.msg} at line {exc.lineno})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a JSON preset (not UTF-8 text)") from None
    except RecursionError:
        raise ValueError(f"{path}: not a JSON preset (nested too deeply)") from None
    if not isinstance(doc, dict) or doc.get("format") != PRESET_FORMAT:
        raise ValueError(f"{path}: not an mrd-env preset file (missing \"format\": \"{PRESET_FORMAT}\")")
    return doc


def _kind(value) -> str:
    return {dict: "an object", list: "a list", str: "text", bool: "a boolean", type(None): "null"}.get(
        type(value), "a number" if isinstance(value, (int, float)) else type(value).__name__)


def _number(path: Path, field: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{path}: {field} must be a number, got {_kind(value)} ({json.dumps(value)[:40]})")
    try:
        out = float(value)
    except OverflowError:
        out = math.inf
    if not math.isfinite(out):
        raise ValueError(f"{path}: {field} must be a finite number, got {value!r}")
    return out


def _check_fields(doc: dict, path: Path) -> None:
    """``ValueError`` naming ``path`` and the field for a preset whose fields have the wrong types."""
    model = doc.get("model")
    if not isinstance(model, str) or not model:
        raise ValueError(f"{path}: \"model\" must be a model name or a preset file name (text), got "
                         f"{_kind(model)}")
    for field, kind, name in (("source", str, "text"), ("provenance", dict, "an object")):
        if field in doc and doc[field] is not None and not isinstance(doc[field], kind):
            raise ValueError(f"{path}: \"{field}\" must be {name}, got {_kind(doc[field])}")
    if "version" in doc and (isinstance(doc["version"], bool) or not isinstance(doc["version"], int)):
        raise ValueError(f"{path}: \"version\" must be an integer, got {_kind(doc['version'])}")
    if model == NEURAL_MODEL:
        if not isinstance(doc.get("network"), dict):
            raise ValueError(f"{path}: \"network\" must be an object (the neural model's description), got "
                             f"{_kind(doc.get('network'))}")
        return
    pars = doc.get("parameters")
    if not isinstance(pars, dict):
        raise ValueError(f"{path}: \"parameters\" must be an object {{name: {{\"value\": number, \"unit\": text}}}}, "
                         f"got {_kind(pars)}")
    for k, entry in pars.items():
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: \"parameters\".\"{k}\" must be an object {{\"value\": number, \"unit\": "
                             f"text}}, got {_kind(entry)}")
        _number(path, f"\"parameters\".\"{k}\".\"value\"", entry.get("value"))
        if not isinstance(entry.get("unit"), str):
            raise ValueError(f"{path}: \"parameters\".\"{k}\".\"unit\" must be text, got {_kind(entry.get('unit'))}")
    c = doc.get("command")
    if not isinstance(c, dict):
        raise ValueError(f"{path}: \"command\" must be an object with {', '.join(COMMAND_FIELDS)}, got {_kind(c)}")
    missing = [k for k in COMMAND_FIELDS if k not in c]
    if missing:
        raise ValueError(f"{path}: \"command\" lacks {', '.join(repr(k) for k in missing)}")
    for k, kind in {**COMMAND_FIELDS, **COMMAND_OPTIONAL}.items():
        if k not in c or (k == "eta_fall" and c[k] is None):
            continue
        if kind is str:
            if not isinstance(c[k], str):
                raise ValueError(f"{path}: \"command\".\"{k}\" must be text, got {_kind(c[k])}")
        else:
            _number(path, f"\"command\".\"{k}\"", c[k])


def _referenced(path: Path, model: str) -> Path:
    """The preset file that ``path``'s ``"model"`` names, inside ``path``'s folder (not ``path`` itself)."""
    target = storage.inside(path.parent, model, what=f"{path}: \"model\"")
    if target.resolve() == path.resolve():
        raise ValueError(f"{path}: \"model\" names the preset file itself ({model!r}): give a model name")
    return target


def read_preset(path: str | Path) -> dict:
    """The JSON document of a preset file, checked for the format marker and its structure (see the module
    docstring); a ``"model"`` naming another preset file is checked to name a model itself."""
    path = Path(path)
    doc = _load(path)
    _check_fields(doc, path)
    if is_preset_file(doc["model"]):
        target = _referenced(path, doc["model"])
        base = _load(target)
        if not isinstance(base.get("model"), str) or not base["model"]:
            raise ValueError(f"{target} (the \"model\" of {path}): \"model\" must be a model name (text)")
        if is_preset_file(base["model"]):
            raise ValueError(f"{path}: \"model\" names {target.name}, whose \"model\" names a preset file "
                             f"({base['model']!r}) in turn: one level at most, give a model name there")
    return doc


def preset_model(path: str | Path) -> str:
    """The model name a preset file holds (that of the preset file its ``"model"`` names, if it names one)."""
    path = Path(path)
    model = read_preset(path)["model"]
    if is_preset_file(model):
        return str(_load(_referenced(path, model))["model"])
    return model
