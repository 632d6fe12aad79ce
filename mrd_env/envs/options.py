"""The options every environment shares — damper, time steps, action mode, sensors, reward weights — checked
once, with errors that name the option and its valid values."""
from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from ..dampers import DamperModel, damper_class, is_preset_file, make_damper
from ..validation import check_n_samples, check_scalar
from .build import as_options
from .reward import CallableReward, QuadraticReward
from .sensors import Sensors

MAX_PERIOD_STEPS = 100_000  # physics steps in one control period (the period's buffers are allocated)


def make_env_damper(damper, preset, params, default_preset: str) -> DamperModel:
    """The damper of an environment: a model name (with ``preset``, default ``default_preset`` where the model
    has it, and parameter overrides ``params``), a preset file (``"fitted.json"``, as ``mrd-env identify
    --save-preset`` writes) or a :class:`DamperModel`."""
    params = named_options("damper_params", params)
    if isinstance(damper, DamperModel):
        if preset is not None:
            raise ValueError("damper_preset applies to a damper model name, not to a DamperModel instance")
        return damper.with_params(**params) if params else damper
    if is_preset_file(damper):
        if preset is not None:
            raise ValueError(f"damper_preset applies to a damper model name; {damper} is a preset file already")
        return make_damper(str(damper), **params)
    if not isinstance(damper, str):
        raise ValueError(f"damper must be a model name (one of the registered models), a preset file (.json) or a "
                         f"DamperModel, got {damper!r}")
    cls = damper_class(damper)  # ValueError naming the available models
    if preset is None:
        preset = default_preset if default_preset in cls.presets else None
    elif not isinstance(preset, str) or preset not in cls.presets:
        raise ValueError(f"damper_preset {preset!r} is not a preset of damper model {damper!r}; "
                         f"available: {sorted(cls.presets)}")
    return make_damper(damper, preset, **params)


def plant_parameters(params_class: type, make, preset, given):
    """A plant's parameters: ``given`` itself when it is a ``params_class``, else ``make(preset, **given)`` (the
    preset with the overrides of the dict ``given``, or none); ``ValueError`` naming ``plant_params`` otherwise."""
    if isinstance(given, params_class):
        return given
    if given is not None and not isinstance(given, dict):
        raise ValueError(f"plant_params must be a dict of {params_class.__name__} overrides or a "
                         f"{params_class.__name__} instance, got {type(given).__name__}")
    return make(preset, **named_options("plant_params", given))


def named_options(name: str, given) -> dict:
    """A dict of overrides whose keys are names (strings), else ``ValueError`` naming ``name``."""
    out = as_options(name, given)
    bad = [k for k in out if not isinstance(k, str)]
    if bad:
        raise ValueError(f"{name} keys must be parameter names (strings), got {bad!r}")
    return out


def time_steps(dt, control_dt, episode_seconds) -> tuple[float, float, float | None]:
    """(dt, control_dt, episode_seconds) checked: control_dt an integer multiple of dt."""
    dt = check_scalar("dt", dt, 0.0, 0.1, lo_open=True, unit="s")
    control_dt = check_scalar("control_dt", control_dt, 0.0, lo_open=True, unit="s")
    ratio = control_dt / dt
    if not ratio <= MAX_PERIOD_STEPS:
        raise ValueError(f"control_dt / dt = {ratio:.3g} physics steps per control period (control_dt = "
                         f"{control_dt:g} s, dt = {dt:g} s): at most {MAX_PERIOD_STEPS}")
    n_sub = int(round(ratio))
    if n_sub < 1 or abs(n_sub * dt - control_dt) > 1e-9 * control_dt:
        raise ValueError(f"control_dt must be an integer multiple of dt = {dt:g} s (e.g. {dt:g}, {2 * dt:g}, "
                         f"{5 * dt:g} s), got {control_dt!r}")
    if episode_seconds is not None:
        episode_seconds = check_scalar("episode_seconds", episode_seconds, n_sub * dt, unit="s")
        check_n_samples(episode_seconds / dt, f"episode_seconds = {episode_seconds:g} s at dt = {dt:g} s")
    return dt, n_sub * dt, episode_seconds


ACTION_MODES = ("physical", "normalized", "force")
#: Default ``force_range`` (N) of ``action_mode="force"``: the force scale of the prototype damper (Spencer et al.
#: 1997, 3 kN capacity; also clipped-optimal control's force_ref).
DEFAULT_FORCE_RANGE = 3000.0


def action_mode(mode) -> str:
    if not isinstance(mode, str) or mode not in ACTION_MODES:
        raise ValueError(f"action_mode must be one of {list(ACTION_MODES)}, got {mode!r}")
    return mode


def actuation(mode, inverse, force_range) -> dict:
    """The action options of an assembly: ``action_mode``, and for ``"force"`` the ``inverse`` (a name of
    :func:`mrd_env.inverse.make_inverse`, a dict ``{"kind": name, **options}`` or an
    :class:`~mrd_env.inverse.Inverse`; default "model") and ``force_range`` (N, default 3000 N)."""
    from ..inverse import INVERSES, Inverse

    mode = action_mode(mode)
    if mode != "force":
        if inverse is not None or force_range is not None:
            raise ValueError(f"inverse and force_range apply to action_mode='force', not to {mode!r}")
        return {"action_mode": mode}
    if inverse is None:
        inverse = "model"
    if isinstance(inverse, Mapping):
        kind = inverse.get("kind", "model")
    elif isinstance(inverse, (str, Inverse)):
        kind = inverse if isinstance(inverse, str) else inverse.name
    else:
        raise ValueError(f"inverse must be a name among {list(INVERSES)}, a dict {{'kind': name, **options}} or an "
                         f"Inverse, got {type(inverse).__name__}")
    if not isinstance(kind, str) or kind not in INVERSES:
        raise ValueError(f"inverse: unknown kind {kind!r}; valid: {list(INVERSES)}")
    f = check_scalar("force_range", DEFAULT_FORCE_RANGE if force_range is None else force_range, 0.0,
                     lo_open=True, unit="N")
    return {"action_mode": mode, "inverse": inverse, "force_range": f}


def sensors(spec, noise, delay, history, default: tuple[str, ...]) -> Sensors:
    """The sensors part from the ``sensors`` option (None → ``default``; names; a :class:`Sensors`) and the
    ``sensor_noise``/``sensor_delay``/``history`` options."""
    if isinstance(spec, Sensors):
        if noise is not None or delay != 0 or history != 1:
            raise ValueError("give sensor_noise, sensor_delay and history inside the Sensors object, not beside it")
        return spec
    return Sensors(default if spec is None else spec, noise, delay, history)


def reward(given, default: Callable[[], QuadraticReward]) -> QuadraticReward | CallableReward:
    """The ``reward`` option: None (the plant's ``default()``), a QuadraticReward, a CallableReward or any callable
    of the period's signals (wrapped in a CallableReward)."""
    if given is None:
        return default()
    if isinstance(given, (QuadraticReward, CallableReward)):
        return given
    if callable(given):
        return CallableReward(given)
    raise ValueError("reward must be None, a QuadraticReward, a CallableReward or a callable of the period's "
                     f"signals, got {type(given).__name__}")


def weights(given, defaults: Mapping[str, float]) -> dict[str, float]:
    """``reward_weights``: the defaults updated with the given ones (each >= 0, names among the defaults)."""
    out = dict(defaults)
    given = as_options("reward_weights", given)
    unknown = sorted(set(given) - set(defaults), key=str)
    if unknown:
        raise ValueError(f"reward_weights has unknown key(s) {unknown}; valid keys: {sorted(defaults)}")
    for k, v in given.items():
        out[k] = check_scalar(f"reward_weights[{k!r}]", v, 0.0)
    return out



MAX_PREVIEW = 10.0  # s: a look-ahead sensor sees metres to tens of metres of road, well under 10 s
#: The most preview times: each is an input channel of every row and a row and a column of the signal map (whose
#: size grows with the square of the count).
MAX_PREVIEW_TIMES = 1000


def preview_times(preview, dt: float) -> tuple[float, ...]:
    """``preview``: None (no preview), or one time or an increasing sequence of times ahead (s), each a multiple of
    ``dt`` in [dt, MAX_PREVIEW]; as a tuple of floats on the dt grid."""
    if preview is None:
        return ()
    if isinstance(preview, (str, bytes, bool, Mapping)):
        raise ValueError(f"preview must be a time ahead in s or a sequence of them (e.g. (0.05, 0.1)), got {preview!r}")
    values = list(preview) if isinstance(preview, (list, tuple, np.ndarray)) else [preview]
    if not values:
        raise ValueError("preview must hold at least one time ahead (s); use None for no preview")
    if len(values) > MAX_PREVIEW_TIMES:
        raise ValueError(f"preview holds {len(values)} times ahead, at most {MAX_PREVIEW_TIMES}: each is an input "
                         "channel of every row and a column of the signal map")
    out = []
    for v in values:
        if isinstance(v, bool):
            raise ValueError(f"preview times must be real numbers (s), got {v!r}")
        t = check_scalar("preview", v, 0.0, MAX_PREVIEW, lo_open=True, unit="s")
        k = int(round(t / dt))
        if k < 1 or abs(k * dt - t) > 1e-9 * t:
            raise ValueError(f"preview times must be multiples of dt = {dt:g} s (e.g. {dt:g}, {10 * dt:g}, "
                             f"{50 * dt:g} s), got {v!r}")
        out.append(k * dt)
    if any(b <= a for a, b in zip(out, out[1:])):
        raise ValueError(f"preview times must be increasing (s ahead, nearest first), got {tuple(values)!r}")
    return tuple(out)
