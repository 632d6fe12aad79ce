"""The quarter car in JAX (needs the ``[jax]`` extra): :mod:`mrd_env.jax.env` (every plant's twin, made from the
plant's own assembly) with the quarter car's road banks and problems.

:func:`make_params` keeps the options of ``QuarterCar-v1`` (10 ms control, normalised actions) and draws its bank of
roads with the project's generator (ISO 8608, ``method="fft"``; or takes ``roads``), so that the passive car's
reference on each road, the Wk filter, the stroke limit and its penalty, the constraint costs and, with ``preview``,
the ``road_preview`` sensor are the native environment's. :func:`native_roads` draws the roads a native
environment meets at ``reset(seed=s)`` (the training mixture of classes and speeds). ``reset``, ``step``,
``rollout``, ``step_autoreset``, ``draw_params``, ``params_of_problem`` are :mod:`mrd_env.jax.env`'s.
"""
from __future__ import annotations

import numpy as np

from ...disturbances import Record, iso8608_road
from ...jax.env import (DRAWN_BANDS, SCHEMES, EnvParams, EnvState, check_bank, command, draw_params, drawn_options,  # noqa: F401
                        episode_return, native_records, params_of_assembly, params_of_problem, reset, rollout, step,
                        step_autoreset)
from ...validation import check_scalar
from . import SPEC
from . import env as native

#: The default sensors, as the native environment's.
SENSORS = native.DEFAULT_SENSORS


def make_params(*, plant_preset: str = "set_a", damper: str = "spencer_dyke", damper_preset: str | None = None,
                damper_params=None, dt: float = 1e-3, control_dt: float = 0.01, episode_seconds: float = 10.0,
                road_class: str = "C", speed: float = 20.0, n_roads: int = 16, seed: int = 0, roads=None,
                scheme: str = "exact", substeps: int = 1, newton_iterations: int = 2, jacobian: str = "kernel",
                action_mode: str = "normalized", stroke_limit: float = 0.1, reward_weights=None,
                preview=None, **options) -> EnvParams:
    """The quarter car's parameters with ``QuarterCar-v1``'s defaults. ``roads``: records with channels
    (z_r, ż_r) at ``dt`` (default: ``n_roads`` ISO 8608 roads of ``road_class`` at ``speed`` drawn from ``seed``,
    ``seed + 1``, ...). ``scheme``: "exact" or "differentiable" (with ``substeps``, a power of two up to 8, and
    ``newton_iterations``; ``jacobian``: :func:`~mrd_env.jax.env.params_of_assembly`). ``preview``: the native option (the times ahead, s): the observation ends with the
    ``road_preview`` sensor (after the default sensors, unless ``sensors`` are given). ``options``: any other option of the native environment (sensors, soft stroke
    limit, ...). Bad values raise ``ValueError`` naming the option."""
    if preview and "sensors" not in options:
        options["sensors"] = (*SENSORS, "road_preview")
    asm = native.assembly(plant_preset=plant_preset, damper=damper, damper_preset=damper_preset,
                          damper_params=damper_params, dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
                          action_mode=action_mode, stroke_limit=stroke_limit, reward_weights=reward_weights,
                          preview=preview, **options)
    if roads is None:
        n_roads = int(check_scalar("n_roads", n_roads, 1, 100_000))
        try:  # refused with the estimate before any road is drawn
            check_bank(asm, seeds=range(n_roads))
        except ValueError as exc:
            raise ValueError(str(exc).replace("seeds (", f"n_roads={n_roads} (", 1)) from None
        roads = [iso8608_road(road_class, speed, asm.episode_seconds, asm.dt, rng=seed + i, method="fft")
                 for i in range(n_roads)]
    roads = [r if isinstance(r, Record) else Record(asm.dt, np.asarray(getattr(r, "data", r), np.float64),
                                                    native.ROAD_CHANNELS, native.ROAD_UNITS) for r in roads]
    return params_of_assembly(asm, roads, scheme=scheme, substeps=substeps, newton_iterations=newton_iterations,
                              jacobian=jacobian, name="roads")


def native_roads(road, seeds, *, dt: float = 1e-3, episode_seconds: float = 10.0) -> list:
    """The road records a native quarter-car environment with the option ``road`` (its spelling: a kind's name or
    ``{"kind": ..., **options}``, e.g. the training mixture of classes and speeds) meets at ``reset(seed=s)``
    for each of ``seeds``: the same generator, drawn from the same Gymnasium seeding, so that :func:`make_params`
    (``roads=``) gives the twin the native episodes' roads."""
    return native_records(native.assembly(road=road, dt=dt, episode_seconds=episode_seconds), seeds)


__all__ = ["SPEC", "SENSORS", "SCHEMES", "DRAWN_BANDS", "EnvParams", "EnvState", "make_params", "native_roads",
           "params_of_problem", "reset", "step", "step_autoreset", "rollout", "command", "episode_return",
           "draw_params", "drawn_options"]
