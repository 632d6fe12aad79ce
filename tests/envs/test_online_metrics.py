"""The driver's online episode metrics (``info["episode_metrics"]`` at the end of an episode: r.m.s., peaks, the
fourth-power dose and the running r.m.s. accumulated step by step inside the compiled driver) equal
:mod:`mrd_env.metrics` computed offline on the same episode's history (``env.signal``): the two implementations
of one definition are tied together here."""
import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env import metrics as M
from mrd_env.plants.quarter_car import metrics as QM
from mrd_env.plants.shear_building import metrics as BM

RTOL = 1e-12  # the two differ only in summation order


def _episode(env_id: str, seed: int, **options) -> tuple[gym.Env, dict]:
    """A whole episode under random commands (so that the damper does work); the unwrapped env and the last info."""
    env = gym.make(env_id, **options)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    while True:
        a = rng.uniform(env.action_space.low, env.action_space.high).astype(env.action_space.dtype)
        *_, term, trunc, info = env.step(a)
        if term or trunc:
            return env.unwrapped, info


def _costs(env, **terms) -> dict:
    """The episode's constraint costs offline: the time beyond each soft limit (the rows after the first, each dt),
    of each term and of any (``terms``: {term: (signal, limit, side)})."""
    beyond = {}
    for term, (signal, limit, side) in terms.items():
        x = env.signal(signal)
        v = {"both": np.abs(x), "above": x, "below": -x}[side]
        beyond[term] = np.any(v[1:] > limit, axis=1)
        assert M.exceedance_time(env.dt, x, limit, side) == np.count_nonzero(beyond[term]) * env.dt
    out = {"cost": np.count_nonzero(np.any(list(beyond.values()), axis=0)) * env.dt}
    out.update({f"cost_{t}": np.count_nonzero(b) * env.dt for t, b in beyond.items()})
    return out


def _assert_same(online: dict, offline: dict) -> None:
    assert set(online) == set(offline)
    for key in offline:
        assert online[key] == pytest.approx(offline[key], rel=RTOL, abs=0.0), key


@pytest.mark.parametrize("env_id", ["mrd_env/QuarterCar-v1", "mrd_env/QuarterCarPhysical-v0"])
def test_quarter_car_metrics_online_equal_offline(env_id):
    env, info = _episode(env_id, 1, episode_seconds=3.0, road_params={"road_class": "D"})
    acc, travel = env.signal("sprung_acc")[:, 0], env.signal("travel")[:, 0]
    assert acc[0] == 0.0  # the car starts at rest: the online filter's start (row 1) and sosfilt's (row 0) agree
    force = env.signal("damper_force")[:, 0]
    static, soft = env.plant_params.static_tyre_load, 0.8 * 0.1
    offline = QM.quarter_car_metrics(env.dt, acc, travel, dynamic_tyre_load=env.signal("_tyre_load")[:, 0],
                                    static_tyre_load=static, soft_stroke_limit=soft)
    offline.update(damper_force_rms=float(M.rms(force)), damper_force_peak=float(np.max(np.abs(force))),
                   duration=(acc.size - 1) * env.dt)
    offline.update(_costs(env, stroke=("travel", soft, "both"), tyre_lift_off=("_tyre_load", static, "below")))
    assert offline["duration"] == pytest.approx(3.0)
    _assert_same(info["episode_metrics"], offline)


@pytest.mark.parametrize("options", [{"drift_limit": 0.005}, {"ground_motion": "kanai_tajimi", "episode_seconds": 3.0},
                                     {"damper_floors": [1, 2, 3], "episode_seconds": 4.0}])
def test_building_metrics_online_equal_offline(options):
    env, info = _episode("mrd_env/ShearBuilding-v1", 2, **options)
    p, ep = env.plant_params, env.episode
    limit = options.get("drift_limit", 0.01)
    controlled = BM.building_metrics(env.dt, env.signal("drift"), ep.extras["heights"], env.signal("abs_acc"),
                                    floor_masses=np.asarray(p.masses), damper_force=env.signal("damper_force"),
                                    damper_stroke=env.signal("damper_stroke"),
                                    displacement=env.signal("floor_disp"))
    rows = env.signal("drift").shape[0]
    # the uncontrolled building on the same record and the same window, computed apart from the env's cache
    unc = BM.building_metrics(env.dt, ep.extras["uncontrolled"]["drift"][:rows], ep.extras["heights"],
                             ep.extras["uncontrolled"]["abs_acc"][:rows], floor_masses=np.asarray(p.masses),
                             displacement=ep.extras["uncontrolled"]["disp"][:rows])
    offline = {**controlled, **BM.benchmark_criteria(controlled, unc, building_weight=p.weight),
               "duration": (rows - 1) * env.dt,
               **BM.control_power(env.dt, env.signal("damper_force"), env.signal("damper_velocity")),
               "drift_exceedance_share": M.exceedance_share(env.dt, env.signal("_drift_ratio"), limit),
               **_costs(env, drift=("_drift_ratio", limit, "both"))}
    assert {"J1", "J2", "J3", "J4", "J5", "J6", "force_over_weight", "stroke_over_disp"} <= set(offline)
    if "drift_limit" in options:  # El Centro drives the storeys beyond 0.5 %: the drift term is not all zero
        assert offline["cost_drift"] > 0.0
    _assert_same(info["episode_metrics"], offline)


def test_half_car_metrics_online_equal_offline():
    env, info = _episode("mrd_env/HalfCar-v1", 3, episode_seconds=3.0, soft_stroke_limit=0.01,
                         road_params={"road_class": "E"})
    static = env.plant_params.static_tyre_loads
    # The online Wk filter starts at the first step (row 0, the initial state, is weighted 0). The half car does not
    # start at rest (body at zero heave, the wheels on the road's initial heights: row 0's body acceleration is
    # not 0), so the offline weighting starts at row 1 as well.
    acc = env.signal("body_acc")[:, 0]
    a_w = np.concatenate([[0.0], M.weighted_acceleration(acc[1:], env.dt)])
    ratio = M.rms(env.signal("_tyre_load")) / static
    travel = env.signal("travel")
    offline = {"acc_weighted_rms": float(M.rms(a_w)),
               "pitch_acc_rms": float(M.rms(env.signal("pitch_acc")[:, 0])),
               "travel_peak": float(np.max(np.abs(travel))),
               "tyre_load_ratio": float(np.max(ratio)), "tyre_load_ratio_front": float(ratio[0]),
               "tyre_load_ratio_rear": float(ratio[1]),
               "acc_vdv": float(M.vdv(a_w, env.dt)), "acc_mtvv": float(M.mtvv(a_w, env.dt)),
               "stroke_exceedance_share": M.exceedance_share(env.dt, travel, 0.01),
               "duration": (travel.shape[0] - 1) * env.dt,
               **_costs(env, stroke=("travel", 0.01, "both"), tyre_lift_off=("_tyre_load", static, "below"))}
    assert offline["cost_stroke"] > 0.0 and offline["cost_tyre_lift_off"] > 0.0
    _assert_same(info["episode_metrics"], offline)


def test_isolator_metrics_online_equal_offline():
    env, info = _episode("mrd_env/Isolator-v1", 4, episode_seconds=3.0, soft_stroke_limit=3e-4)
    acc, base = env.signal("payload_acc")[:, 0], env.signal("base_acc")[:, 0]
    a_w = np.concatenate([[0.0], M.weighted_acceleration(acc[1:], env.dt)])
    stroke, force = env.signal("stroke")[:, 0], env.signal("damper_force")[:, 0]
    offline = {"acc_rms": float(M.rms(acc)), "acc_peak": float(np.max(np.abs(acc))),
               "acc_weighted_rms": float(M.rms(a_w)), "acc_vdv": float(M.vdv(a_w, env.dt)),
               "acc_mtvv": float(M.mtvv(a_w, env.dt)), "transmissibility": float(M.rms(acc) / M.rms(base)),
               "stroke_rms": float(M.rms(stroke)), "stroke_peak": float(np.max(np.abs(stroke))),
               "damper_force_rms": float(M.rms(force)), "damper_force_peak": float(np.max(np.abs(force))),
               "duration": (stroke.size - 1) * env.dt,
               "stroke_exceedance_share": M.exceedance_share(env.dt, stroke, 3e-4),
               **_costs(env, stroke=("stroke", 3e-4, "both"))}
    assert 0.0 < offline["stroke_exceedance_share"] < 1.0
    _assert_same(info["episode_metrics"], offline)
