"""Quarter car with an MR damper between the sprung and unsprung masses (``mrd_env/QuarterCarPhysical-v0``)."""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ...disturbances import Record, iso8608_road
from ...metrics import weighting_sos
from ...mechanics import CoupledPlant, LinearPlant
from . import SPEC
from .physics import QuarterCarParams, quarter_car
from ...mechanics import foh_response
from ...resources import FLOAT, Budget
from ...envs import options as opt
from ...envs.base import MRDamperEnv
from ...envs.roads import ROAD_CHANNELS, ROAD_UNITS, road_source  # noqa: F401  (the car's road rule)
from ...envs.core import Assembly, Episode, EpisodeStats
from ...envs.costs import SOFT_STROKE_FRACTION, car_costs, exceedance_share, soft_limit
from ...envs.disturbance import Generated, with_preview
from ...envs.reward import QuadraticReward
from ...envs.signals import SignalMap
from ...envs.termination import Limits
from ...envs.vector import MRDamperVectorEnv

#: Reference scales of the quarter-car reward (SI).
A_REF = 1.0     # m/s², Wk-weighted sprung acceleration
X_REF = 0.05    # m, suspension travel

SENSOR_UNITS = {"sprung_acc": "m/s^2", "unsprung_acc": "m/s^2", "travel": "m", "travel_rate": "m/s",
                "sprung_vel": "m/s", "unsprung_vel": "m/s", "damper_force": "N", "command": "cmd", "road": "m",
                "road_preview": "m", "damper_states": "model"}
#: What a test car measures (and what every controller and agent gets by default, for a fair comparison): body and
#: wheel accelerometers, their integrals (the absolute velocities), a suspension displacement sensor and its
#: derivative, the damper's load cell and the command the controller itself sent.
DEFAULT_SENSORS = ("sprung_acc", "unsprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel",
                   "damper_force", "command")
DEFAULT_REWARD_WEIGHTS = {"comfort": 0.5, "travel": 0.25, "tyre": 0.25, "termination": 10.0}
#: The reward's terms: the signal of each weight.
REWARD_SIGNALS = {"comfort": "sprung_acc_wk", "travel": "travel", "tyre": "_tyre_load"}
#: Floats per record sample an episode computes at reset (the passive car's response), for the memory estimate.
EPISODE_FLOATS = 10


# --- the assembly ------------------------------------------------------------------------------------------------
def _plant_params(plant_preset, plant_params) -> QuarterCarParams:
    return opt.plant_parameters(QuarterCarParams, quarter_car, plant_preset, plant_params)


def preview_channels(times: tuple[float, ...]) -> tuple[str, ...]:
    """The input channels of the road ahead: z_r at t + τ for each preview time τ (s)."""
    return tuple(f"z_r(t+{t:g}s)" for t in times)


def with_preview_inputs(lp: LinearPlant, times: tuple[float, ...]) -> LinearPlant:
    """``lp`` with one more input per preview time, which the plant ignores (zero columns of E): the road ahead
    rides along in the input record so that a sensor can read it, and the dynamics do not change."""
    if not times:
        return lp
    return dataclasses.replace(lp, E=np.hstack([lp.E, np.zeros((lp.n_dof, len(times)))]),
                               input_names=(*lp.input_names, *preview_channels(times)))


def signals(coupled: CoupledPlant, p: QuarterCarParams, command_unit: str) -> SignalMap:
    """The quarter car's named signals (see :class:`QuarterCarEnv`)."""
    sm = SignalMap(coupled)
    n_preview = len(coupled.plant.input_names) - len(ROAD_CHANNELS)
    sm.add("sprung_acc", sm.acc([1.0, 0.0]), "m/s^2")
    sm.add("unsprung_acc", sm.acc([0.0, 1.0]), "m/s^2")
    sm.add("travel", sm.disp([1.0, -1.0]), "m")
    sm.add("travel_rate", sm.vel([1.0, -1.0]), "m/s")
    sm.add("sprung_vel", sm.vel([1.0, 0.0]), "m/s")
    sm.add("unsprung_vel", sm.vel([0.0, 1.0]), "m/s")
    sm.add("damper_force", sm.force(), "N")
    sm.add("road", sm.inp([[1.0, 0.0]]), "m")
    if n_preview:
        sm.add("road_preview", sm.inp(np.hstack([np.zeros((n_preview, 2)), np.eye(n_preview)])), "m")
    sm.add("damper_states", sm.damper_states(), "model")
    sm.add("_z", sm.disp(np.eye(2)), "m")
    # dynamic tyre load k_t (z_r − z_u) + c_t (ż_r − ż_u), positive = more load than static
    sm.add("_tyre_load", -p.k_t * sm.disp([0.0, 1.0]) - p.c_t * sm.vel([0.0, 1.0]) + sm.inp([[p.k_t, p.c_t]]), "N")
    sm.add_commands(command_unit)
    sm.add_output("sprung_acc_wk", "m/s^2")
    return sm


def passive_reference(p: QuarterCarParams, rec: Record, q0: np.ndarray, rows: int, dt: float) -> dict:
    """Mean squares of the reward's terms (Wk-weighted sprung acceleration, travel, dynamic tyre load) for the
    conventional passive car — the set's passive damper ``passive_c`` in place of the MR damper, a linear plant
    simulated exactly — on the record's first ``rows`` samples: the reward's units."""
    import scipy.signal

    lp = p.plant()
    A, _, Bw = lp.state_space(extra_damping=p.passive_c)
    w = np.asarray(rec.data[:rows])
    X = foh_response(A, Bw, w, dt, x0=q0)
    acc = X @ A[2:3].T + w @ Bw[2:3].T
    a_w = scipy.signal.sosfilt(weighting_sos("Wk", dt), acc[:, 0])
    travel = X[:, 0] - X[:, 1]
    tyre = p.k_t * (w[:, 0] - X[:, 1]) + p.c_t * (w[:, 1] - X[:, 3])
    tail = slice(1, None) if rows > 1 else slice(None)
    return {"comfort": float(np.mean(a_w[tail] ** 2)), "travel": float(np.mean(travel[tail] ** 2)),
            "tyre": float(np.mean(tyre[tail] ** 2))}


def _absolute_reference(p: QuarterCarParams) -> dict:
    """Fixed reference scales, for a car without a passive reference damper (``passive_c`` = 0)."""
    return {"comfort": A_REF ** 2, "travel": X_REF ** 2, "tyre": p.static_tyre_load ** 2}


#: The nominal road of weights="reward"'s fixed reference scales (:func:`nominal_reference`).
NOMINAL_ROAD = {"road_class": "C", "speed": 20.0, "duration": 100.0, "seed": 0}


def nominal_reference(p: QuarterCarParams, dt: float) -> dict:
    """{reward signal: mean square} of the reward's normaliser on a nominal road: the conventional passive car
    (:func:`passive_reference`) on an ISO 8608 class-C road at 20 m/s, 100 s (``method="fft"``, seed 0; the
    long-run values: 10 s episodes scatter around them by ±10–50 %, travel the most); the fixed reference scales
    for a car without a passive damper."""
    if p.passive_c > 0:
        nom = NOMINAL_ROAD
        rec = iso8608_road(nom["road_class"], nom["speed"], nom["duration"], dt, rng=nom["seed"], method="fft")
        z0, zd0 = rec.data[0]
        ref = passive_reference(p, rec, np.array([z0, z0, zd0, zd0]), rec.n_samples, dt)
    else:
        ref = _absolute_reference(p)
    return {REWARD_SIGNALS[k]: v for k, v in ref.items()}


def metrics(stats: EpisodeStats, episode: Episode, static_tyre_load: float) -> dict[str, float]:
    """ISO 2631 comfort, travel and tyre load of an episode (as :func:`~mrd_env.plants.quarter_car.metrics.quarter_car_metrics`),
    and the share of its time the travel is beyond the soft stroke limit."""
    r, pk = stats.rms, stats.peak
    out = {"acc_weighted_rms": float(r["sprung_acc_wk"][0]), "acc_rms": float(r["sprung_acc"][0]),
           "acc_vdv": float((stats.dose4 * stats.dt) ** 0.25), "acc_mtvv": stats.max_running_rms,
           "travel_rms": float(r["travel"][0]), "travel_peak": float(pk["travel"][0]),
           "tyre_load_rms": float(r["_tyre_load"][0]), "tyre_load_ratio": float(r["_tyre_load"][0]) / static_tyre_load,
           "damper_force_rms": float(r["damper_force"][0]), "damper_force_peak": float(pk["damper_force"][0]),
           "duration": (stats.n_rows - 1) * stats.dt, "stroke_exceedance_share": exceedance_share(stats)}
    return out


def _new_episode(p: QuarterCarParams, episode_seconds: float | None, dt: float, ahead: tuple[float, ...],
                 rec: Record) -> Episode:
    """An episode on road ``rec``: the car at rest in static equilibrium on the road's initial height, moving
    with it (no step hits the tyre), the passive car's reference scales, the road ahead for the preview."""
    zr0, zrd0 = rec.data[0]
    q0 = np.array([zr0, zr0, zrd0, zrd0])
    rows = rec.n_samples if episode_seconds is None else min(rec.n_samples, int(round(episode_seconds / dt)) + 1)
    ref = passive_reference(p, rec, q0, rows, dt) if p.passive_c > 0 else _absolute_reference(p)
    if ahead:
        rec = with_preview(rec, "z_r", [int(round(t / dt)) for t in ahead], preview_channels(ahead), "m")
    return Episode(rec, q0, {"reference": {k: max(v, 1e-12) for k, v in ref.items()}})


def _per_reference(ep: Episode) -> np.ndarray:
    """The reward's weights per unit of the passive car's mean squares on the episode's road."""
    return np.array([1.0 / ep.extras["reference"][k] for k in REWARD_SIGNALS])


def assembly(*, plant_preset: str = "set_a", plant_params=None, road="iso8608", road_params=None,
             damper="spencer_dyke", damper_preset: str | None = None, damper_params=None, dt: float = 1e-3,
             control_dt: float = 1e-3, episode_seconds: float | None = None, sensors=None, sensor_noise=None,
             sensor_delay: int = 0, history: int = 1, action_mode: str = "physical", inverse=None,
             force_range: float | None = None, reward=None, reward_weights=None,
             stroke_limit: float | None = None, soft_stroke_limit: float | None = None, preview=None) -> Assembly:
    """The quarter-car environment's parts from its options (see :class:`QuarterCarEnv`)."""
    given = {k: v for k, v in locals().items()}
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    p = _plant_params(plant_preset, plant_params)
    d = opt.make_env_damper(damper, damper_preset, damper_params, "automotive")
    ahead = opt.preview_times(preview, dt)
    sensor_part = opt.sensors(sensors, sensor_noise, sensor_delay, history, DEFAULT_SENSORS)
    if "road_preview" in sensor_part.names and not ahead:
        raise ValueError("the sensor 'road_preview' needs the preview option: the times ahead in s, e.g. "
                         "preview=(0.05, 0.1, 0.2)")
    lp = with_preview_inputs(p.plant(), ahead)
    coupled = CoupledPlant(lp, d)
    sm = signals(coupled, p, d.command.unit)
    w = opt.weights(reward_weights, DEFAULT_REWARD_WEIGHTS)
    static = p.static_tyre_load
    reward = opt.reward(reward, lambda: QuadraticReward({REWARD_SIGNALS[k]: w[k] for k in REWARD_SIGNALS},
                                                        episode_scale=_per_reference))
    limit = opt.check_scalar("stroke_limit", 0.1 if stroke_limit is None else stroke_limit, 0.0, lo_open=True,
                             unit="m")
    soft = soft_limit("soft_stroke_limit", soft_stroke_limit, limit, SOFT_STROKE_FRACTION)
    # per record sample of one environment's episode: its input buffer and the passive car's reference response
    # (computed at reset: the state, the acceleration and its weighting, travel and tyre load)
    source = road_source(road, road_params, dt, episode_seconds,
                         budget=Budget(FLOAT * (coupled.system.nw + EPISODE_FLOATS)))
    if episode_seconds is None and isinstance(source, Generated):
        episode_seconds = 10.0

    from .render import QuarterCarRenderer

    return Assembly(
        kind=SPEC.name, damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=tuple(SENSOR_UNITS),
        sensors=sensor_part, disturbance=source, reward=reward,
        limits=Limits({"travel": limit}, penalty=0.0, penalty_rate=w["termination"]),
        new_episode=functools.partial(_new_episode, p, episode_seconds, dt, ahead),
        metrics=functools.partial(metrics, static_tyre_load=static),
        roles={"body_velocity": "sprung_vel", "wheel_velocity": "unsprung_vel", "damper_velocity": "travel_rate",
               "damper_stroke": "travel", "damper_force": "damper_force"},
        objective={"sprung_acc": 1.0 / A_REF ** 2, "travel": 1.0 / X_REF ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        filters=[("sprung_acc", "sprung_acc_wk", weighting_sos("Wk", dt))],
        stat_signals=("sprung_acc_wk", "sprung_acc", "travel", "_tyre_load", "damper_force"),
        dose_signal="sprung_acc_wk", dose_window=1.0, renderer=QuarterCarRenderer, options=given,
        preview_times=ahead, reset_floats=EPISODE_FLOATS, nominal_reference=functools.partial(nominal_reference, p, dt),
        costs=car_costs(soft, static))


class QuarterCarEnv(MRDamperEnv):
    """Quarter car with an MR damper across its suspension, driven by a road profile.

    ## Description

    Quarter car (sprung mass m_s, unsprung mass m_u, suspension spring k_s, tyre k_t/c_t) with an MR damper
    across the suspension, driven by a road profile; physics at ``dt`` = 1 ms, the command held over each control
    period (``control_dt``). The task: ride comfort against rattle space and road holding, by choosing only the
    damper's command (semi-active control). Equations: :mod:`mrd_env.plants.quarter_car`.

    ## Action Space

    One command, a ``Box`` of shape ``(1,)``, float32: in ``Physical-v0`` the damper's command in V or A,
    [v_min, v_max] of the preset ([0, 2] V for the default "automotive" Spencer–Dyke damper); in ``-v1``
    normalised to [−1, 1] (``action_mode="normalized"``); with ``action_mode="force"`` the desired damper force
    beyond the static preload (N). See :class:`~mrd_env.envs.base.MRDamperEnv` for clipping and the command lag.

    ## Observation Space

    A ``Box(-inf, inf)``, float32, of the chosen sensors in order (``env.unwrapped.sensor_layout``). The default
    sensors (what a test car measures; every controller and agent gets the same), shape ``(8,)``:

    | Index | Sensor | Quantity | Unit |
    |---|---|---|---|
    | 0 | ``sprung_acc`` | body acceleration z̈_s (gravity removed) | m/s² |
    | 1 | ``unsprung_acc`` | wheel acceleration z̈_u | m/s² |
    | 2 | ``travel`` | suspension travel z_s − z_u (extension positive) | m |
    | 3 | ``travel_rate`` | its rate ż_s − ż_u | m/s |
    | 4 | ``sprung_vel`` | body velocity ż_s (absolute) | m/s |
    | 5 | ``unsprung_vel`` | wheel velocity ż_u (absolute) | m/s |
    | 6 | ``damper_force`` | damper force (load cell, includes the static preload) | N |
    | 7 | ``command`` | the command applied over the last step | V or A |

    All sensors (SI): ``sprung_acc`` z̈_s (m/s², gravity removed), ``unsprung_acc`` z̈_u, ``travel`` z_s − z_u (m),
    ``travel_rate`` (m/s), ``sprung_vel`` ż_s and ``unsprung_vel`` ż_u (m/s, absolute — on a car these come
    from integrated accelerometers), ``damper_force`` (N, load cell, includes the static preload), ``command``
    (applied, V or A), ``road`` z_r (m), ``damper_states`` (the model's internal states, hidden unless asked),
    ``road_preview`` (m, one channel per preview time: z_r(t + τ), the road height τ seconds ahead of the wheel
    as a camera or lidar preview suspension measures it; beyond the end of the record the last height is held;
    noise, delay and history apply as to any sensor). Preview is never in the default: a controller that uses it
    must be compared as one that had it
    (``sensors=(*DEFAULT_SENSORS, "road_preview")`` with ``preview=...``). With preview, the plant has one
    more input per preview time, which it ignores (``linear_plant.input_names`` ends with ``z_r(t+τs)``; zero
    columns of E) and ``env.record`` carries those channels; the dynamics are those without preview, bit for
    bit.

    ## Rewards

    The cost integrated over the control period (so returns do not depend on the control rate)::

        r = −∫ c dt,   c = w_comfort a_w² / ⟨a_w²⟩_p + w_travel x² / ⟨x²⟩_p + w_tyre F_t² / ⟨F_t²⟩_p

    a_w the ISO 2631-1 Wk-weighted sprung acceleration filtered online (causal IIR at 1/dt), x the travel,
    F_t = k_t (z_r − z_u) + c_t (ż_r − ż_u) the dynamic tyre load; ⟨·⟩_p the mean square of the same signal for
    the conventional passive car (the set's ``passive_c`` damper, simulated exactly at reset) on the same road.
    The return is thus the comfort / rattle-space / road-holding index of the field, relative to the passive
    car, per second: the passive car scores −1 per second on any road, and rough and smooth roads weigh alike.
    An episode ended by the stroke limit loses ``reward_weights["termination"]`` = 10 × its planned length in
    seconds: more than any controller that finishes pays (a test checks it on every benchmark scenario).

    ## Starting State

    The car starts at rest in static equilibrium on the road's initial height (both masses at z_r(0), moving with
    ż_r(0)). A generated road is new each episode, drawn from ``np_random`` (``reset(seed=...)``).

    ## Episode End

    ``terminated`` when |travel| exceeds ``stroke_limit`` (0.1 m; ``info["termination_reason"] =
    "stroke_limit"``) or the simulation diverges; ``truncated`` after ``episode_seconds`` (10 s for generated
    roads: ``env.spec.max_episode_steps`` steps, 10 000 in ``Physical-v0``, 1 000 in ``-v1``).

    Constraint costs (the CMDP signal of safe RL; no part of the reward): every step's ``info["cost"]`` is the time
    (s) during the control period at which the car violates a constraint — |travel| beyond ``soft_stroke_limit``
    (default 0.8 × ``stroke_limit`` = 0.08 m: the last 20 % of the travel, where bump and rebound stops engage;
    illustrative) or tyre lift-off (the dynamic tyre load below −the static load: the tyre would pull, the wheel
    leaves the road) — counted on the 1 ms physics rows, so 0 ≤ cost ≤ ``control_dt``;
    ``info["cost_terms"]`` = {"stroke": s, "tyre_lift_off": s} (:mod:`mrd_env.envs.costs`).

    ``info["episode_metrics"]`` at the end of an episode: acc_weighted_rms, acc_rms (m/s²), acc_vdv (m/s^1.75),
    acc_mtvv (m/s²; ISO 2631-1 Wk, MTVV over 1 s), travel_rms, travel_peak (m), tyre_load_rms (N),
    tyre_load_ratio (its r.m.s. over the static load), damper_force_rms, damper_force_peak (N), duration (s),
    stroke_exceedance_share (the share of the time |travel| is beyond the soft stroke limit), cost,
    cost_stroke, cost_tyre_lift_off (s: the step costs summed) — accumulated by the compiled step, no history
    needed.

    ## Arguments

    Keyword-only (``gym.make("mrd_env/QuarterCar-v1", **options)``; every bad value raises ``ValueError`` naming
    the option):

    * ``plant_preset``: "set_a" (default), "set_b", "set_c" (reference parameter sets); ``plant_params``: a dict
      of :class:`~mrd_env.plants.QuarterCarParams` overrides, or a ``QuarterCarParams``.
    * ``damper`` (model name, default "spencer_dyke", or a ``DamperModel``), ``damper_preset`` (default
      "automotive", or the model's default preset if it has no "automotive" one), ``damper_params`` (overrides).
    * ``road`` (one rule: a kind name, a dict ``{"kind": ..., **options}``, a
      :class:`~mrd_env.disturbances.Record` with channels z_r, zdot_r, or a
      :class:`~mrd_env.envs.disturbance.Disturbance`): "iso8608" (default; a new random road each episode from
      ``np_random``: road_class "C", speed 20 m/s, method "fft", n_min, n_max, n_waves, waviness as
      :func:`~mrd_env.disturbances.iso8608_road`), "bump" (height 0.05 m, length 1 m, speed 10 m/s, t_start
      0.5 s, duration: bump end + 2 s), "sine_sweep" (amplitude 0.01 m, f_start 0.5 Hz, f_end 20 Hz, kind "log",
      duration: episode_seconds or 10 s), "csv" (path, height_column, distance_column + speed or time_column,
      units: :func:`~mrd_env.disturbances.road_from_csv`); ``road_params``: the options of a named kind.
    * ``episode_seconds``: default 10 s for generated roads, the record's length for the others.
    * ``dt`` 1e-3 s, ``control_dt`` 1e-3 s (an integer multiple of dt; the command is held over it).
    * ``sensors`` (names, or a :class:`~mrd_env.envs.sensors.Sensors`), ``sensor_noise`` ({name: std} SI),
      ``sensor_delay`` (control steps), ``history`` (control steps stacked in the observation, oldest first).
    * ``action_mode``: "physical" ([v_min, v_max] in V or A), "normalized" ([−1, 1]) or "force": the desired
      damper force beyond the static preload, in N, Box [−``force_range``, ``force_range``] (default 3000 N),
      turned into the command inside the step by the ``inverse`` (default "model"; a name of
      :func:`mrd_env.inverse.make_inverse`, a dict ``{"kind": name, **options}`` or an Inverse built for the
      damper at ``control_dt``) from the measured damper force, stroke and velocity (the sensors of ``roles``;
      :class:`~mrd_env.envs.actuation.ForceActuation`).
    * ``reward_weights`` (comfort 0.5, travel 0.25, tyre 0.25; termination 10 per second) or
      ``reward``: a :class:`~mrd_env.envs.reward.QuadraticReward`, or any callable of the period's signals
      (``{name: (n_sub, width)}`` → float; one Python call per step).
    * ``stroke_limit`` (default 0.1 m on |z_s − z_u|: the episode ends), ``soft_stroke_limit`` (m, in (0,
      ``stroke_limit``]; default 0.8 × ``stroke_limit``: a cost), ``render_mode`` ("rgb_array", "human").
    * ``preview``: None (default: no preview), or the times ahead τ (s; one or an increasing sequence, each a
      multiple of ``dt`` in [dt, 10 s]) at which the ``road_preview`` sensor reads the road;
      ``env.unwrapped.preview_times`` gives them (a tuple in s, empty without preview).

    ## Version History

    * v1: the defaults an RL user expects — ``control_dt`` = 0.01 s (100 Hz, 1 000 steps per 10 s episode;
      physics still at 1 ms) and ``action_mode="normalized"`` (:data:`mrd_env.envs.RL_DEFAULTS`).
    * v0: the physics-level defaults — a command in V or A at every 1 ms step.
    """

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


class QuarterCarVectorEnv(MRDamperVectorEnv):
    """``num_envs`` quarter cars in one compiled call (``gymnasium.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=N,
    vectorization_mode="vector_entry_point", **options)``; options as :class:`QuarterCarEnv`)."""

    env_id = SPEC.physics_id
    build = staticmethod(assembly)
