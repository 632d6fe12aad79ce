"""Inverse models of MR dampers: from a desired force to the command (see :mod:`mrd_env.inverse.base`).

``make_inverse(name, damper, **options)`` builds one by name (:data:`INVERSES`):

- ``"heaviside"`` — the clipped-optimal on–off law and its continuous force-feedback variant (:mod:`.heaviside`);
- ``"sid"`` — simplified inverse dynamics of the Bouc–Wen family (:mod:`.sid`);
- ``"model"`` — one-step model-predictive inverse for any registered model (:mod:`.model`);
- ``"neural"`` — a small network trained on virtual-rig or measured data (:mod:`.neural`, training in
  :mod:`.training`).

:func:`track` runs an inverse in closed loop with a damper along a motion record and scores the tracking
(:mod:`.tracking`); :func:`achievable_forces` makes desired forces a damper can produce (:mod:`.data`).
"""
from __future__ import annotations

import inspect

from .base import Inverse
from .data import achievable_forces, random_command
from .heaviside import Heaviside
from .model import ModelPredictive
from .tracking import TrackingResult, nrmse, plot_tracking, track, tracking_figure

__all__ = ["INVERSES", "Inverse", "make_inverse", "available_inverses", "track", "TrackingResult", "nrmse",
           "plot_tracking", "tracking_figure", "achievable_forces", "random_command", "train_neural_inverse"]


def _classes() -> dict:
    from .neural import NeuralInverse
    from .sid import SimplifiedInverse

    return {c.name: c for c in (Heaviside, SimplifiedInverse, ModelPredictive, NeuralInverse)}


INVERSES = ("heaviside", "sid", "model", "neural")


def available_inverses() -> list[str]:
    """Names accepted by :func:`make_inverse`."""
    return list(INVERSES)


def make_inverse(name: str, damper, **options) -> Inverse:
    """An inverse by name (:data:`INVERSES`) for ``damper`` (a DamperModel or a model name), with its options
    (all take ``dt``, the control step in s; the others are listed in each class's docstring)."""
    classes = _classes()
    if not isinstance(name, str) or name not in classes:
        raise ValueError(f"unknown inverse {name!r}; available: {list(INVERSES)}")
    cls = classes[name]
    params = inspect.signature(cls.__init__).parameters
    valid = [k for k, p in params.items() if p.kind == p.KEYWORD_ONLY]
    unknown = sorted(set(options) - set(valid))
    if unknown:
        raise ValueError(f"unknown option(s) {unknown} for the {name!r} inverse; valid: {valid}")
    return cls(damper, **options)


def train_neural_inverse(*args, **kwargs):
    """Train a neural inverse (needs torch); see :func:`mrd_env.inverse.training.train_neural_inverse`."""
    from .training import train_neural_inverse as train

    return train(*args, **kwargs)
