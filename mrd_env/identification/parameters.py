"""Which parameters a fit frees, and their default bounds.

Free parameters: by default all parameters except the ones fixed by :func:`fixed_by_default`; each parameter
declares in its metadata whether it is fixed by default and why (``param(..., fixed="reason")``), e.g. the
Bouc–Wen exponent n (a shape choice), smoothing scales of sign functions (a regularisation, not physics),
internal filter time constants and conditions of the test; the Bouc–Wen A is fixed when α, β, γ are present
((α, A, β, γ) → (α/s, s A, β/sⁿ, γ/sⁿ) leaves the force unchanged, so one of the four must be fixed);
parameters that are exactly zero in the preset (structurally absent) are fixed too. The command dynamics can be
fitted under the names of :data:`COMMAND_PARAMS` (``command_eta``, ``command_eta_fall``, ``command_delay``).

Default bounds: (p0/f, p0·f) around the initial value p0 > 0 (f = ``bound_factor``, 10), (p0·f, p0/f) for
p0 < 0, and p0 ± f|p0| for a parameter whose valid range has no lower limit (so it may change sign, e.g. x0),
always intersected with the declared valid range; a delay starting at 0 gets [0, 5 ms].
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..command_lag import LAG_DELAY, LAG_FALL, LAG_RISE
from ..dampers import DamperModel, damper_class
from ..validation import shown


#: Pseudo-parameters of the command dynamics (:class:`~mrd_env.dampers.CommandSpec`): name → (field, unit, lo, hi).
COMMAND_PARAMS = {
    "command_eta": ("eta", "1/s", 0.0, math.inf),
    "command_eta_fall": ("eta_fall", "1/s", 0.0, math.inf),
    "command_delay": ("delay", "s", 0.0, 1.0),
}
COMMAND_ETA, COMMAND_ETA_FALL, COMMAND_DELAY = COMMAND_PARAMS
LAG_COLUMN = {COMMAND_ETA: LAG_RISE, COMMAND_ETA_FALL: LAG_FALL, COMMAND_DELAY: LAG_DELAY}
_ZERO_REASON = "zero in the preset (structurally absent): name it in free and give bounds to fit it"


def fixed_by_default(model: str | type | DamperModel, params=None) -> dict[str, str]:
    """Parameters that :func:`~mrd_env.identification.fit.fit_model` keeps fixed unless named in ``free``, with
    the reason for each: those whose declaration says so (``param(..., fixed=reason)``), and those equal to zero
    in ``params`` (the preset: structurally absent)."""
    cls = _model_class(model)
    fixed = cls.Params.fixed_by_default()
    if params is not None:
        for k, v in params.to_dict().items():
            if v == 0.0 and k not in fixed:
                fixed[k] = _ZERO_REASON
    return fixed


def initial_values(params, command) -> dict[str, float]:
    """{name: value} of every parameter and command pseudo-parameter of a configured damper."""
    lag = command.lag_vector()
    return {**params.to_dict(), **{k: float(lag[c]) for k, c in LAG_COLUMN.items()}}


def command_with(command, lag_row, free: tuple[str, ...]):
    """``command`` with the fitted (η_rise, η_fall, τ) of ``lag_row``; a symmetric lag stays symmetric unless
    η_fall was fitted."""
    asym = command.eta_fall is not None or COMMAND_ETA_FALL in free
    return dataclasses.replace(command, eta=float(lag_row[LAG_RISE]),
                               eta_fall=float(lag_row[LAG_FALL]) if asym else None,
                               delay=float(lag_row[LAG_DELAY]))


def default_bounds(model: str | type | DamperModel, name: str, value: float,
                   bound_factor: float = 10.0) -> tuple[float, float]:
    """Default bounds of parameter ``name`` around its initial ``value`` (see the module docstring)."""
    cls = _model_class(model)
    f = float(bound_factor)
    if not (math.isfinite(f) and f > 1):
        raise ValueError(f"bound_factor = {shown(bound_factor)} is invalid: must be > 1")
    lo_valid, hi_valid, _ = valid_range(cls, name)
    v = float(value)
    if name == COMMAND_DELAY:
        return 0.0, min(max(f * v, 5e-3), hi_valid)
    if v == 0.0:
        raise ValueError(f"parameter {name!r} is 0 in the initial guess: give its bounds explicitly")
    if math.isinf(lo_valid):
        lo, hi = v - f * abs(v), v + f * abs(v)
    elif v > 0:
        lo, hi = v / f, v * f
    else:
        lo, hi = v * f, v / f
    return max(lo, lo_valid), min(hi, hi_valid)


def valid_range(cls, name: str) -> tuple[float, float, bool]:
    if name in COMMAND_PARAMS:
        _, _, lo, hi = COMMAND_PARAMS[name]
        return lo, hi, name != COMMAND_DELAY
    f = {fl.name: fl for fl in dataclasses.fields(cls.Params)}[name]
    return f.metadata["lo"], f.metadata["hi"], f.metadata["lo_open"]


def make_params(cls, p: np.ndarray):
    """The model's parameter dataclass from a vector in declaration order (fields may be keyword-only)."""
    return cls.Params(**{k: float(v) for k, v in zip(cls.Params.names(), p)})


def _model_class(model) -> type:
    if isinstance(model, str):
        return damper_class(model)
    if isinstance(model, DamperModel):
        return type(model)
    if isinstance(model, type) and issubclass(model, DamperModel):
        return model
    raise ValueError(f"model must be a registered model name or a DamperModel, got {model!r}")
