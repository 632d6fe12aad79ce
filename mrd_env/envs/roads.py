"""The road under a car's wheel, one rule for every kind: ``road`` is a kind name (with ``road_params``), a dict
``{"kind": ..., **options}``, a :class:`~mrd_env.disturbances.Record` with the road's channels (z_r, zdot_r: m,
m/s) or a :class:`~.disturbance.Disturbance`. The kinds: ISO 8608 random roads (a new one per episode, class and
speed drawn per episode where given as a list and a range), a bump, a sine sweep, a measured profile from CSV.
A road's length is checked against the memory limit before it is made."""
from __future__ import annotations

import functools

from ..disturbances import Record, bump, iso8608_road, road_from_csv, sine_sweep
from ..resources import Budget
from . import randomize
from .build import as_options, build
from .disturbance import Disturbance, FixedRecord, Generated

ROAD_CHANNELS = ("z_r", "zdot_r")
ROAD_UNITS = ("m", "m/s")


def _iso8608(*, dt, episode_seconds, budget=None, road_class="C", speed=20.0, method="fft", n_min=None, n_max=None,
             n_waves=None, waviness=None):
    """A new random road per episode; ``road_class`` may be a list and ``speed`` a range (lo, hi) to draw per
    episode (:mod:`.randomize`)."""
    # a generated road at least 2 s long, so that the FFT grid holds waves down to low spatial frequencies
    duration = max(episode_seconds or 10.0, 2.0)
    (budget or Budget()).check_record(duration / dt + 1, dt, len(ROAD_CHANNELS),
                                      f"episode_seconds={episode_seconds or 10.0:g}", what="the road",
                                      generated=True)
    extra = {k: v for k, v in dict(n_min=n_min, n_max=n_max, n_waves=n_waves, waviness=waviness).items()
             if v is not None}
    # the options are checked now, not at reset: every class and both ends of the speed range
    n_samples = max(iso8608_road(c, v, duration, dt, rng=0, method=method, **extra).n_samples
                    for c in randomize.values("road_class", road_class, lambda v: v)
                    for v in randomize.values("road_params['speed']", speed))
    return Generated(functools.partial(_iso8608_record, road_class, speed, duration, dt, method, extra),
                     ROAD_CHANNELS, f"ISO 8608 class {randomize.describe(road_class)} at "
                                    f"{randomize.describe(speed)} m/s", max_samples=n_samples)


def _iso8608_record(road_class, speed, duration: float, dt: float, method: str, extra: dict, rng) -> Record:
    """One episode's ISO 8608 road, its class and speed drawn from ``rng`` where they are random."""
    return iso8608_road(randomize.draw(road_class, rng), randomize.draw(speed, rng), duration, dt, rng=rng,
                        method=method, **extra)


def _road_length(seconds, dt: float, budget: Budget | None, cause: str) -> None:
    """``ValueError`` (:mod:`mrd_env.resources`) if a road of ``seconds`` at ``dt`` and the episode on it do not
    fit the memory limit (nothing is checked for a value that is not a positive number: the road's own checks
    name it)."""
    try:
        n = float(seconds) / dt + 1
    except (TypeError, ValueError, OverflowError):
        return
    if n > 0:
        (budget or Budget()).check_record(n, dt, len(ROAD_CHANNELS), cause, what="the road")


def _bump(*, dt, episode_seconds, budget=None, height=0.05, length=1.0, speed=10.0, t_start=0.5, duration=None):
    if duration is not None:
        _road_length(duration, dt, budget, f"road_params['duration']={duration!r}")
    else:
        try:  # the default: the end of the bump and 2 s more
            seconds = float(t_start) + float(length) / float(speed) + 2.0
        except (TypeError, ValueError, ZeroDivisionError, OverflowError):
            seconds = None
        _road_length(seconds, dt, budget, f"a bump of road_params length={length!r}, speed={speed!r}, "
                                          f"t_start={t_start!r}")
    return FixedRecord(bump(height, length, speed, t_start, duration, dt=dt), ROAD_CHANNELS, ROAD_UNITS, dt)


def _sweep(*, dt, episode_seconds, budget=None, amplitude=0.01, f_start=0.5, f_end=20.0, kind="log", duration=None):
    _road_length(duration if duration is not None else (episode_seconds or 10.0), dt, budget,
                 f"road_params['duration']={duration!r}" if duration is not None
                 else f"episode_seconds={episode_seconds or 10.0:g}")
    duration = duration if duration is not None else (episode_seconds or 10.0)
    return FixedRecord(sine_sweep(amplitude, f_start, f_end, duration, dt=dt, kind=kind), ROAD_CHANNELS,
                       ROAD_UNITS, dt)


def _csv(*, dt, episode_seconds, budget=None, path=None, height_column=None, distance_column=None, time_column=None,
         speed=None, units=None):
    if path is None or height_column is None:
        raise ValueError("road 'csv' needs 'path' and 'height_column' (and 'distance_column' + 'speed', or "
                         "'time_column')")
    rest = {k: v for k, v in dict(distance_column=distance_column, time_column=time_column, speed=speed,
                                  units=units).items() if v is not None}
    return FixedRecord(road_from_csv(path, height_column=height_column, dt=dt, duration=episode_seconds,
                                     budget=budget, **rest), ROAD_CHANNELS, ROAD_UNITS, dt)


ROADS = {"iso8608": _iso8608, "bump": _bump, "sine_sweep": _sweep, "csv": _csv}


def road_source(road, road_params, dt: float, episode_seconds, *, kinds=None, channels=ROAD_CHANNELS,
                units=ROAD_UNITS, budget: Budget | None = None, **kind_options) -> Disturbance:
    """The road part: a kind name (with ``road_params``), a dict {"kind": ..., options}, a Record with the road's
    ``channels`` (z_r, zdot_r: m, m/s), or a :class:`~.disturbance.Disturbance`. ``kinds`` (default ``ROADS``),
    ``channels``, ``units`` and ``kind_options`` (e.g. the half car's wheelbase) let another car use the rule.
    A road's length is checked against the memory limit before it is made, with the episode's ``budget``
    (:class:`~mrd_env.resources.Budget`)."""
    if isinstance(road, Record):
        if road_params:
            raise ValueError("road_params apply to a road kind, not to a Record")
        return FixedRecord(road, channels, units, dt)
    if isinstance(road, str) and road_params is not None:
        road = {"kind": road, **as_options(f"road_params (road={road!r})", road_params)}
    return build("road", road, ROADS if kinds is None else kinds, "iso8608", Disturbance, dt=dt,
                 episode_seconds=episode_seconds, budget=budget, **kind_options)
