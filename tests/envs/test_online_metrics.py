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


def _assert_same(online: dict, offline: dict) -> None:
    assert set(online) == set(offline)
    for key in offline:
        assert online[key] == pytest.approx(offline[key], rel=RTOL, abs=0.0), key


@pytest.mark.parametrize("env_id", ["mrd_env/QuarterCar-v1", "mrd_env/QuarterCarPhysical-v0"])
def test_quarter_car_metrics_online_equal_offline(env_id):
    env, info = _episode(env_id, 1, episode_seconds=3.0)
    acc, travel = env.signal("sprung_acc")[:, 0], env.signal("travel")[:, 0]
    assert acc[0] == 0.0  # the car starts at rest: the online filter's start (row 1) and sosfilt's (row 0) agree
    force = env.signal("damper_force")[:, 0]
    offline = QM.quarter_car_metrics(env.dt, acc, travel, dynamic_tyre_load=env.signal("_tyre_load")[:, 0],
                                    static_tyre_load=env.plant_params.static_tyre_load)
    offline.update(damper_force_rms=float(M.rms(force)), damper_force_peak=float(np.max(np.abs(force))),
                   duration=(acc.size - 1) * env.dt)
    assert offline["duration"] == pytest.approx(3.0)
    _assert_same(info["episode_metrics"], offline)


@pytest.mark.parametrize("options", [{}, {"ground_motion": "kanai_tajimi", "episode_seconds": 3.0}])
def test_building_metrics_online_equal_offline(options):
    env, info = _episode("mrd_env/ShearBuilding-v1", 2, **options)
    p, ep = env.plant_params, env.episode
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
               "duration": (rows - 1) * env.dt}
    assert {"J1", "J2", "J3", "J4", "J5", "J6", "force_over_weight", "stroke_over_disp"} <= set(offline)
    _assert_same(info["episode_metrics"], offline)


def test_half_car_metrics_online_equal_offline():
    env, info = _episode("mrd_env/HalfCar-v1", 3, episode_seconds=3.0)
    static = env.plant_params.static_tyre_loads
    # The online Wk filter starts at the first step (row 0, the initial state, is weighted 0). The half car does not
    # start at rest (body at zero heave, the wheels on the road's initial heights: row 0's body acceleration is
    # not 0), so the offline weighting starts at row 1 as well.
    acc = env.signal("body_acc")[:, 0]
    a_w = np.concatenate([[0.0], M.weighted_acceleration(acc[1:], env.dt)])
    offline = {"acc_weighted_rms": float(M.rms(a_w)),
               "pitch_acc_rms": float(M.rms(env.signal("pitch_acc")[:, 0])),
               "travel_peak": float(np.max(np.abs(env.signal("travel")))),
               "tyre_load_ratio": float(np.max(M.rms(env.signal("_tyre_load")) / static)),
               "duration": (env.signal("travel").shape[0] - 1) * env.dt}
    _assert_same(info["episode_metrics"], offline)
