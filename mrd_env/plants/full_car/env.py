"""Full car with an MR damper at each corner (``mrd_env/FullCarPhysical-v0``): its environment."""
from __future__ import annotations

import functools

import numpy as np
import scipy.linalg

from ...dampers import DamperModel
from ...disturbances import Record
from ...envs import options as opt
from ...envs.base import MRDamperEnv
from ...envs.core import Assembly, Episode, EpisodeStats
from ...envs.costs import SOFT_STROKE_FRACTION, car_costs, exceedance_share, soft_limit
from ...envs.reward import QuadraticReward
from ...envs.signals import SignalMap
from ...envs.termination import Limits
from ...envs.vector import MRDamperVectorEnv
from ...mechanics import CoupledPlant, LinearPlant
from ...metrics import weighting_sos
from ...resources import FLOAT, Budget
from . import SPEC
from .metrics import K_PITCH, K_ROLL, vibration_total, we_sos
from .physics import CORNERS, ROAD_CHANNELS, FullCarParams, full_car
from .roads import Geometry, preview_channels, road_source, two_track_iso8608, wheelbase_preview_channels

#: Reference scales of the reward without a passive reference damper (SI).
A_REF = 1.0     # m/s², the comfort's vibration total value
X_REF = 0.05    # m, suspension travel at each corner

SENSOR_UNITS = {"body_acc": "m/s^2", "pitch_acc": "rad/s^2", "roll_acc": "rad/s^2", "body_vel": "m/s",
                "pitch_rate": "rad/s", "roll_rate": "rad/s", "travel": "m", "travel_rate": "m/s",
                "body_vel_at_corners": "m/s", "wheel_vel": "m/s", "wheel_acc": "m/s^2", "damper_force": "N",
                "command": "cmd", "road": "m", "road_preview": "m", "wheelbase_preview": "m",
                "damper_states": "model"}
#: What a test car measures, and what every controller and agent gets by default: the body's heave, pitch and roll
#: accelerations (an inertial unit at the centre of mass), the four suspension travels and their rates, the body's
#: vertical velocity above each corner and each wheel's (integrated accelerometers: what skyhook, groundhook and
#: the hybrid law read per corner), the dampers' load cells and the commands sent.
DEFAULT_SENSORS = ("body_acc", "pitch_acc", "roll_acc", "travel", "travel_rate", "body_vel_at_corners", "wheel_vel",
                   "damper_force", "command")
DEFAULT_REWARD_WEIGHTS = {"comfort": 0.5, "travel": 0.25, "tyre": 0.25, "termination": 10.0}
#: The comfort term's signals and their weights in it: ISO 2631-1's point vibration total value squared,
#: a_wz² + (k_y a_wθ)² + (k_x a_wφ)² (:func:`~.metrics.vibration_total`).
COMFORT = {"body_acc_wk": 1.0, "pitch_acc_we": K_PITCH ** 2, "roll_acc_we": K_ROLL ** 2}
#: The reward's terms and their signals.
REWARD_TERMS = {"comfort": tuple(COMFORT), "travel": ("travel",), "tyre": ("_tyre_load",)}
#: Floats per record sample an episode computes at reset (the passive car's response), for the memory estimate.
EPISODE_FLOATS = 40
#: The nominal road of weights="reward"'s fixed reference scales (:func:`nominal_reference`).
NOMINAL_ROAD = {"road_class": "C", "speed": 20.0, "duration": 100.0, "seed": 0}


# --- the plant and its signals -----------------------------------------------------------------------------------
def _plant_params(plant_preset, plant_params) -> FullCarParams:
    return opt.plant_parameters(FullCarParams, full_car, plant_preset, plant_params)


def with_inputs(lp: LinearPlant, names: tuple[str, ...]) -> LinearPlant:
    """``lp`` with the record's further channels (the previews) as inputs the plant ignores (zero columns of E)."""
    import dataclasses

    extra = names[len(lp.input_names):]
    if not extra:
        return lp
    return dataclasses.replace(lp, E=np.hstack([lp.E, np.zeros((lp.n_dof, len(extra)))]), input_names=names)


def signals(coupled: CoupledPlant, p: FullCarParams, command_unit: str, geometry: Geometry) -> SignalMap:
    """The full car's named signals (see :class:`FullCarEnv`)."""
    sm = SignalMap(coupled)
    S = coupled.plant.S
    eye = np.eye(7)
    wheels = eye[3:]
    n_prev, n_wb = 4 * len(geometry.preview), 2 * len(geometry.wheelbase_preview)
    sm.add("body_acc", sm.acc(eye[0]), "m/s^2")
    sm.add("pitch_acc", sm.acc(eye[1]), "rad/s^2")
    sm.add("roll_acc", sm.acc(eye[2]), "rad/s^2")
    sm.add("body_vel", sm.vel(eye[0]), "m/s")
    sm.add("pitch_rate", sm.vel(eye[1]), "rad/s")
    sm.add("roll_rate", sm.vel(eye[2]), "rad/s")
    sm.add("travel", sm.disp(S), "m")
    sm.add("travel_rate", sm.vel(S), "m/s")
    sm.add("body_vel_at_corners", sm.vel(p.body_at_corners()), "m/s")
    sm.add("wheel_vel", sm.vel(wheels), "m/s")
    sm.add("wheel_acc", sm.acc(wheels), "m/s^2")
    sm.add("damper_force", sm.force(), "N")
    heights = np.zeros((4, 8 + n_prev + n_wb))
    heights[np.arange(4), 2 * np.arange(4)] = 1.0
    sm.add("road", sm.inp(heights), "m")
    if n_prev:
        sm.add("road_preview", sm.inp(np.hstack([np.zeros((n_prev, 8)), np.eye(n_prev), np.zeros((n_prev, n_wb))])),
               "m")
    if n_wb:
        sm.add("wheelbase_preview", sm.inp(np.hstack([np.zeros((n_wb, 8 + n_prev)), np.eye(n_wb)])), "m")
    sm.add("damper_states", sm.damper_states(), "model")
    sm.add("_q", sm.disp(eye), "m, rad")  # for the renderer
    # the dynamic tyre loads k_t (z_r − z_u) + c_t (ż_r − ż_u), positive = more load than static
    kt = np.array([p.k_tf, p.k_tf, p.k_tr, p.k_tr])
    ct = np.array([p.c_tf, p.c_tf, p.c_tr, p.c_tr])
    road = np.zeros((4, 8))
    road[np.arange(4), 2 * np.arange(4)], road[np.arange(4), 2 * np.arange(4) + 1] = kt, ct
    sm.add("_tyre_load", -sm.disp(kt[:, None] * wheels) - sm.vel(ct[:, None] * wheels) + sm.inp(road), "N")
    sm.add_commands(command_unit)
    sm.add_output("body_acc_wk", "m/s^2")
    sm.add_output("pitch_acc_we", "rad/s^2")
    sm.add_output("roll_acc_we", "rad/s^2")
    return sm


# --- the passive car's reference ---------------------------------------------------------------------------------
def passive_reference(p: FullCarParams, rec: Record, q0: np.ndarray, rows: int, dt: float) -> dict:
    """Mean squares of the reward's terms for the conventional passive car — the set's passive dampers
    (``passive_cf``, ``passive_cr``) in place of the MR dampers, a linear plant simulated exactly — on the record's
    first ``rows`` samples: the comfort (the vibration total value squared: Wk heave, We pitch and roll), the
    travels (their sum of squares over the corners) and the tyre loads (the sum over the corners of the squared
    dynamic load over the static one). The reward's units."""
    import scipy.signal

    from ...mechanics import foh_response

    lp = p.plant()
    A, _, Bw = lp.state_space(extra_damping=p.passive_damping)
    w = np.asarray(rec.data[:rows, :8])
    X = foh_response(A, Bw, w, dt, x0=q0)
    acc = X @ A[7:10].T + w @ Bw[7:10].T                       # heave, pitch, roll accelerations
    a_w = scipy.signal.sosfilt(weighting_sos("Wk", dt), acc[:, 0])
    rot = scipy.signal.sosfilt(we_sos(dt), acc[:, 1:], axis=0)
    travel = X[:, :7] @ lp.S.T
    kt = lp.E[3:, 0::2].diagonal()
    ct = lp.E[3:, 1::2].diagonal()
    tyre = (kt * (w[:, 0::2] - X[:, 3:7]) + ct * (w[:, 1::2] - X[:, 10:14])) / p.static_tyre_loads
    tail = slice(1, None) if rows > 1 else slice(None)
    comfort = a_w ** 2 + COMFORT["pitch_acc_we"] * rot[:, 0] ** 2 + COMFORT["roll_acc_we"] * rot[:, 1] ** 2
    return {"comfort": float(np.mean(comfort[tail])), "travel": float(np.mean(np.sum(travel[tail] ** 2, axis=1))),
            "tyre": float(np.mean(np.sum(tyre[tail] ** 2, axis=1)))}


def _absolute_reference() -> dict:
    """Fixed reference scales, for a car without passive reference dampers: 1 m/s², 5 cm at each corner, each
    tyre's static load."""
    return {"comfort": A_REF ** 2, "travel": 4 * X_REF ** 2, "tyre": 4.0}


def static_state(p: FullCarParams, road_now: np.ndarray, damper: DamperModel | None = None) -> np.ndarray:
    """[q, q̇] at rest on the roads' heights ``road_now`` (the 8 road channels at one instant), as the other cars
    start: in static equilibrium, K q + Sᵀ (F_r(S q) − F_r(0)) = E_z z_r with the ``damper``'s static force at rest
    F_r (a Spencer–Dyke accumulator's k1·x_d; on a warped road — four heights no plane holds — the springs, bars
    and dampers share the twist), and with zero stroke rates (S q̇ = 0): the body and wheels move as one rigid
    body, the wheels' velocities the least-squares fit of the roads' ż_r (exact on a plane), so no damper is
    driven at t = 0 and nothing but the tyres' damping of the rest of ż_r accelerates."""
    lp = p.plant()
    Ez = lp.E[:, 0::2]
    q = lp.static_deflection(Ez @ road_now[0::2], damper)
    rigid = scipy.linalg.null_space(lp.S)                   # q̇ with S q̇ = 0: heave, pitch, roll of the whole car
    wheels = rigid[3:7]
    a = np.linalg.lstsq(wheels, np.asarray(road_now[1::2], dtype=float), rcond=None)[0]
    return np.concatenate([q, rigid @ a])


def nominal_reference(p: FullCarParams, geometry_track: float, dt: float) -> dict:
    """{reward signal: mean square} of the reward's normaliser on a nominal road: the conventional passive car
    (:func:`passive_reference`) on a two-track ISO 8608 class-C road at 20 m/s, 100 s (seed 0); the fixed scales
    for a car without passive reference dampers. Each comfort signal gets the comfort term's mean square (the term
    is their weighted sum)."""
    if np.any(p.passive_damping > 0):
        nom = NOMINAL_ROAD
        rec = two_track_iso8608(nom["road_class"], nom["speed"], nom["duration"], dt,
                                np.random.default_rng(nom["seed"]), Geometry(p.wheelbase, geometry_track))
        ref = passive_reference(p, rec, static_state(p, rec.data[0]), rec.n_samples, dt)
    else:
        ref = _absolute_reference()
    return {s: ref[term] for term, sigs in REWARD_TERMS.items() for s in sigs}


# --- episodes ----------------------------------------------------------------------------------------------------
def _with_previews(rec: Record, geometry: Geometry, dt: float) -> Record:
    """A record of the roads alone with the road preview's channels appended (each corner's height shifted τ ahead,
    the last sample held beyond the end, as the quarter car's)."""
    if tuple(rec.channels) == geometry.channels:
        return rec
    x = rec.data[:, 0:8:2]
    idx = np.arange(rec.n_samples)
    ahead = [x[np.minimum(idx + int(round(t / dt)), rec.n_samples - 1), j]
             for j in range(4) for t in geometry.preview]
    return Record(rec.dt, np.column_stack([rec.data[:, :8], *ahead]), geometry.channels, geometry.units, rec.name)


def _new_episode(p: FullCarParams, geometry: Geometry, episode_seconds: float | None, dt: float,
                 damper: DamperModel, rec: Record) -> Episode:
    """An episode on road ``rec``: the car at rest on the roads' initial heights with ``damper`` at each corner
    (:func:`static_state`), the passive car's reference scales (that car at rest on the same heights), the
    previews."""
    x0 = static_state(p, np.asarray(rec.data[0, :8]), damper)
    rows = rec.n_samples if episode_seconds is None else min(rec.n_samples, int(round(episode_seconds / dt)) + 1)
    ref = (passive_reference(p, rec, static_state(p, np.asarray(rec.data[0, :8])), rows, dt)
           if np.any(p.passive_damping > 0) else _absolute_reference())
    return Episode(_with_previews(rec, geometry, dt), x0, {"reference": {k: max(v, 1e-12) for k, v in ref.items()}})


def _per_reference(ep: Episode) -> np.ndarray:
    """The reward's weights per unit of the passive car's mean squares on the episode's road, per column."""
    ref = ep.extras["reference"]
    return np.array([1.0 / ref["comfort"]] * 3 + [1.0 / ref["travel"]] * 4 + [1.0 / ref["tyre"]] * 4)


def metrics(stats: EpisodeStats, episode: Episode, static: np.ndarray) -> dict[str, float]:
    """ISO 2631-1 comfort (heave, pitch, roll and their vibration total value), travel and tyre load per corner of an
    episode (as :func:`~mrd_env.plants.full_car.metrics.full_car_metrics`), the dampers' forces and the share of
    its time a travel is beyond the soft stroke limit."""
    r, pk = stats.rms, stats.peak
    ratio = r["_tyre_load"] / static
    out = {"acc_weighted_rms": float(r["body_acc_wk"][0]), "pitch_acc_weighted_rms": float(r["pitch_acc_we"][0]),
           "roll_acc_weighted_rms": float(r["roll_acc_we"][0]),
           "comfort_rms": float(vibration_total(r["body_acc_wk"][0], r["pitch_acc_we"][0], r["roll_acc_we"][0])),
           "acc_rms": float(r["body_acc"][0]), "pitch_acc_rms": float(r["pitch_acc"][0]),
           "roll_acc_rms": float(r["roll_acc"][0]), "acc_vdv": float((stats.dose4 * stats.dt) ** 0.25),
           "acc_mtvv": stats.max_running_rms, "travel_rms": float(r["travel"].max()),
           "travel_peak": float(pk["travel"].max()), "tyre_load_rms": float(r["_tyre_load"].max()),
           **{f"tyre_load_rms_{c}": float(v) for c, v in zip(CORNERS, r["_tyre_load"])},
           "tyre_load_ratio": float(ratio.max()), **{f"tyre_load_ratio_{c}": float(v) for c, v in zip(CORNERS, ratio)},
           "damper_force_rms": float(r["damper_force"].max()), "damper_force_peak": float(pk["damper_force"].max()),
           "duration": (stats.n_rows - 1) * stats.dt, "stroke_exceedance_share": exceedance_share(stats)}
    return out


# --- the assembly ------------------------------------------------------------------------------------------------
def _times(name: str, value, dt: float) -> tuple[float, ...]:
    try:
        return opt.preview_times(value, dt)
    except ValueError as e:
        if name == "preview":
            raise
        raise ValueError(f"{name}: {e}") from None


def assembly(*, plant_preset: str = "sedan", plant_params=None, road="iso8608", road_params=None,
             damper="spencer_dyke", damper_preset: str | None = None, damper_params=None, dt: float = 1e-3,
             control_dt: float = 1e-3, episode_seconds: float | None = 10.0, sensors=None, sensor_noise=None,
             sensor_delay: int = 0, history: int = 1, action_mode: str = "physical", inverse=None,
             force_range: float | None = None, reward=None, reward_weights=None, stroke_limit: float = 0.1,
             soft_stroke_limit: float | None = None, preview=None, wheelbase_preview=None) -> Assembly:
    """The full-car environment's parts from its options (see :class:`FullCarEnv`)."""
    given = {k: v for k, v in locals().items()}
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    p = _plant_params(plant_preset, plant_params)
    d = opt.make_env_damper(damper, damper_preset, damper_params, "automotive")
    geometry = Geometry(p.wheelbase, p.t_f, _times("preview", preview, dt),
                        _times("wheelbase_preview", wheelbase_preview, dt))
    sensor_part = opt.sensors(sensors, sensor_noise, sensor_delay, history, DEFAULT_SENSORS)
    for sensor, option, example in (("road_preview", geometry.preview, "preview=(0.05, 0.1, 0.2)"),
                                    ("wheelbase_preview", geometry.wheelbase_preview,
                                     "wheelbase_preview=(0.02, 0.05)")):
        if sensor in sensor_part.names and not option:
            raise ValueError(f"the sensor {sensor!r} needs the {sensor.replace('road_', '')} option: the times "
                             f"ahead in s, e.g. {example}")
    lp = with_inputs(p.plant(), geometry.channels)
    coupled = CoupledPlant(lp, d)
    sm = signals(coupled, p, d.command.unit, geometry)
    w = opt.weights(reward_weights, DEFAULT_REWARD_WEIGHTS)
    static = p.static_tyre_loads
    reward = opt.reward(reward, lambda: QuadraticReward(
        {**{s: w["comfort"] * c for s, c in COMFORT.items()}, "travel": np.full(4, w["travel"]),
         "_tyre_load": w["tyre"] / static ** 2}, episode_scale=_per_reference))
    limit = opt.check_scalar("stroke_limit", stroke_limit, 0.0, lo_open=True, unit="m")
    soft = soft_limit("soft_stroke_limit", soft_stroke_limit, limit, SOFT_STROKE_FRACTION)
    source = road_source(road, road_params, dt, episode_seconds, geometry,
                         budget=Budget(FLOAT * (coupled.system.nw + EPISODE_FLOATS)))
    if geometry.wheelbase_preview and tuple(source.channels) != geometry.channels:
        raise ValueError("wheelbase_preview needs a road kind that knows its speed ('iso8608', 'bump', "
                         f"'pothole'), not {source.describe()!r}: the front wheels' past is the rear wheels' road "
                         "ahead only wheelbase/speed later")
    if tuple(source.channels) not in (geometry.channels, ROAD_CHANNELS):
        raise ValueError(f"road: a Disturbance must give the channels {ROAD_CHANNELS}, got {source.channels}")

    from .render import FullCarRenderer

    return Assembly(
        kind=SPEC.name, damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=tuple(SENSOR_UNITS), sensors=sensor_part, disturbance=source, reward=reward,
        limits=Limits({"travel": limit}, penalty=0.0, penalty_rate=w["termination"]),
        new_episode=functools.partial(_new_episode, p, geometry, episode_seconds, dt, d),
        metrics=functools.partial(metrics, static=static),
        roles={"body_velocity": "body_vel_at_corners", "wheel_velocity": "wheel_vel",
               "damper_velocity": "travel_rate", "damper_stroke": "travel", "damper_force": "damper_force"},
        objective={"body_acc": 1.0 / A_REF ** 2, "pitch_acc": K_PITCH ** 2 / A_REF ** 2,
                   "roll_acc": K_ROLL ** 2 / A_REF ** 2, "travel": 1.0 / X_REF ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        filters=[("body_acc", "body_acc_wk", weighting_sos("Wk", dt)), ("pitch_acc", "pitch_acc_we", we_sos(dt)),
                 ("roll_acc", "roll_acc_we", we_sos(dt))],
        stat_signals=("body_acc_wk", "pitch_acc_we", "roll_acc_we", "body_acc", "pitch_acc", "roll_acc", "travel",
                      "_tyre_load", "damper_force"),
        dose_signal="body_acc_wk", dose_window=1.0, renderer=FullCarRenderer, options=given,
        preview_times=geometry.preview, reset_floats=EPISODE_FLOATS,
        nominal_reference=functools.partial(nominal_reference, p, geometry.track, dt),
        costs=car_costs(soft, static))


class FullCarEnv(MRDamperEnv):
    """Full car (body heave, pitch and roll, four wheels) with an MR damper at each corner, on two-track roads.

    ## Description

    The 7-degree-of-freedom car of ride studies: a rigid body (mass m_s, roll and pitch inertias I_x, I_y) on four
    suspensions (spring, MR damper, optional anti-roll bars front and rear), four unsprung masses on their tyres,
    each wheel on its road; the right track correlated with the left as an isotropic road surface is, the rear
    wheels on the front wheels' tracks wheelbase/speed later. Physics at ``dt`` = 1 ms, the four commands held over
    each control period. The task: ride comfort (heave, pitch and roll, ISO 2631-1) against rattle space and road
    holding at four corners, by choosing only the dampers' commands. Equations and parameters:
    :mod:`mrd_env.plants.full_car.physics`; roads: :mod:`mrd_env.plants.full_car.roads`.

    ## Action Space

    Four commands (front left, front right, rear left, rear right), a ``Box`` of shape ``(4,)``, float32: in
    ``Physical-v0`` in V or A, [v_min, v_max] of the preset ([0, 2] V for the default "automotive" Spencer–Dyke
    damper, the same model at every corner); in ``-v1`` normalised to [−1, 1]; with ``action_mode="force"`` the
    desired damper forces beyond the static preload (N). See :class:`~mrd_env.envs.base.MRDamperEnv`.

    ## Observation Space

    A ``Box(-inf, inf)``, float32, of the chosen sensors in order (``env.unwrapped.sensor_layout``). Per-corner
    sensors have four channels in the order fl, fr, rl, rr. The default sensors (what every controller and agent
    gets), shape ``(27,)``:

    | Index | Sensor | Quantity | Unit |
    |---|---|---|---|
    | 0 | ``body_acc`` | body heave acceleration at the centre of mass | m/s² |
    | 1 | ``pitch_acc`` | body pitch acceleration (nose down positive) | rad/s² |
    | 2 | ``roll_acc`` | body roll acceleration (left side up positive) | rad/s² |
    | 3–6 | ``travel`` | suspension travels (extension positive) | m |
    | 7–10 | ``travel_rate`` | their rates | m/s |
    | 11–14 | ``body_vel_at_corners`` | the body's vertical velocity above each corner | m/s |
    | 15–18 | ``wheel_vel`` | the wheels' vertical velocities | m/s |
    | 19–22 | ``damper_force`` | damper forces (load cells, the static preload included) | N |
    | 23–26 | ``command`` | the commands applied over the last step | V or A |

    Also available: ``body_vel`` (m/s), ``pitch_rate``, ``roll_rate`` (rad/s), ``wheel_acc`` (4, m/s²), ``road``
    (4: each wheel's road height, m), ``road_preview`` (each wheel's road at the ``preview`` times ahead: 4 × the
    number of times, wheel by wheel), ``wheelbase_preview`` (the rear wheels' road at the ``wheelbase_preview``
    times ahead, each at most wheelbase/speed: the road the front wheels met that long ago — what a car can know
    without a look-ahead sensor; 2 × the number of times, rl then rr) and ``damper_states``.

    ## Rewards

    The cost integrated over the control period, the quarter car's three terms normalised by the conventional
    passive car on the same road (the set's passive dampers, 1290 N·s/m front and 1620 N·s/m rear, on the episode's
    road: the passive car scores −(sum of the weights) per second)::

        r = −∫ (w_comfort a_v² / ⟨a_v²⟩_p + w_travel Σ_i x_i² / ⟨Σ_i x_i²⟩_p + w_tyre Σ_i (F_t,i/F_s,i)² /
               ⟨Σ_i (F_t,i/F_s,i)²⟩_p) dt

    a_v² = a_wz² + (0.40 m/rad · a_wθ)² + (0.63 m/rad · a_wφ)² the ISO 2631-1 point vibration total value (Wk
    heave, We pitch and roll, filtered online), x_i the travels, F_t,i the dynamic tyre loads over the static
    ones F_s,i; ``reward_weights`` comfort 0.5, travel 0.25, tyre 0.25. An episode ended by the stroke limit loses
    ``reward_weights["termination"]`` = 10 × its planned length in seconds. ``weights="reward"`` of the
    model-based laws designs on this cost with the passive car's mean squares on a nominal two-track class-C road
    at 20 m/s.

    ## Starting State

    At rest on the roads' initial heights (:func:`static_state`), as the other cars start: in static equilibrium,
    K q + Sᵀ (F_r(S q) − F_r(0)) = E z_r(0) with the dampers' internal states at rest at their strokes and their
    static forces F_r (a Spencer–Dyke accumulator's k1·x_d) — on four heights no plane holds, springs, bars and
    dampers share the twist —, and with zero stroke rates: the car moves as one rigid body, its wheels' velocities
    the least-squares fit of the roads' ż_r(0). No spring, tyre or damper is stepped and nothing accelerates at
    t = 0 but through the tyres' damping of the part of ż_r(0) no plane follows.
    A generated road is new each episode, drawn from ``np_random`` (``reset(seed=...)``).

    ## Episode End

    ``terminated`` when a |travel| exceeds ``stroke_limit`` (0.1 m; ``info["termination_reason"] =
    "stroke_limit"``) or the simulation diverges; ``truncated`` after ``episode_seconds`` (10 s: 10 000 steps in
    ``Physical-v0``, 1 000 in ``-v1``). ``info["cost"]``: the time in the control period a travel is beyond the soft
    stroke limit or a tyre lifts off (:mod:`mrd_env.envs.costs`).

    ``info["episode_metrics"]``: acc_weighted_rms (Wk heave, m/s²), pitch_acc_weighted_rms and
    roll_acc_weighted_rms (We, rad/s²), comfort_rms (the vibration total value, m/s²), acc_rms, pitch_acc_rms,
    roll_acc_rms, acc_vdv (Wk heave, m/s^1.75), acc_mtvv, travel_rms and travel_peak (the largest corner's, m),
    tyre_load_rms (N, the largest corner's; and tyre_load_rms_fl/fr/rl/rr) and tyre_load_ratio (the largest
    corner's r.m.s. dynamic load over its static load; and tyre_load_ratio_fl/fr/rl/rr), damper_force_rms, damper_force_peak (N), duration (s), stroke_exceedance_share,
    and the costs' totals.

    ## Arguments

    As :class:`~mrd_env.plants.quarter_car.env.QuarterCarEnv` where they apply, except:

    * ``plant_preset`` "sedan" (:data:`mrd_env.plants.full_car.FULL_CAR_PRESETS`); ``plant_params`` a dict of
      :class:`~mrd_env.plants.full_car.FullCarParams` overrides (e.g. anti-roll bars ``k_arf``, ``k_arr`` in
      N·m/rad) or a ``FullCarParams``.
    * ``road``: "iso8608" (default; new each episode; ``road_params``: ``road_class`` "C" (or a list), ``speed``
      20 m/s (or a range), ``coherence`` "isotropic" (or a number in [0, 1]), ``n_min``, ``n_max``, ``duration``),
      "bump" (``height`` 0.05 m, ``length`` 1 m, ``speed`` 10 m/s, ``t_start`` 0.5 s, ``side`` "left", "right" or
      "both", ``duration``), "pothole" (``depth`` 0.05 m, ``length`` 0.5 m, the same others), a Record with the
      channels z_rfl, zdot_rfl, z_rfr, zdot_rfr, z_rrl, zdot_rrl, z_rrr, zdot_rrr (m, m/s), or a Disturbance.
    * ``episode_seconds`` default 10 s.
    * ``preview``: None, or the times ahead (s) of the ``road_preview`` sensor; ``wheelbase_preview``: None, or the
      times ahead (s, each at most wheelbase over the fastest speed of the road) of the ``wheelbase_preview``
      sensor (a road kind that knows its speed).
    * ``reward_weights``: comfort 0.5, travel 0.25, tyre 0.25, termination 10 per second; or ``reward``.

    ## Version History

    * v1: ``control_dt`` = 0.01 s (100 Hz) and ``action_mode="normalized"`` (:data:`mrd_env.envs.RL_DEFAULTS`).
    * v0: the physics-level defaults — commands in V or A at every 1 ms step.
    """

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


class FullCarVectorEnv(MRDamperVectorEnv):
    """``num_envs`` full cars in one compiled call (options as :class:`FullCarEnv`)."""

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


__all__ = ["FullCarEnv", "FullCarVectorEnv", "preview_channels", "wheelbase_preview_channels"]
