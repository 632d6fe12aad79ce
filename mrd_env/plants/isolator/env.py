"""The MR isolator (``mrd_env/IsolatorPhysical-v0``): a payload on a spring and an MR damper, on a moving base."""
from __future__ import annotations

import functools
import math

import numpy as np

from ...disturbances import Record, sine_sweep
from ...disturbances.record import n_samples_for
from ...envs import options as opt
from ...envs import randomize
from ...envs.base import MRDamperEnv
from ...envs.build import as_options, build
from ...envs.core import Assembly, Episode, EpisodeStats
from ...envs.costs import SOFT_STROKE_FRACTION, Constraint, Costs, exceedance_share, soft_limit
from ...envs.disturbance import Disturbance, FixedRecord, Generated
from ...envs.reward import QuadraticReward
from ...envs.signals import SignalMap
from ...envs.termination import Limits
from ...envs.vector import MRDamperVectorEnv
from ...mechanics import CoupledPlant
from ...metrics import weighting_sos
from ...resources import FLOAT, Budget
from ...validation import check_scalar
from . import SPEC
from .physics import IsolatorParams, isolator

#: Reference scales of the reward (SI): the payload's absolute acceleration and the stroke.
A_REF = 1.0     # m/s²
X_REF = 0.025   # m (half the default stroke limit)
#: The base motion's channels: displacement, velocity and acceleration (the acceleration drives the plant).
CHANNELS = ("z_b", "zdot_b", "zddot_b")
UNITS = ("m", "m/s", "m/s^2")
SENSOR_UNITS = {"payload_acc": "m/s^2", "stroke": "m", "stroke_rate": "m/s", "payload_vel": "m/s",
                "base_vel": "m/s", "base_acc": "m/s^2", "damper_force": "N", "command": "cmd",
                "damper_states": "model"}
#: What an instrumented isolator measures (and every controller and agent gets by default): an accelerometer on
#: the payload and its integral (the absolute velocity skyhook needs), the stroke and its rate, the base's
#: velocity (an integrated accelerometer on the base), the damper's load cell and the command sent.
DEFAULT_SENSORS = ("payload_acc", "stroke", "stroke_rate", "payload_vel", "base_vel", "damper_force", "command")
DEFAULT_REWARD_WEIGHTS = {"acc": 1.0, "stroke": 0.5, "termination": 10.0}
#: The reward's terms: the signal of each weight, and its reference mean square.
REWARD_SIGNALS = {"acc": "payload_acc", "stroke": "stroke"}
REFERENCE = {"payload_acc": A_REF ** 2, "stroke": X_REF ** 2}
#: ``force_range`` of ``action_mode="force"`` (N): about the force of the default damper at full command.
FORCE_RANGE = 1000.0
#: The length of a generated base motion without ``episode_seconds`` (s).
DEFAULT_SECONDS = 10.0


# --- the base motion: one rule, these kinds ----------------------------------------------------------------------
def _seconds(duration, episode_seconds, dt: float, budget: Budget | None, generated: bool = False) -> float:
    """The length of a generated base motion (``duration``, else the episode's, else 10 s), checked against the
    memory limit with the episode on it."""
    if duration is None:
        seconds, cause = episode_seconds or DEFAULT_SECONDS, f"episode_seconds={episode_seconds or DEFAULT_SECONDS:g}"
    else:
        seconds = check_scalar("base_motion_params['duration']", duration, dt, unit="s")
        cause = f"base_motion_params['duration']={duration!r}"
    (budget or Budget()).check_record(seconds / dt + 1, dt, len(CHANNELS), cause, what="the base motion",
                                      generated=generated)
    return float(seconds)


def _positive(name: str, unit: str, hi: float = math.inf):
    return lambda v: check_scalar(f"base_motion_params[{name!r}]", v, 0.0, hi, lo_open=True, hi_open=True, unit=unit)


def _harmonic_record(amplitude, frequency, duration: float, dt: float, rng=None) -> Record:
    """z_b = A sin(2π f t) and its exact derivatives (``amplitude`` and ``frequency`` drawn from ``rng`` where they
    are random: :mod:`~mrd_env.envs.randomize`)."""
    a, f = randomize.draw(amplitude, rng), randomize.draw(frequency, rng)
    t = np.arange(n_samples_for(duration, dt)) * dt
    w = 2.0 * math.pi * f
    s, c = np.sin(w * t), np.cos(w * t)
    return Record(dt, np.column_stack([a * s, a * w * c, -a * w * w * s]), CHANNELS, UNITS,
                  f"harmonic base {a:g} m at {f:g} Hz")


def _harmonic(*, dt, episode_seconds, budget=None, amplitude=0.01, frequency=1.5, duration=None):
    """A sinusoidal base displacement; ``amplitude`` (m) and ``frequency`` (Hz) may be ranges or lists drawn per
    episode."""
    randomize.values("base_motion_params['amplitude']", amplitude, _positive("amplitude", "m"))
    randomize.values("base_motion_params['frequency']", frequency, _positive("frequency", "Hz", 0.5 / dt))
    drawn = randomize.is_random(amplitude) or randomize.is_random(frequency)
    seconds = _seconds(duration, episode_seconds, dt, budget, generated=drawn)
    if drawn:
        return Generated(functools.partial(_harmonic_record, amplitude, frequency, seconds, dt), CHANNELS,
                         f"harmonic base {randomize.describe(amplitude)} m at {randomize.describe(frequency)} Hz",
                         max_samples=n_samples_for(seconds, dt))
    return FixedRecord(_harmonic_record(amplitude, frequency, seconds, dt), CHANNELS, UNITS, dt)


def _sweep(*, dt, episode_seconds, budget=None, amplitude=0.002, f_start=0.5, f_end=10.0, sweep="log",
           duration=None):
    """A constant-amplitude displacement sweep (:func:`mrd_env.disturbances.sine_sweep`: ``sweep`` "log" or
    "linear"), with its exact acceleration."""
    seconds = _seconds(duration, episode_seconds, dt, budget)
    try:
        rec = sine_sweep(amplitude, f_start, f_end, seconds, dt=dt, kind=sweep)
    except ValueError as e:
        raise ValueError(f"base_motion 'sine_sweep': {e}".replace("kind must", "sweep must")) from None
    z, zd = rec.data[:, 0], rec.data[:, 1]
    t, f_start, f_end = rec.t, float(f_start), float(f_end)
    if sweep == "linear":
        f = f_start + (f_end - f_start) * t / seconds
        fdot = np.full_like(t, (f_end - f_start) / seconds)
    else:
        f = f_start * (f_end / f_start) ** (t / seconds)
        fdot = f * math.log(f_end / f_start) / seconds
    # z = A sin φ, ż = A 2πf cos φ with φ̇ = 2πf: z̈ = (ḟ/f) ż − (2πf)² z
    zdd = fdot / f * zd - (2.0 * math.pi * f) ** 2 * z
    return FixedRecord(Record(dt, np.column_stack([z, zd, zdd]), CHANNELS, UNITS, f"base {rec.name}"), CHANNELS,
                       UNITS, dt)


def _period(duration: float, dt: float) -> int:
    """Samples in one period of the random base motion: the record's, at least 10 s (lines 0.1 Hz apart or closer,
    however short the episode)."""
    return max(n_samples_for(duration, dt), n_samples_for(DEFAULT_SECONDS, dt)) - 1


def _random_record(acc_rms, f_low: float, f_high: float, duration: float, dt: float, rng) -> Record:
    """A random-phase multisine base acceleration: every frequency line k/T of [f_low, f_high] at one amplitude and
    a phase drawn from ``rng`` (a stationary, nearly Gaussian band-limited noise of flat acceleration spectrum,
    periodic over T = max(duration, 10 s), its r.m.s. over a period exactly ``acc_rms``), its velocity and
    displacement integrated exactly in the frequency domain (zero mean, no drift); cut to ``duration``."""
    a_rms = randomize.draw(acc_rms, rng)
    n = n_samples_for(duration, dt)
    m = _period(duration, dt)                   # one period; its first sample closes it
    f = np.fft.rfftfreq(m, dt)
    band = (f >= f_low) & (f <= f_high) & (f > 0.0)
    spectrum = np.zeros(f.size, dtype=complex)
    spectrum[band] = np.exp(1j * rng.uniform(0.0, 2.0 * math.pi, int(band.sum())))
    w = 2.0 * math.pi * f[band]
    vel, disp = np.zeros_like(spectrum), np.zeros_like(spectrum)
    vel[band] = spectrum[band] / (1j * w)
    disp[band] = -spectrum[band] / (w * w)
    acc = np.fft.irfft(spectrum, m)
    scale = a_rms / math.sqrt(float(np.mean(acc ** 2)))
    data = np.column_stack([np.fft.irfft(disp, m), np.fft.irfft(vel, m), acc]) * scale
    return Record(dt, np.vstack([data, data[:1]])[:n], CHANNELS, UNITS,
                  f"random base {a_rms:g} m/s² r.m.s., {f_low:g}-{f_high:g} Hz")


def _random(*, dt, episode_seconds, budget=None, acc_rms=1.0, f_low=0.5, f_high=5.0, duration=None):
    """A new random base motion per episode (:func:`_random_record`); ``acc_rms`` (m/s²) may be a range or a list
    drawn per episode. The default band, 0.5–5 Hz, is illustrative: the low-frequency band of a vehicle floor's
    vibration, across the seat's resonance, where a suspension seat has to work; on it neither passive extreme is
    the best command (passive-off and passive-on score alike over the training distribution, continuous skyhook
    about 16 % better, on 8 validation episodes at 1 and 10 ms), while over 0.5–10 Hz the soft damper wins and no law beats passive-off."""
    randomize.values("base_motion_params['acc_rms']", acc_rms, _positive("acc_rms", "m/s^2"))
    f_low = check_scalar("base_motion_params['f_low']", f_low, 0.0, 0.5 / dt, lo_open=True, hi_open=True, unit="Hz")
    f_high = check_scalar("base_motion_params['f_high']", f_high, f_low, 0.5 / dt, hi_open=True, unit="Hz")
    seconds = _seconds(duration, episode_seconds, dt, budget, generated=True)
    m = _period(seconds, dt)
    if m < 2 or not np.any((np.fft.rfftfreq(m, dt) >= f_low) & (np.fft.rfftfreq(m, dt) <= f_high)):
        raise ValueError(f"base_motion 'random': no frequency line k/T (T = {m * dt:g} s) lies in [f_low, f_high] = "
                         f"[{f_low:g}, {f_high:g}] Hz; widen the band or lengthen the record")
    return Generated(functools.partial(_random_record, acc_rms, f_low, f_high, seconds, dt), CHANNELS,
                     f"random base {randomize.describe(acc_rms)} m/s² r.m.s., {f_low:g}-{f_high:g} Hz",
                     max_samples=n_samples_for(seconds, dt))


BASE_MOTIONS = {"harmonic": _harmonic, "sine_sweep": _sweep, "random": _random}


def base_motion_source(base_motion, base_motion_params, dt: float, episode_seconds,
                       budget: Budget | None = None) -> Disturbance:
    """The base-motion part: a kind name (with ``base_motion_params``), a dict ``{"kind": ..., **options}``, a
    :class:`~mrd_env.disturbances.Record` with channels z_b, zdot_b, zddot_b (m, m/s, m/s²), or a
    :class:`~mrd_env.envs.disturbance.Disturbance`."""
    if isinstance(base_motion, Record):
        if base_motion_params:
            raise ValueError("base_motion_params apply to a base-motion kind, not to a Record")
        return FixedRecord(base_motion, CHANNELS, UNITS, dt)
    if base_motion_params is not None:
        if not isinstance(base_motion, str):
            raise ValueError("base_motion_params apply to a base-motion kind given by name (e.g. "
                             f"base_motion='harmonic'), not to {type(base_motion).__name__}")
        base_motion = {"kind": base_motion, **as_options(f"base_motion_params (base_motion={base_motion!r})",
                                                          base_motion_params)}
    return build("base_motion", base_motion, BASE_MOTIONS, "random", Disturbance, dt=dt,
                 episode_seconds=episode_seconds, budget=budget)


# --- the assembly ------------------------------------------------------------------------------------------------
def _plant_params(plant_preset, plant_params) -> IsolatorParams:
    return opt.plant_parameters(IsolatorParams, isolator, plant_preset, plant_params)


def signals(coupled: CoupledPlant, command_unit: str) -> SignalMap:
    """The isolator's named signals (see :class:`IsolatorEnv`); the coordinate is the stroke x_d = x − z_b."""
    sm = SignalMap(coupled)
    base_disp, base_vel, base_acc = ([[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]], [[0.0, 0.0, 1.0]])
    sm.add("payload_acc", sm.acc([1.0]) + sm.inp(base_acc), "m/s^2")
    sm.add("stroke", sm.disp([1.0]), "m")
    sm.add("stroke_rate", sm.vel([1.0]), "m/s")
    sm.add("payload_vel", sm.vel([1.0]) + sm.inp(base_vel), "m/s")
    sm.add("base_vel", sm.inp(base_vel), "m/s")
    sm.add("base_acc", sm.inp(base_acc), "m/s^2")
    sm.add("damper_force", sm.force(), "N")
    sm.add("damper_states", sm.damper_states(), "model")
    sm.add("_x", sm.disp([1.0]) + sm.inp(base_disp), "m")  # the payload's absolute displacement (renderer)
    sm.add("_base", sm.inp(base_disp), "m")
    sm.add_commands(command_unit)
    sm.add_output("payload_acc_wk", "m/s^2")
    return sm


def nominal_reference() -> dict:
    """{reward signal: mean square} of the reward's normaliser: its fixed reference scales (A_REF², X_REF²), on
    any base motion — what ``weights="reward"`` of the model-based laws divides by, so that their cost is the
    reward's own cost rate."""
    return dict(REFERENCE)


def _per_reference(ep: Episode) -> np.ndarray:
    """The reward's weights per unit of the reference mean squares (fixed: the same every episode)."""
    return np.array([1.0 / REFERENCE[s] for s in REWARD_SIGNALS.values()])


def metrics(stats: EpisodeStats, episode: Episode) -> dict[str, float]:
    """The isolation of an episode: the payload's acceleration (r.m.s., peak, ISO 2631-1 Wk-weighted r.m.s., VDV,
    MTVV over 1 s), its r.m.s. over the base's (a transmissibility of the episode), the stroke, the damper
    force (the measured force, preload included) and the share of the time the stroke is beyond its soft limit."""
    r, pk = stats.rms, stats.peak
    acc, base = float(r["payload_acc"][0]), float(r["base_acc"][0])
    return {"acc_rms": acc, "acc_peak": float(pk["payload_acc"][0]),
            "acc_weighted_rms": float(r["payload_acc_wk"][0]), "acc_vdv": float((stats.dose4 * stats.dt) ** 0.25),
            "acc_mtvv": stats.max_running_rms, "transmissibility": acc / base if base > 0 else math.nan,
            "stroke_rms": float(r["stroke"][0]), "stroke_peak": float(pk["stroke"][0]),
            "damper_force_rms": float(r["damper_force"][0]), "damper_force_peak": float(pk["damper_force"][0]),
            "duration": (stats.n_rows - 1) * stats.dt, "stroke_exceedance_share": exceedance_share(stats)}


def _new_episode(rec: Record) -> Episode:
    """The payload at rest relative to the base (zero stroke and stroke rate: moving with it), in static
    equilibrium, wherever the base starts."""
    return Episode(rec, np.zeros(2))


def assembly(*, plant_preset: str = "seat", plant_params=None, base_motion="random", base_motion_params=None,
             damper="spencer_dyke", damper_preset: str | None = None, damper_params=None, dt: float = 1e-3,
             control_dt: float = 1e-3, episode_seconds: float | None = DEFAULT_SECONDS, sensors=None,
             sensor_noise=None, sensor_delay: int = 0, history: int = 1, action_mode: str = "physical",
             inverse=None, force_range: float | None = None, reward=None, reward_weights=None,
             stroke_limit: float = 0.05, soft_stroke_limit: float | None = None) -> Assembly:
    """The isolator environment's parts from its options (see :class:`IsolatorEnv`)."""
    given = {k: v for k, v in locals().items()}
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    p = _plant_params(plant_preset, plant_params)
    d = opt.make_env_damper(damper, damper_preset, damper_params, "automotive")
    lp = p.plant()
    coupled = CoupledPlant(lp, d)
    sm = signals(coupled, d.command.unit)
    w = opt.weights(reward_weights, DEFAULT_REWARD_WEIGHTS)
    reward = opt.reward(reward, lambda: QuadraticReward({REWARD_SIGNALS[k]: w[k] for k in REWARD_SIGNALS},
                                                        episode_scale=_per_reference))
    limit = opt.check_scalar("stroke_limit", stroke_limit, 0.0, lo_open=True, unit="m")
    soft = soft_limit("soft_stroke_limit", soft_stroke_limit, limit, SOFT_STROKE_FRACTION)
    if opt.action_mode(action_mode) == "force" and force_range is None:
        force_range = FORCE_RANGE
    source = base_motion_source(base_motion, base_motion_params, dt, episode_seconds,
                                budget=Budget(FLOAT * coupled.system.nw))

    from .render import IsolatorRenderer

    return Assembly(
        kind=SPEC.name, damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=tuple(SENSOR_UNITS),
        sensors=opt.sensors(sensors, sensor_noise, sensor_delay, history, DEFAULT_SENSORS),
        disturbance=source, reward=reward,
        limits=Limits({"stroke": limit}, penalty=0.0, penalty_rate=w["termination"]),
        new_episode=_new_episode, metrics=metrics,
        # the base plays the wheel's part: groundhook and the hybrid law act on the damper's velocity against it
        roles={"body_velocity": "payload_vel", "wheel_velocity": "base_vel", "damper_velocity": "stroke_rate",
               "damper_stroke": "stroke", "damper_force": "damper_force"},
        objective={"payload_acc": 1.0 / A_REF ** 2, "stroke": 1.0 / X_REF ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        filters=[("payload_acc", "payload_acc_wk", weighting_sos("Wk", dt))],
        stat_signals=("payload_acc", "payload_acc_wk", "base_acc", "stroke", "damper_force"),
        dose_signal="payload_acc_wk", dose_window=1.0, renderer=IsolatorRenderer, options=given,
        nominal_reference=nominal_reference, costs=Costs({"stroke": Constraint("stroke", soft)}))


class IsolatorEnv(MRDamperEnv):
    """Single-degree-of-freedom isolator: a payload on a spring with an MR damper, on a moving base.

    ## Description

    A payload of mass m on a spring k (and an optional parallel dashpot c_p), an MR damper between it and a base
    that moves z_b(t) — a suspension seat on a cab floor, an instrument on a vibrating machine frame (the review's
    Table 1 lists washing machines; its conclusion, whole-body vibration protection). Physics at ``dt`` = 1 ms,
    the command held over each control period (``control_dt``). The task: keep the payload still (its absolute
    acceleration) within the stroke the isolator has, by choosing only the damper's command. A soft damper
    isolates above √2 times the natural frequency but lets the resonance through; a hard one locks the payload to
    the base. Equations and parameters: :mod:`mrd_env.plants.isolator.physics`.

    ## Action Space

    One command, a ``Box`` of shape ``(1,)``, float32: in ``Physical-v0`` the damper's command in V or A,
    [v_min, v_max] of the preset ([0, 2] V for the default "automotive" Spencer–Dyke damper); in ``-v1``
    normalised to [−1, 1]; with ``action_mode="force"`` the desired damper force beyond the static preload (N,
    default ``force_range`` 1000 N). See :class:`~mrd_env.envs.base.MRDamperEnv`.

    ## Observation Space

    A ``Box(-inf, inf)``, float32, of the chosen sensors in order (``env.unwrapped.sensor_layout``). The default
    sensors (every controller and agent gets the same), shape ``(7,)``:

    | Index | Sensor | Quantity | Unit |
    |---|---|---|---|
    | 0 | ``payload_acc`` | payload's absolute acceleration ẍ (gravity removed) | m/s² |
    | 1 | ``stroke`` | damper stroke x − z_b (extension positive) | m |
    | 2 | ``stroke_rate`` | its rate ẋ − ż_b | m/s |
    | 3 | ``payload_vel`` | payload's absolute velocity ẋ | m/s |
    | 4 | ``base_vel`` | base velocity ż_b | m/s |
    | 5 | ``damper_force`` | damper force (load cell, includes the static preload) | N |
    | 6 | ``command`` | the command applied over the last step | V or A |

    Also available: ``base_acc`` z̈_b (m/s², a base accelerometer) and ``damper_states`` (the model's internal
    states). Noise, delay and history apply to every sensor.

    ## Rewards

    The cost integrated over the control period (so returns do not depend on the control rate)::

        r = −∫ (w_acc ẍ² / (1 m/s²)² + w_stroke x_d² / (0.025 m)²) dt

    ẍ the payload's absolute acceleration, x_d the stroke; ``reward_weights`` acc 1.0, stroke 0.5. An episode
    ended by the stroke limit loses ``reward_weights["termination"]`` = 10 × its planned length in seconds.
    ``weights="reward"`` of the model-based laws designs on this cost (the reference scales are fixed, so the
    nominal reference is those scales on any base motion).

    ## Starting State

    In static equilibrium and at rest relative to the base — zero stroke, zero stroke rate: the payload moves with
    the base at its initial velocity. A random base motion is new each episode, drawn from ``np_random``
    (``reset(seed=...)``).

    ## Episode End

    ``terminated`` when |stroke| exceeds ``stroke_limit`` (0.05 m; ``info["termination_reason"] =
    "stroke_limit"``) or the simulation diverges; ``truncated`` after ``episode_seconds`` (10 s:
    ``env.spec.max_episode_steps`` 10 000 steps in ``Physical-v0``, 1 000 in ``-v1``).

    Constraint cost (:mod:`mrd_env.envs.costs`): ``info["cost"]`` the time (s) during the control period at which
    |stroke| is beyond ``soft_stroke_limit`` (default 0.8 × ``stroke_limit`` = 0.04 m: the end stops' travel;
    illustrative), counted on the physics rows; ``info["cost_terms"]`` = {"stroke": s}.

    ``info["episode_metrics"]`` at the end of an episode: acc_rms, acc_peak (m/s², the payload's absolute
    acceleration), acc_weighted_rms, acc_vdv (m/s^1.75), acc_mtvv (ISO 2631-1 Wk; MTVV over 1 s),
    transmissibility (acc_rms over the base acceleration's r.m.s. over the episode), stroke_rms, stroke_peak (m),
    damper_force_rms, damper_force_peak (N), duration (s), stroke_exceedance_share (the share of the time
    |stroke| is beyond the soft limit), cost, cost_stroke (s).

    ## Arguments

    Keyword-only; every bad value raises ``ValueError`` naming the option:

    * ``plant_preset``: "seat" (default: 100 kg at 1.5 Hz, :data:`~mrd_env.plants.isolator.ISOLATOR_PRESETS`);
      ``plant_params``: a dict of :class:`~mrd_env.plants.isolator.IsolatorParams` overrides (m, k, c_p), or an
      ``IsolatorParams``.
    * ``damper`` (model name, default "spencer_dyke", or a ``DamperModel``), ``damper_preset`` (default
      "automotive" where the model has it), ``damper_params`` (overrides).
    * ``base_motion`` (one rule: a kind name, a dict ``{"kind": ..., **options}``, a
      :class:`~mrd_env.disturbances.Record` with channels z_b, zdot_b, zddot_b (m, m/s, m/s²), or a
      :class:`~mrd_env.envs.disturbance.Disturbance`): "random" (default; new each episode: a random-phase
      multisine acceleration, flat from ``f_low`` 0.5 Hz to ``f_high`` 5 Hz, periodic over the episode or 10 s,
      whichever is longer, ``acc_rms`` 1 m/s² over a period — or a range (lo, hi) or list drawn per episode;
      displacement and velocity integrated exactly, no drift), "harmonic" (``amplitude`` 0.01 m, ``frequency`` 1.5 Hz; either may be
      a range or a list), "sine_sweep" (``amplitude`` 0.002 m, ``f_start`` 0.5 Hz, ``f_end`` 10 Hz, ``sweep``
      "log" or "linear"); each takes ``duration`` (s, default ``episode_seconds``); ``base_motion_params``: the
      options of a named kind.
    * ``episode_seconds`` (10 s; None: the record's length), ``dt`` 1e-3 s, ``control_dt`` 1e-3 s (an integer
      multiple of dt).
    * ``sensors``, ``sensor_noise`` ({name: std} SI), ``sensor_delay`` (control steps), ``history``.
    * ``action_mode``: "physical", "normalized" or "force" (with ``inverse`` and ``force_range``, default 1000 N).
    * ``reward_weights`` (acc 1.0, stroke 0.5, termination 10 per second) or ``reward`` (a
      :class:`~mrd_env.envs.reward.QuadraticReward` or any callable of the period's signals).
    * ``stroke_limit`` (default 0.05 m on |x − z_b|: the episode ends), ``soft_stroke_limit`` (m, in (0,
      ``stroke_limit``]; default 0.8 × ``stroke_limit``: a cost), ``render_mode`` ("rgb_array", "human").

    ## Version History

    * v1: the defaults an RL user expects — ``control_dt`` = 0.01 s (100 Hz) and ``action_mode="normalized"``
      (:data:`mrd_env.envs.RL_DEFAULTS`).
    * v0: the physics-level defaults — a command in V or A at every 1 ms step.
    """

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


class IsolatorVectorEnv(MRDamperVectorEnv):
    """``num_envs`` isolators in one compiled call (``gymnasium.make_vec("mrd_env/IsolatorPhysical-v0",
    num_envs=N, vectorization_mode="vector_entry_point", **options)``; options as :class:`IsolatorEnv`)."""

    env_id = SPEC.physics_id
    build = staticmethod(assembly)
