"""Half car with MR dampers at the front and the rear (``mrd_env/HalfCar-v0``): the example of a plant added
to the library — this module, the plant's module and one line in :data:`mrd_env.envs.ENVS`."""
from __future__ import annotations

import numpy as np

from ..disturbances import Record, iso8608_road
from ..metrics import weighting_sos
from ..plants import CoupledPlant
from ..plants.half_car import HalfCarParams, half_car
from . import options as opt
from .base import MRDamperEnv
from .core import Assembly, Episode, EpisodeStats
from .disturbance import Generated
from .reward import QuadraticReward
from .signals import SignalMap
from .termination import Limits
from .vector import MRDamperVectorEnv

CHANNELS = ("z_rf", "zdot_rf", "z_rr", "zdot_rr")
SENSORS = ("body_acc", "pitch_acc", "travel", "travel_rate", "body_vel_at_axles", "wheel_vel", "damper_force",
           "command", "damper_states")


def road(road_class: str, speed: float, duration: float, dt: float, wheelbase: float):
    """An ISO 8608 road under both axles: the rear meets the front's profile wheelbase/speed later."""
    lag = int(round(wheelbase / speed / dt))

    def generate(rng) -> Record:
        r = iso8608_road(road_class, speed, duration + lag * dt, dt, rng=rng, method="fft")
        z, zd = r.channel("z_r"), r.channel("zdot_r")
        n = z.size - lag
        data = np.column_stack([z[lag:], zd[lag:], z[:n], zd[:n]])
        return Record(dt, data, CHANNELS, ("m", "m/s", "m", "m/s"), f"ISO 8608 class {road_class} (half car)")
    generate(np.random.default_rng(0))  # the options are checked now
    return Generated(generate, CHANNELS, f"ISO 8608 class {road_class} at {speed:g} m/s, both axles")


def assembly(*, plant_preset="sedan", plant_params=None, road_class="C", speed=20.0, damper="spencer_dyke",
             damper_preset=None, damper_params=None, dt=1e-3, control_dt=1e-3, episode_seconds=10.0, sensors=None,
             sensor_noise=None, sensor_delay=0, history=1, action_mode="physical", inverse=None, force_range=None,
             stroke_limit=0.1) -> Assembly:
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
    sm.add_commands(d.command.unit)
    sm.add_output("body_acc_wk", "m/s^2")
    reward = QuadraticReward({"body_acc_wk": 1.0, "travel": np.full(2, 0.5 / 0.05 ** 2),
                              "_tyre_load": 0.5 / static ** 2})

    def metrics(st: EpisodeStats, ep: Episode) -> dict:
        return {"acc_weighted_rms": float(st.rms["body_acc_wk"][0]), "pitch_acc_rms": float(st.rms["pitch_acc"][0]),
                "travel_peak": float(st.peak["travel"].max()), "tyre_load_ratio": float(np.max(
                    st.rms["_tyre_load"] / static)), "duration": (st.n_rows - 1) * st.dt}

    return Assembly(
        kind="half_car", damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=SENSORS, sensors=opt.sensors(sensors, sensor_noise, sensor_delay, history,
                                                  ("body_acc", "pitch_acc", "travel", "damper_force", "command")),
        disturbance=road(road_class, speed, episode_seconds, dt, p.wheelbase), reward=reward,
        limits=Limits({"travel": opt.check_scalar("stroke_limit", stroke_limit, 0.0, lo_open=True)}),
        new_episode=lambda rec: Episode(rec, np.concatenate([[0.0, 0.0], rec.data[0, [0, 2]], [0.0, 0.0],
                                                             rec.data[0, [1, 3]]])),
        metrics=metrics,
        roles={"body_velocity": "body_vel_at_axles", "wheel_velocity": "wheel_vel", "damper_velocity": "travel_rate",
               "damper_stroke": "travel", "damper_force": "damper_force"},
        objective={"body_acc": 1.0, "travel": 1.0 / 0.05 ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        filters=[("body_acc", "body_acc_wk", weighting_sos("Wk", dt))],
        stat_signals=("body_acc_wk", "pitch_acc", "travel", "_tyre_load"))


class HalfCarEnv(MRDamperEnv):
    """Half car (body heave and pitch, two wheels) with an MR damper at each axle on an ISO 8608 road
    (``road_class``, ``speed``); two commands per step (front, rear). Options as
    :class:`~mrd_env.envs.quarter_car.QuarterCarEnv` where they apply; no rendering."""

    metadata = {"render_modes": [], "render_fps": 30}

    def __init__(self, *, render_mode=None, **options):
        super().__init__(assembly(**options), render_mode=render_mode)


class HalfCarVectorEnv(MRDamperVectorEnv):
    def __init__(self, num_envs: int = 1, *, render_mode=None, autoreset_mode="NextStep", **options):
        super().__init__(assembly(**options), num_envs, render_mode=render_mode, autoreset_mode=autoreset_mode)
