"""The full car's roads: two parallel tracks (left and right wheels), the rear wheels on the front wheels' tracks
wheelbase/speed later, exactly (a delay of any length, not rounded to the time step).

Kinds (the quarter car's one rule, :func:`mrd_env.envs.roads.road_source`):

* ``"iso8608"`` — a new two-track random road per episode (:func:`two_track_iso8608`): each track an ISO 8608
  road of the class (the quarter car's spectrum, waviness 2, on the band [n_min, n_max]), the two tracks
  correlated as the *isotropic road model* says (Dodds & Robson 1973, "The description of road surface
  roughness", J. Sound Vib. 31(2): 175–183; the attribution is from memory, the formula is derived below and
  checked by ``tests/plants/test_full_car.py``): a surface whose roughness has no preferred direction, seen along
  two parallel lines B apart, has the cross-spectrum

      G_lr(n) = G_d(n) · ρ(n),   ρ(n) = x K_1(x),   x = 2π n B

  for the waviness w = 2 of ISO 8608 (K_1 the modified Bessel function of the second kind): the 2-D spectrum
  of a 1-D spectrum C n⁻² is ∝ |k|⁻³, and ∫ (n² + m²)^(−3/2) cos(2π m B) dm / ∫ (n² + m²)^(−3/2) dm = x K_1(x).
  ρ is real (no phase between the tracks) and falls from 1 at long waves to 0.5 at x ≈ 1.26 and 0.05 at
  x ≈ 4.0 (at the sedan's track B = 1.51 m: ρ = 0.98 at 0.011 cycle/m, 0.62 at 0.1, 0.30 at 0.2, 0.03 at
  0.5 cycle/m — waves shorter than about 3 m are nearly independent); the coherence is ρ². ``coherence`` may be a
  number c in [0, 1]: ρ = c at every wavelength (1: both tracks the same road, 0: independent tracks).
* ``"bump"`` and ``"pothole"`` — one (1 − cos) bump of ``height`` (or a pothole of ``depth``) and ``length`` on
  one ``side`` ("left", "right" or "both"), crossed at ``speed``, the front wheel(s) from ``t_start``.
* a :class:`~mrd_env.disturbances.Record` with the channels z_rfl, zdot_rfl, z_rfr, zdot_rfr, z_rrl, zdot_rrl,
  z_rrr, zdot_rrr (m, m/s), or a :class:`~mrd_env.envs.disturbance.Disturbance` giving them.

The previews ride in the record as more channels (the plant ignores them): ``road_preview`` the road of every
wheel τ ahead (``preview`` times), ``wheelbase_preview`` the road of the rear wheels τ ahead, τ at most
wheelbase/speed: the front wheels' road of τ − wheelbase/speed ago, what the car has already driven over
(``wheelbase_preview`` times). The generated kinds evaluate them from the road itself (no end effects); on a
Record the road preview holds the last sample beyond the end (as the quarter car's) and the wheelbase preview,
which needs the speed, is refused.

The tracks are the front track t_f apart; a car whose rear track differs still has its rear wheels on the front
wheels' tracks (the sedan's are equal). Both tracks are evaluated as sums of cosines on one FFT grid whose period is longer than the episode, its
previews and the delay together, so that the rear wheels' road before the episode's start is road the front
wheels crossed before it, never a wrapped copy of the episode's own road. A generic two-track generator could
move to :mod:`mrd_env.disturbances` once another plant needs one.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.special

from ...disturbances import ISO8608_N_MAX, ISO8608_N_MIN, Record, iso8608_psd
from ...disturbances.record import n_samples_for
from ...envs import randomize
from ...envs.disturbance import Disturbance, FixedRecord, Generated
from ...envs.options import MAX_PREVIEW
from ...resources import Budget
from ...validation import check_scalar
from .physics import CORNERS, ROAD_CHANNELS, ROAD_UNITS

SIDES = {"left": ("fl", "rl"), "right": ("fr", "rr"), "both": CORNERS}
#: The track (0 left, 1 right) and axle (0 front, 1 rear) of each corner.
_TRACK = {"fl": 0, "fr": 1, "rl": 0, "rr": 1}
_REAR = {"fl": False, "fr": False, "rl": True, "rr": True}
#: The length of a generated road without ``episode_seconds`` (s).
DEFAULT_SECONDS = 10.0


def preview_channels(times: tuple[float, ...]) -> tuple[str, ...]:
    """The road preview's channels: each wheel's road height τ ahead, wheel by wheel (fl, fr, rl, rr), each wheel's
    times in order."""
    return tuple(f"z_r{c}(t+{t:g}s)" for c in CORNERS for t in times)


def wheelbase_preview_channels(times: tuple[float, ...]) -> tuple[str, ...]:
    """The wheelbase preview's channels: the rear wheels' road τ ahead (rl, then rr), from the front wheels' past."""
    return tuple(f"z_r{c}(t+{t:g}s, front's past)" for c in ("rl", "rr") for t in times)


@dataclass(frozen=True)
class Geometry:
    """What a road kind needs of the car: the wheelbase and the track (m), and the preview times (s, multiples of
    dt) of the road preview and of the wheelbase preview."""

    wheelbase: float
    track: float
    preview: tuple[float, ...] = ()
    wheelbase_preview: tuple[float, ...] = ()

    @property
    def channels(self) -> tuple[str, ...]:
        """Every channel of a road record: the roads, then the previews."""
        return (*ROAD_CHANNELS, *preview_channels(self.preview), *wheelbase_preview_channels(self.wheelbase_preview))

    @property
    def units(self) -> tuple[str, ...]:
        return (*ROAD_UNITS, *["m"] * (len(self.channels) - len(ROAD_CHANNELS)))

    def horizon(self) -> float:
        """The furthest preview ahead (s)."""
        return max((*self.preview, *self.wheelbase_preview), default=0.0)

    def check_speed(self, speeds) -> None:
        """``ValueError`` naming ``wheelbase_preview`` if a time of it is beyond wheelbase/speed at the fastest of
        ``speeds``: the rear wheels' road that far ahead is road the front wheels have not met yet."""
        if not self.wheelbase_preview:
            return
        delay = self.wheelbase / max(speeds)
        if max(self.wheelbase_preview) > delay * (1.0 + 1e-12):
            raise ValueError(f"wheelbase_preview: the rear wheels' road ahead is the front wheels' past only up to "
                             f"wheelbase/speed = {self.wheelbase:g} m / {max(speeds):g} m/s = {delay:.4g} s, got "
                             f"times up to {max(self.wheelbase_preview):g} s (use the preview option for the road "
                             f"further ahead)")


def _evaluations(geometry: Geometry, delay: float) -> list[tuple[str, str, float]]:
    """(channel, 'z' or 'zdot', time offset s) of every channel of a record: each corner's road at t (rear: t −
    delay), then the previews at t + τ (rear: t + τ − delay)."""
    out = []
    for c in CORNERS:
        off = -delay if _REAR[c] else 0.0
        out += [(f"z_r{c}", "z", off), (f"zdot_r{c}", "zdot", off)]
    for name, (c, t) in zip(preview_channels(geometry.preview),
                            [(c, t) for c in CORNERS for t in geometry.preview]):
        out.append((name, "z", t - (delay if _REAR[c] else 0.0)))
    for name, (c, t) in zip(wheelbase_preview_channels(geometry.wheelbase_preview),
                            [(c, t) for c in ("rl", "rr") for t in geometry.wheelbase_preview]):
        out.append((name, "z", t - delay))
    return out


# --- the two-track ISO 8608 road ---------------------------------------------------------------------------------
def track_coherence(n, track: float, coherence="isotropic") -> np.ndarray:
    """ρ(n) between two parallel tracks ``track`` m apart at spatial frequencies ``n`` (cycle/m): the isotropic
    model's x K_1(x), x = 2π n track (see the module docstring), or a constant ``coherence`` in [0, 1]."""
    n = np.asarray(n, dtype=float)
    if isinstance(coherence, str):
        if coherence != "isotropic":
            raise ValueError(f"road_params['coherence'] must be 'isotropic' or a number in [0, 1], got {coherence!r}")
        x = 2.0 * math.pi * n * track
        return x * scipy.special.k1(x)
    return np.full(n.shape, float(coherence))


def _check_coherence(coherence):
    if isinstance(coherence, str):
        track_coherence(np.ones(1), 1.0, coherence)  # ValueError for an unknown name
        return coherence
    if isinstance(coherence, bool):
        raise ValueError(f"road_params['coherence'] must be 'isotropic' or a number in [0, 1], got {coherence!r}")
    return check_scalar("road_params['coherence']", coherence, 0.0, 1.0)


def two_track_spectrum(road_class: str, speed: float, m: int, dt: float, track: float, rng, *,
                       coherence="isotropic", n_min: float = ISO8608_N_MIN, n_max: float = ISO8608_N_MAX):
    """(k, left, right): the FFT lines k of a period of ``m`` samples at ``dt`` that fall in [n_min, n_max] cycle/m at
    ``speed``, and the complex amplitudes of the two tracks there, z(t) = Σ Re(X_k e^{i 2π k t / (m dt)}).

    Left: the quarter car's ISO 8608 amplitudes √(2 G_d(n_k) Δn) with phases uniform on [0, 2π) (as
    :func:`mrd_env.disturbances.iso8608_road`'s ``method="fft"``); right: ρ_k times the left plus √(1 − ρ_k²)
    times an independent track of the same spectrum, so that each track has the ISO spectrum and their
    cross-spectrum is ρ G_d (coherence ρ², ρ from :func:`track_coherence`)."""
    df = 1.0 / (m * dt)
    k = np.arange(1, m // 2)
    n_k = k * df / speed
    keep = (n_k >= n_min) & (n_k <= n_max)
    if not keep.any():
        raise ValueError(f"the road is too short to place any wave in [n_min, n_max] = [{n_min:g}, {n_max:g}] "
                         f"cycle/m at {speed:g} m/s")
    k, n_k = k[keep], n_k[keep]
    amp = np.sqrt(2.0 * iso8608_psd(n_k, road_class) * (df / speed))
    left = amp * np.exp(1j * rng.uniform(0.0, 2.0 * math.pi, k.size))
    other = amp * np.exp(1j * rng.uniform(0.0, 2.0 * math.pi, k.size))
    rho = track_coherence(n_k, track, coherence)
    return k, left, rho * left + np.sqrt(np.clip(1.0 - rho * rho, 0.0, 1.0)) * other


def _period(n: int, dt: float, geometry: Geometry, delay: float) -> int:
    """An FFT length whose period holds the episode, the longest preview any option may ask for (MAX_PREVIEW, not
    the geometry's own: the road under the wheels must not depend on whether a controller has preview, or a preview
    suite's episodes would not be its nominal suite's) and the delay (see the module docstring)."""
    ahead = int(math.ceil(max(MAX_PREVIEW, geometry.horizon()) / dt - 1e-9))
    return scipy.fft.next_fast_len(n + ahead + int(math.ceil(delay / dt)) + 1, real=True)


def two_track_iso8608(road_class, speed, duration: float, dt: float, rng, geometry: Geometry, *,
                      coherence="isotropic", n_min: float = ISO8608_N_MIN, n_max: float = ISO8608_N_MAX) -> Record:
    """One episode's two-track ISO 8608 road under the four wheels (class and speed drawn from ``rng`` where they
    are random: :mod:`mrd_env.envs.randomize`), with the previews of ``geometry``; the rear wheels on the front
    wheels' tracks exactly wheelbase/speed later."""
    c, v = randomize.draw(road_class, rng), randomize.draw(speed, rng)
    n = n_samples_for(duration, dt)
    delay = geometry.wheelbase / v
    m = _period(n, dt, geometry, delay)
    k, left, right = two_track_spectrum(c, v, m, dt, geometry.track, rng, coherence=coherence, n_min=n_min,
                                        n_max=n_max)
    omega = 2.0 * math.pi * k / (m * dt)
    cache: dict = {}

    def evaluate(track: int, what: str, offset: float) -> np.ndarray:
        key = (track, what, offset)
        if key not in cache:
            X = np.zeros(m // 2 + 1, dtype=np.complex128)
            X[k] = (left if track == 0 else right) * np.exp(1j * omega * offset)
            if what == "zdot":
                X[k] *= 1j * omega
            cache[key] = scipy.fft.irfft(X, m)[:n] * (m / 2.0)
        return cache[key]

    data = [evaluate(_track_of(ch), what, off) for ch, what, off in _evaluations(geometry, delay)]
    return Record(dt, np.column_stack(data), geometry.channels, geometry.units,
                  f"ISO 8608 class {c} two-track road at {v:g} m/s")


def _track_of(channel: str) -> int:
    """The track (0 left, 1 right) of a road channel ("z_rfl", "zdot_rrr", "z_rrl(t+0.1s)", ...)."""
    corner = channel.split("_r", 1)[1][:2]
    return _TRACK[corner]


def _iso8608(*, dt, episode_seconds, geometry: Geometry, budget=None, road_class="C", speed=20.0,
             coherence="isotropic", n_min=ISO8608_N_MIN, n_max=ISO8608_N_MAX, duration=None):
    """A new two-track road per episode; ``road_class`` may be a list and ``speed`` a range (lo, hi) drawn per
    episode."""
    seconds = _seconds(duration, episode_seconds, dt, budget, len(geometry.channels), generated=True)
    classes = randomize.values("road_params['road_class']", road_class, lambda v: v)
    speeds = randomize.values("road_params['speed']", speed,
                              lambda v: check_scalar("road_params['speed']", v, 0.0, lo_open=True, unit="m/s"))
    coherence = _check_coherence(coherence)
    n_min = check_scalar("road_params['n_min']", n_min, 0.0, lo_open=True, unit="cycle/m")
    n_max = check_scalar("road_params['n_max']", n_max, n_min, lo_open=True, unit="cycle/m")
    if n_max * max(speeds) >= 0.5 / dt:
        raise ValueError(f"road_params['speed']: the shortest wave (n_max = {n_max:g} cycle/m) at {max(speeds):g} m/s "
                         f"is beyond the Nyquist frequency at dt = {dt:g} s")
    geometry.check_speed(speeds)
    # the FFT grid holds the rear wheels' delay wheelbase/speed: at a slow speed it is far longer than the episode
    slowest = min(speeds)
    grid = _period(n_samples_for(seconds, dt), dt, geometry, geometry.wheelbase / slowest)
    (budget or Budget()).check_generation(
        n_samples_for(seconds, dt), dt, len(geometry.channels),
        f"road_params['speed']={slowest:g} m/s (the rear wheels' delay wheelbase/speed = "
        f"{geometry.wheelbase / slowest:.3g} s is part of the road's FFT grid) with a {seconds:g} s road",
        grid_samples=grid, what="the road", grid="generating the two-track road on its FFT grid")
    # the options are checked now, not at reset: every class, and a wave of the band at both ends of the speeds
    for c in classes:
        iso8608_psd(ISO8608_N_MIN, c)
    for v in speeds:
        m = _period(n_samples_for(seconds, dt), dt, geometry, geometry.wheelbase / v)
        n_k = np.arange(1, m // 2) / (m * dt) / v
        if not np.any((n_k >= n_min) & (n_k <= n_max)):
            raise ValueError(f"road_params: no road wave of [n_min, n_max] = [{n_min:g}, {n_max:g}] cycle/m fits a "
                             f"{seconds:g} s road at {v:g} m/s")
    return Generated(functools.partial(two_track_iso8608, road_class, speed, seconds, dt, geometry=geometry,
                                       coherence=coherence, n_min=n_min, n_max=n_max), geometry.channels,
                     f"ISO 8608 class {randomize.describe(road_class)} two-track road at "
                     f"{randomize.describe(speed)} m/s", max_samples=n_samples_for(seconds, dt))


# --- bumps and potholes on one side ------------------------------------------------------------------------------
def cosine_bump(t: np.ndarray, t_start: float, height: float, length: float, speed: float):
    """(z, ż) of a (1 − cos) bump of ``height`` and ``length`` met at ``t_start`` at ``speed``: z = height/2 (1 −
    cos(2π speed (t − t_start)/length)) over the bump, 0 elsewhere (:func:`mrd_env.disturbances.bump`'s shape)."""
    s = (t - t_start) * speed / length
    on = (s >= 0.0) & (s <= 1.0)
    phase = 2.0 * math.pi * np.where(on, s, 0.0)
    z = np.where(on, 0.5 * height * (1.0 - np.cos(phase)), 0.0)
    zd = np.where(on, 0.5 * height * np.sin(phase) * 2.0 * math.pi * speed / length, 0.0)
    return z, zd


def bump_record(height: float, length: float, speed: float, t_start: float, side: str, duration: float, dt: float,
                geometry: Geometry) -> Record:
    """The roads of a bump (or, ``height`` < 0, a pothole) on ``side`` under the four wheels, with the previews."""
    n = n_samples_for(duration, dt)
    t = np.arange(n) * dt
    delay = geometry.wheelbase / speed
    hit = SIDES[side]
    data = []
    for ch, what, off in _evaluations(geometry, delay):
        corner = ch.split("_r", 1)[1][:2]
        if corner not in hit:
            data.append(np.zeros(n))
            continue
        z, zd = cosine_bump(t + off, t_start, height, length, speed)
        data.append(z if what == "z" else zd)
    kind = "bump" if height >= 0 else "pothole"
    return Record(dt, np.column_stack(data), geometry.channels, geometry.units,
                  f"{abs(height) * 100:g} cm {kind} on the {side} side at {speed:g} m/s")


def _one_side(*, dt, geometry, budget, height, length, speed, t_start, side, duration, what):
    height = check_scalar(f"road_params['{what}']", height, 0.0, lo_open=True, unit="m") * (1 if what == "height"
                                                                                            else -1)
    length = check_scalar("road_params['length']", length, 0.0, lo_open=True, unit="m")
    speed = check_scalar("road_params['speed']", speed, 0.0, lo_open=True, unit="m/s")
    t_start = check_scalar("road_params['t_start']", t_start, 0.0, unit="s")
    if side not in SIDES:
        raise ValueError(f"road_params['side'] must be one of {list(SIDES)}, got {side!r}")
    geometry.check_speed([speed])
    if duration is None:  # the rear wheels off it and 2 s more
        duration = t_start + geometry.wheelbase / speed + length / speed + 2.0
    seconds = _seconds(duration, None, dt, budget, len(geometry.channels))
    return FixedRecord(bump_record(height, length, speed, t_start, side, seconds, dt, geometry), geometry.channels,
                       geometry.units, dt)


def _bump(*, dt, episode_seconds, geometry: Geometry, budget=None, height=0.05, length=1.0, speed=10.0,
          t_start=0.5, side="left", duration=None):
    """A bump on one side (default: the left wheels)."""
    return _one_side(dt=dt, geometry=geometry, budget=budget, height=height, length=length, speed=speed,
                     t_start=t_start, side=side, duration=duration, what="height")


def _pothole(*, dt, episode_seconds, geometry: Geometry, budget=None, depth=0.05, length=0.5, speed=10.0,
             t_start=0.5, side="left", duration=None):
    """A pothole on one side (default: the left wheels)."""
    return _one_side(dt=dt, geometry=geometry, budget=budget, height=depth, length=length, speed=speed,
                     t_start=t_start, side=side, duration=duration, what="depth")


def _seconds(duration, episode_seconds, dt: float, budget: Budget | None, channels: int,
             generated: bool = False) -> float:
    """The length of a road (``duration``, else the episode's, else 10 s), checked against the memory limit."""
    if duration is None:
        seconds, cause = episode_seconds or DEFAULT_SECONDS, f"episode_seconds={episode_seconds or DEFAULT_SECONDS:g}"
    else:
        seconds = check_scalar("road_params['duration']", duration, dt, unit="s")
        cause = f"road_params['duration']={duration!r}"
    (budget or Budget()).check_record(seconds / dt + 1, dt, channels, cause, what="the road", generated=generated)
    return float(seconds)


ROADS = {"iso8608": _iso8608, "bump": _bump, "pothole": _pothole}


def road_source(road, road_params, dt: float, episode_seconds, geometry: Geometry,
                budget: Budget | None = None) -> Disturbance:
    """The road part, by the quarter car's rule (:func:`mrd_env.envs.roads.road_source`): a kind of :data:`ROADS`
    (with ``road_params``), a dict {"kind": ..., options}, a Record with the channels z_rfl, zdot_rfl, ..., zdot_rrr
    (m, m/s), or a :class:`~mrd_env.envs.disturbance.Disturbance`."""
    from ...envs.roads import road_source as car_road

    return car_road(road, road_params, dt, episode_seconds, kinds=ROADS, channels=ROAD_CHANNELS, units=ROAD_UNITS,
                    geometry=geometry, budget=budget)
