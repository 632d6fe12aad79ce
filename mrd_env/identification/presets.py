"""Presets as JSON: :func:`save_preset` / :func:`load_preset` write and read the model, SI parameters with units,
the command channel and the provenance of a fit; floats are written with ``repr`` and come back exactly equal."""
from __future__ import annotations

import json
from pathlib import Path

from .. import storage
from ..dampers import DamperModel
from ..dampers.preset_file import PRESET_FORMAT, read_preset  # noqa: F401  (re-exported)
from ..dampers.registry import load_damper_preset
from .neural import NeuralForwardModel
from .result import FitResult


def save_preset(result: FitResult | DamperModel, path: str | Path, *, source: str = "") -> Path:
    """Write a fitted damper (or any damper) as a JSON preset: model name, parameters (SI, with units), command
    channel, and the provenance of a fit (records, method, seed, error measures). Floats are stored with repr,
    so :func:`load_preset` gives back exactly equal parameters."""
    if isinstance(result, FitResult):
        damper = result.damper
        prov = {
            "method": result.method, "seed": result.seed, "free": list(result.free),
            "bounds": {k: list(v) for k, v in result.bounds.items()},
            "initial": result.initial, "records": list(result.records),
            "errors": {"per_record": result.per_record, "overall": result.overall},
            "objective": result.objective, "initial_objective": result.initial_objective,
            "n_evaluations": result.n_evaluations, "wall_time_s": result.wall_time,
            "converged": result.converged, "message": result.message,
            "settings": {k: v for k, v in result.settings.items() if _jsonable(v)},
        }
    elif isinstance(result, (DamperModel, NeuralForwardModel)):
        damper, prov = result, {}
    else:
        raise ValueError(f"save_preset needs a FitResult, a DamperModel or a NeuralForwardModel, got "
                         f"{type(result).__name__}")
    from .. import __version__
    doc = {
        "format": PRESET_FORMAT, "version": 1, "mrd_env_version": __version__,
        "model": damper.name,
        "source": source or (f"fitted with mrd_env.identification.fit_model ({prov['method']})" if prov else ""),
    }
    if isinstance(damper, NeuralForwardModel):
        doc["network"] = damper.to_dict()
    else:
        units = damper.Params.units()
        c = damper.command
        doc["parameters"] = {k: {"value": float(v), "unit": units[k]} for k, v in damper.params.to_dict().items()}
        doc["command"] = {"unit": c.unit, "v_min": float(c.v_min), "v_max": float(c.v_max), "eta": float(c.eta),
                          "eta_fall": None if c.eta_fall is None else float(c.eta_fall), "eta_unit": "1/s",
                          "delay_s": float(c.delay)}
    doc["provenance"] = prov
    return storage.write_text(path, json.dumps(doc, indent=2, ensure_ascii=False, allow_nan=True) + "\n")


def _jsonable(v) -> bool:
    try:
        json.dumps(v)
        return True
    except (TypeError, ValueError):
        return False


def load_preset(path: str | Path) -> DamperModel | NeuralForwardModel:
    """The damper of a preset written by :func:`save_preset` (parameters exactly as saved): a parametric
    :class:`~mrd_env.dampers.DamperModel` (:func:`mrd_env.dampers.load_damper_preset`) or a
    :class:`~.neural.NeuralForwardModel`.

    Raises ``ValueError`` for an unknown model, missing or extra parameters, or a unit that differs from the
    model's declared SI unit.
    """
    doc = read_preset(path)
    if doc.get("model") == NeuralForwardModel.name:
        return NeuralForwardModel.from_dict(doc.get("network", {}))
    return load_damper_preset(path)
