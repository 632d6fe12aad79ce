"""Half car with MR dampers at the front and the rear (``mrd_env/HalfCarPhysical-v0``): its environment."""
from __future__ import annotations

import functools

import numpy as np

from ...disturbances import Record, iso8608_road
from ...metrics import weighting_sos
from ...mechanics import CoupledPlant
from . import SPEC
from .physics import HalfCarParams, half_car
from ...resources import FLOAT, Budget
from ...envs import options as opt
from ...envs import randomize
from ...envs.base import MRDamperEnv
from ...envs.core import Assembly, Episode, EpisodeStats
from ...envs.costs import SOFT_STROKE_FRACTION, car_costs, exceedance_share, soft_limit
from ...envs.disturbance import Disturbance, Generated
from ...envs.reward import QuadraticReward
from ...envs.signals import SignalMap
from ...envs.termination import Limits
from ...envs.vector import MRDamperVectorEnv

CHANNELS = ("z_rf", "zdot_rf", "z_rr", "zdot_rr")
UNITS = ("m", "m/s", "m", "m/s")
SENSORS = ("body_acc", "pitch_acc", "travel", "travel_rate", "body_vel_at_axles", "wheel_vel", "damper_force",
           "command", "damper_states")
DEFAULT_SENSORS = ("body_acc", "pitch_acc", "travel", "damper_force", "command")
DEFAULT_REWARD_WEIGHTS = {"comfort": 1.0, "travel": 0.5, "tyre": 0.5, "termination": 10.0}
X_REF = 0.05  # m, suspension travel
#: Bytes per sample while the road under both axles is generated with the rear axle's lag (the ISO 8608 FFT road,
#: its two channels and the four columns of the record: measured 58 with tracemalloc,
#: ``experiments/measurements/memory/estimate.py``).
LAGGED_ROAD_SAMPLE_BYTES = 96


# --- the road: one rule, these kinds --------------------------------------------------------------------------
def _iso8608(*, dt, episode_seconds, wheelbase, budget=None, road_class="C", speed=20.0):
    """An ISO 8608 road under both axles, new each episode; ``road_class`` may be a list and ``speed`` a range
    (lo, hi) to draw per episode (:mod:`.randomize`)."""
    if episode_seconds is None:
        raise ValueError("road 'iso8608' needs episode_seconds (s), got None")
    # one road, the rear axle's lag longer (under a second at the slowest speeds a car drives)
    (budget or Budget()).check_record(episode_seconds / dt + 1, dt, len(CHANNELS), f"episode_seconds={episode_seconds:g}",
                                      what="the road", generated=True)
    classes = randomize.values("road_params['road_class']", road_class, lambda v: v)
    speeds = randomize.values("road_params['speed']", speed,
                              lambda v: opt.check_scalar("road_params['speed']", v, 0.0, lo_open=True, unit="m/s"))
    # the road is generated wheelbase/speed longer than the episode (the rear axle's lag): at a slow speed, far longer
    lag = wheelbase / min(speeds)
    (budget or Budget()).check_generation(
        episode_seconds / dt + 1, dt, len(CHANNELS),
        f"road_params['speed']={min(speeds):g} m/s (the rear axle's lag wheelbase/speed = {lag:.3g} s is generated "
        f"with the road) with episode_seconds={episode_seconds:g}",
        grid_samples=(episode_seconds + lag) / dt + 1, what="the road",
        grid="generating the road with the rear axle's lag", sample_bytes=LAGGED_ROAD_SAMPLE_BYTES)
    n_samples = max(_axles_record(c, v, episode_seconds, dt, wheelbase, np.random.default_rng(0)).n_samples
                    for c in classes for v in speeds)
    return Generated(functools.partial(_axles_record, road_class, speed, episode_seconds, dt, wheelbase), CHANNELS,
                     f"ISO 8608 class {randomize.describe(road_class)} at {randomize.describe(speed)} m/s, "
                     f"both axles", max_samples=n_samples)


def _axles_record(road_class, speed, duration: float, dt: float, wheelbase: float, rng) -> Record:
    """An ISO 8608 road under both axles: the rear meets the front's profile wheelbase/speed later."""
    c, v = randomize.draw(road_class, rng), randomize.draw(speed, rng)
    lag = int(round(wheelbase / v / dt))
    r = iso8608_road(c, v, duration + lag * dt, dt, rng=rng, method="fft")
    z, zd = r.channel("z_r"), r.channel("zdot_r")
    n = z.size - lag
    data = np.column_stack([z[lag:], zd[lag:], z[:n], zd[:n]])
    return Record(dt, data, CHANNELS, UNITS, f"ISO 8608 class {c} (half car)")


ROADS = {"iso8608": _iso8608}


def road_source(road, road_params, dt: float, episode_seconds: float, wheelbase: float,
                budget: Budget | None = None) -> Disturbance:
    """The road part, by the quarter car's rule (:func:`mrd_env.envs.roads.road_source`): a kind name (with
    ``road_params``), a dict {"kind": ..., options}, a Record with channels z_rf, zdot_rf, z_rr, zdot_rr (m, m/s),
    or a :class:`~.disturbance.Disturbance`."""
    from ...envs.roads import road_source as car_road

    return car_road(road, road_params, dt, episode_seconds, kinds=ROADS, channels=CHANNELS, units=UNITS,
                    wheelbase=wheelbase, budget=budget)


# --- the assembly ------------------------------------------------------------------------------------------------
def _metrics(st: EpisodeStats, ep: Episode, static: np.ndarray) -> dict:
    """Comfort (ISO 2631-1 Wk r.m.s., VDV, MTVV of the body's heave), pitch, travel, road holding per axle and the
    share of the time a travel is beyond the soft stroke limit (see :class:`HalfCarEnv`, Episode End)."""
    ratio = st.rms["_tyre_load"] / static
    return {"acc_weighted_rms": float(st.rms["body_acc_wk"][0]), "pitch_acc_rms": float(st.rms["pitch_acc"][0]),
            "travel_peak": float(st.peak["travel"].max()),
            "tyre_load_ratio": float(np.max(ratio)), "duration": (st.n_rows - 1) * st.dt,
            "acc_vdv": float((st.dose4 * st.dt) ** 0.25), "acc_mtvv": st.max_running_rms,
            "tyre_load_ratio_front": float(ratio[0]), "tyre_load_ratio_rear": float(ratio[1]),
            "stroke_exceedance_share": exceedance_share(st)}


def _new_episode(p: HalfCarParams, rec: Record) -> Episode:
    """In static equilibrium on the road's initial heights, moving with it (no step hits a tyre or a suspension,
    as for the quarter car): each wheel on its road, the body where both strokes are zero."""
    zf, zdf, zr, zdr = rec.data[0]
    L = p.wheelbase
    body = np.array([[p.b / L, p.a / L], [-1.0 / L, 1.0 / L]])  # [z_s, θ] from the axles' heights (x_f = x_r = 0)
    zs, th = body @ [zf, zr]
    vs, om = body @ [zdf, zdr]
    return Episode(rec, np.array([zs, th, zf, zr, vs, om, zdf, zdr]))


def assembly(*, plant_preset="sedan", plant_params=None, road="iso8608", road_params=None, damper="spencer_dyke",
             damper_preset=None, damper_params=None, dt=1e-3, control_dt=1e-3, episode_seconds=10.0, sensors=None,
             sensor_noise=None, sensor_delay=0, history=1, action_mode="physical", inverse=None, force_range=None,
             reward=None, reward_weights=None, stroke_limit=0.1, soft_stroke_limit=None) -> Assembly:
    """The half-car environment's parts from its options (see :class:`HalfCarEnv`)."""
    given = {k: v for k, v in locals().items()}
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    p = plant_params if isinstance(plant_params, HalfCarParams) else \
        half_car(plant_preset, **opt.named_options("plant_params", plant_params))
    d = opt.make_env_damper(damper, damper_preset, damper_params, "automotive")
    lp = p.plant()
    coupled = CoupledPlant(lp, d)
    sm = SignalMap(coupled)
    S = lp.S
    axles = np.array([[1.0, -p.a, 0.0, 0.0], [1.0, p.b, 0.0, 0.0]])  # body motion above each axle
    sm.add("body_acc", sm.acc([[1.0, 0.0, 0.0, 0.0]]), "m/s^2")
    sm.add("pitch_acc", sm.acc([[0.0, 1.0, 0.0, 0.0]]), "rad/s^2")
    sm.add("travel", sm.disp(S), "m")
    sm.add("travel_rate", sm.vel(S), "m/s")
    sm.add("body_vel_at_axles", sm.vel(axles), "m/s")
    sm.add("wheel_vel", sm.vel(np.eye(4)[2:]), "m/s")
    sm.add("damper_force", sm.force(), "N")
    sm.add("damper_states", sm.damper_states(), "model")
    static = p.static_tyre_loads
    tyre = -np.diag([p.k_tf, p.k_tr]) @ np.eye(4)[2:]
    sm.add("_tyre_load", sm.disp(tyre) + sm.inp([[p.k_tf, 0, 0, 0], [0, 0, p.k_tr, 0]]), "N")
    sm.add("_q", sm.disp(np.eye(4)), "m, rad")  # for the renderer
    sm.add("_road", sm.inp([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), "m")
    sm.add_commands(d.command.unit)
    sm.add_output("body_acc_wk", "m/s^2")
    w = opt.weights(reward_weights, DEFAULT_REWARD_WEIGHTS)
    limit = opt.check_scalar("stroke_limit", stroke_limit, 0.0, lo_open=True, unit="m")
    soft = soft_limit("soft_stroke_limit", soft_stroke_limit, limit, SOFT_STROKE_FRACTION)
    reward = opt.reward(reward, lambda: QuadraticReward({"body_acc_wk": w["comfort"],
                                                         "travel": np.full(2, w["travel"] / X_REF ** 2),
                                                         "_tyre_load": w["tyre"] / static ** 2}))

    from .render import HalfCarRenderer

    return Assembly(
        kind=SPEC.name, damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=SENSORS, sensors=opt.sensors(sensors, sensor_noise, sensor_delay, history, DEFAULT_SENSORS),
        disturbance=road_source(road, road_params, dt, episode_seconds, p.wheelbase,
                                budget=Budget(FLOAT * coupled.system.nw)), reward=reward,
        limits=Limits({"travel": limit}, penalty_rate=w["termination"]),
        new_episode=functools.partial(_new_episode, p), metrics=functools.partial(_metrics, static=static),
        roles={"body_velocity": "body_vel_at_axles", "wheel_velocity": "wheel_vel", "damper_velocity": "travel_rate",
               "damper_stroke": "travel", "damper_force": "damper_force"},
        objective={"body_acc": 1.0, "travel": 1.0 / X_REF ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        filters=[("body_acc", "body_acc_wk", weighting_sos("Wk", dt))],
        stat_signals=("body_acc_wk", "pitch_acc", "travel", "_tyre_load"), renderer=HalfCarRenderer, options=given,
        dose_signal="body_acc_wk", dose_window=1.0, costs=car_costs(soft, static))


class HalfCarEnv(MRDamperEnv):
    """Half car (body heave and pitch, two wheels) with an MR damper at each axle, driven by a road profile.

    ## Description

    Half car in the pitch plane: body mass m_s and pitch inertia I_y, front and rear unsprung masses, suspension
    springs and tyres, and an MR damper across each suspension; the rear wheel meets the front wheel's road
    wheelbase/speed later. Physics at ``dt`` = 1 ms, the commands held over each control period. The task: ride
    comfort (heave and pitch) against rattle space and road holding, by choosing only the two dampers' commands.
    Equations: :mod:`mrd_env.plants.half_car`.

    ## Action Space

    Two commands (front, rear), a ``Box`` of shape ``(2,)``, float32: in ``Physical-v0`` in V or A, [v_min, v_max] of
    the preset ([0, 2] V for the default "automotive" Spencer–Dyke damper); in ``-v1`` normalised to [−1, 1];
    with ``action_mode="force"`` the desired damper forces (N). See :class:`~mrd_env.envs.base.MRDamperEnv`.

    ## Observation Space

    A ``Box(-inf, inf)``, float32, of the chosen sensors in order (``env.unwrapped.sensor_layout``). The default
    sensors, shape ``(8,)``:

    | Index | Sensor | Quantity | Unit |
    |---|---|---|---|
    | 0 | ``body_acc`` | body heave acceleration at the centre of mass | m/s² |
    | 1 | ``pitch_acc`` | body pitch acceleration (nose down positive) | rad/s² |
    | 2–3 | ``travel`` | suspension travel, front and rear (extension positive) | m |
    | 4–5 | ``damper_force`` | damper forces, front and rear | N |
    | 6–7 | ``command`` | the commands applied over the last step | V or A |

    All sensors: ``body_acc``, ``pitch_acc``, ``travel`` (2), ``travel_rate`` (2, m/s), ``body_vel_at_axles``
    (2, m/s: the body's vertical velocity above each axle), ``wheel_vel`` (2, m/s), ``damper_force`` (2),
    ``command`` (2), ``damper_states`` (hidden unless asked).

    ## Rewards

    The cost integrated over the control period, as the quarter car's but with fixed scales::

        r = −∫ (w_comfort a_w² + w_travel Σ_i (x_i / 0.05 m)² + w_tyre Σ_i (F_t,i / F_static,i)²) dt

    a_w the Wk-weighted body acceleration (m/s², filtered online), x_i the travel and F_t,i the dynamic tyre
    load of axle i over its static load. An episode ended by the stroke limit loses
    ``reward_weights["termination"]`` = 10 × its planned length in seconds.

    ## Starting State

    In static equilibrium on the road's initial heights and moving with it: each wheel on its road, the body
    where both suspension strokes are zero (as the quarter car). A
    generated road is new each episode, drawn from ``np_random`` (``reset(seed=...)``).

    ## Episode End

    ``terminated`` when a |travel| exceeds ``stroke_limit`` (0.1 m; ``info["termination_reason"] =
    "stroke_limit"``) or the simulation diverges; ``truncated`` after ``episode_seconds`` (10 s:
    ``env.spec.max_episode_steps`` 10 000 steps in ``Physical-v0``, 1 000 in ``-v1``).

    Constraint costs, as the quarter car's (:mod:`mrd_env.envs.costs`): ``info["cost"]`` the time (s) during the
    control period at which a travel is beyond ``soft_stroke_limit`` (default 0.8 × ``stroke_limit``) or a tyre
    lifts off (its dynamic load below −its static load), front or rear; ``info["cost_terms"]`` = {"stroke": s,
    "tyre_lift_off": s}.

    ``info["episode_metrics"]`` at the end of an episode: acc_weighted_rms (Wk, m/s²), acc_vdv (m/s^1.75),
    acc_mtvv (m/s², over 1 s) of the body's heave, pitch_acc_rms (rad/s²), travel_peak (m, both axles),
    tyre_load_ratio (the larger axle's r.m.s. dynamic tyre load over its static load), tyre_load_ratio_front,
    tyre_load_ratio_rear, stroke_exceedance_share (the share of the time a travel is beyond the soft stroke
    limit), duration (s), cost, cost_stroke, cost_tyre_lift_off (s).

    ## Arguments

    As :class:`~mrd_env.plants.quarter_car.env.QuarterCarEnv` where they apply, except:

    * ``road``: "iso8608" (default; a new road each episode under both axles, the rear meeting the front's
      profile wheelbase/speed later; ``road_params``: ``road_class`` "C" (or a list to draw from), ``speed``
      20 m/s (or a range (lo, hi))), a Record with channels z_rf, zdot_rf, z_rr, zdot_rr, or a Disturbance.
    * ``episode_seconds`` default 10 s; ``plant_preset`` "sedan" (:data:`mrd_env.plants.half_car.HALF_CAR_PRESETS`).
    * ``stroke_limit`` 0.1 m (each axle; the episode ends), ``soft_stroke_limit`` (default 0.8 × ``stroke_limit``:
      a cost).
    * ``reward_weights``: comfort 1.0 (on the Wk-weighted body acceleration², m²/s⁴), travel 0.5 (per
      (0.05 m)² on each axle), tyre 0.5 (per static tyre load²), termination 10 per second; or ``reward``.
    * no ``preview``.

    ## Version History

    * v1: the defaults an RL user expects — ``control_dt`` = 0.01 s (100 Hz) and ``action_mode="normalized"``
      (:data:`mrd_env.envs.RL_DEFAULTS`).
    * v0: the physics-level defaults — commands in V or A at every 1 ms step.
    """

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


class HalfCarVectorEnv(MRDamperVectorEnv):
    """``num_envs`` half cars in one compiled call (options as :class:`HalfCarEnv`)."""

    env_id = SPEC.physics_id
    build = staticmethod(assembly)
