"""Constraint costs (issue 39, item 4): ``info["cost"]`` per step (s in violation during the control period),
``info["cost_terms"]`` per constraint, their episode totals in ``episode_metrics``; the vector env's batched costs
as SyncVectorEnv's; the soft limits' options."""
from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.envs.costs import Constraint, Costs, SOFT_STROKE_FRACTION
from mrd_env.envs.vector import env_info

SHORT = dict(episode_seconds=0.1, control_dt=0.01)
TERMS = {"QuarterCar": ("stroke", "tyre_lift_off"), "HalfCar": ("stroke", "tyre_lift_off"),
         "ShearBuilding": ("drift",), "Isolator": ("stroke",)}
#: a small disturbance: no constraint is near its limit
QUIET = {"QuarterCar": dict(road_params={"road_class": "A"}), "HalfCar": dict(road_params={"road_class": "A"}),
         "ShearBuilding": dict(ground_motion_params={"amplitude_scale": 0.01}),
         "Isolator": dict(base_motion_params={"acc_rms": 0.01})}
#: a soft limit that the default disturbance exceeds (the hard limit, where there is one, far away)
TIGHT = {"QuarterCar": dict(soft_stroke_limit=2e-3), "HalfCar": dict(soft_stroke_limit=2e-3),
         "ShearBuilding": dict(drift_limit=1e-5), "Isolator": dict(soft_stroke_limit=1e-4)}


def _name(env_id: str) -> str:
    return env_id.split("/")[1].split("-")[0].removesuffix("Physical")


def _episode(env, action=None):
    """(per-step infos, the last info) of one episode at a constant action (the Box's midpoint)."""
    a = 0.5 * (env.action_space.low + env.action_space.high) if action is None else action
    infos = []
    while True:
        *_, term, trunc, info = env.step(a)
        infos.append(info)
        if term or trunc:
            return infos, info


V1 = ["mrd_env/QuarterCar-v1", "mrd_env/HalfCar-v1", "mrd_env/ShearBuilding-v1", "mrd_env/Isolator-v1"]


@pytest.mark.parametrize("env_id", V1)
def test_cost_is_zero_on_a_quiet_episode_and_positive_beyond_a_soft_limit(env_id):
    name = _name(env_id)
    env = gym.make(env_id, episode_seconds=0.3, **QUIET[name])
    _, info = env.reset(seed=0)
    assert info["cost"] == 0.0 and info["cost_terms"] == dict.fromkeys(TERMS[name], 0.0)
    infos, last = _episode(env)
    assert all(i["cost"] == 0.0 and set(i["cost_terms"]) == set(TERMS[name]) for i in infos)
    m = last["episode_metrics"]
    assert m["cost"] == 0.0 and all(m[f"cost_{t}"] == 0.0 for t in TERMS[name])

    env = gym.make(env_id, episode_seconds=0.3, **TIGHT[name])
    env.reset(seed=0)
    infos, last = _episode(env)
    assert not last.get("termination_reason")
    costs = np.array([i["cost"] for i in infos])
    assert costs.max() > 0.0 and np.all(costs >= 0.0) and np.all(costs <= 0.01 + 1e-15)
    assert last["episode_metrics"]["cost"] > 0.0


@pytest.mark.parametrize("env_id", ["mrd_env/QuarterCarPhysical-v0", "mrd_env/HalfCar-v1"])
def test_tyre_lift_off_costs_where_the_dynamic_load_exceeds_the_static(env_id):
    """A rough road at speed lifts the wheels: the tyre term, from the dynamic tyre load below −static."""
    road = dict(road="bump", road_params={"height": 0.08, "length": 0.3, "speed": 20.0}) if "Quarter" in env_id \
        else dict(road_params={"road_class": "F", "speed": 30.0})
    env = gym.make(env_id, episode_seconds=1.0, stroke_limit=1.0, soft_stroke_limit=1.0, **road)
    env.reset(seed=0)
    infos, last = _episode(env)
    m = last["episode_metrics"]
    assert m["cost_tyre_lift_off"] > 0.0 and m["cost_stroke"] == 0.0 and m["cost"] == m["cost_tyre_lift_off"]
    load = env.unwrapped.signal("_tyre_load")
    static = env.unwrapped.plant_params.static_tyre_load if "Quarter" in env_id else \
        env.unwrapped.plant_params.static_tyre_loads
    assert m["cost_tyre_lift_off"] == pytest.approx(np.count_nonzero(np.any(load[1:] < -static, axis=1)) * 1e-3)


@pytest.mark.parametrize("env_id", V1 + ["mrd_env/IsolatorPhysical-v0"])
def test_step_costs_count_the_periods_physics_rows_and_sum_to_the_episode_total(env_id):
    """Each step's cost is dt × the rows of its period at which a declared constraint is violated (counted here
    from the episode's history: violations between control steps count), per term and any; the episode totals are
    the sums of the step costs, bit for bit."""
    name = _name(env_id)
    env = gym.make(env_id, episode_seconds=0.5, **TIGHT[name])
    env.reset(seed=3)
    infos, last = _episode(env, env.action_space.low)
    u = env.unwrapped
    dt, n_sub = u.dt, u.assembly.n_sub
    terms = u.assembly.costs.terms
    assert tuple(terms) == TERMS[name]
    beyond = {}
    for term, constraints in terms.items():
        hits = []
        for c in constraints:
            x = u.signal(c.signal)
            v = {"both": np.abs(x), "above": x, "below": -x}[c.side]
            hits.append(np.any(v > np.asarray(c.limit), axis=1))
        beyond[term] = np.any(hits, axis=0)
    anyone = np.any(list(beyond.values()), axis=0)
    totals = dict.fromkeys(("cost", *TERMS[name]), 0.0)
    for k, info in enumerate(infos):
        rows = slice(k * n_sub + 1, (k + 1) * n_sub + 1)
        assert info["cost"] == int(np.count_nonzero(anyone[rows])) * dt
        for term in TERMS[name]:
            assert info["cost_terms"][term] == int(np.count_nonzero(beyond[term][rows])) * dt
            totals[term] += info["cost_terms"][term]
        totals["cost"] += info["cost"]
    m = last["episode_metrics"]
    assert m["cost"] == totals["cost"] > 0.0
    assert all(m[f"cost_{t}"] == totals[t] for t in TERMS[name])


def _pair(env_id, mode, **kw):
    kw = {**SHORT, **kw}
    native = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kw)
    sync = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **kw)
    return native, sync


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP], ids=lambda m: m.value)
@pytest.mark.parametrize("env_id", V1)
def test_vector_costs_equal_sync_vector_env_bit_for_bit(env_id, mode):
    """The native vector env's ``infos["cost"]`` (N,) and ``infos["cost_terms"]`` with their masks on every step,
    ``final_info`` included, as SyncVectorEnv over the scalar envs gives them (a soft limit the random commands
    exceed: costs that are not all zero, and a stroke limit that ends some episodes early)."""
    name = _name(env_id)
    extra = {} if name == "ShearBuilding" else {"stroke_limit": 6e-3 if name == "Isolator" else 8e-3}
    native, sync = _pair(env_id, mode, **TIGHT[name], **extra)
    assert data_equivalence(native.reset(seed=0), sync.reset(seed=0), exact=True)
    native.action_space.seed(1)
    paid = 0.0
    for _ in range(25):
        a = native.action_space.sample()
        out_n, out_s = native.step(a), sync.step(a)
        assert data_equivalence(out_n, out_s, exact=True), (out_n[4], out_s[4])
        info = out_n[4]
        assert info["cost"].shape == (3,) and info["_cost"].all() and info["_cost_terms"].all()
        assert set(info["cost_terms"]) == {*TERMS[name], *(f"_{t}" for t in TERMS[name])}
        paid += info["cost"].sum() + info.get("final_info", {}).get("cost", np.zeros(3)).sum()
    assert paid > 0.0


def test_vector_env_i_costs_equal_a_scalar_env_with_the_same_seed():
    env_id = "mrd_env/QuarterCar-v1"
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **SHORT, **TIGHT["QuarterCar"])
    env = gym.make(env_id, **SHORT, **TIGHT["QuarterCar"])
    venv.reset(seed=5)
    env.reset(seed=6)
    a = np.array([[0.3], [-0.7]])
    for _ in range(10):
        info = venv.step(a)[4]
        scalar = env.step(a[1])[4]
        mine = env_info(info, 1)
        assert mine["cost"] == scalar["cost"] and mine["cost_terms"] == scalar["cost_terms"]
    assert mine["episode_metrics"] == scalar["episode_metrics"]


def test_sb3_bridge_passes_the_costs():
    pytest.importorskip("stable_baselines3")
    from mrd_env.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mrd_env/QuarterCar-v1", n_envs=2, seed=0, **SHORT, **TIGHT["QuarterCar"])
    venv.reset()
    seen = 0.0
    for _ in range(12):
        _, _, dones, infos = venv.step(np.full((2, 1), -1.0, dtype=np.float32))
        for i in infos:
            assert set(i["cost_terms"]) == {"stroke", "tyre_lift_off"} and 0.0 <= i["cost"] <= 0.01
            seen += i["cost"]
        assert all("episode_metrics" in infos[i] for i in np.flatnonzero(dones))
    assert seen > 0.0


# --- options ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id, option, value, match", [
    ("mrd_env/QuarterCar-v1", "soft_stroke_limit", 0.0, "soft_stroke_limit"),
    ("mrd_env/QuarterCar-v1", "soft_stroke_limit", -0.01, "soft_stroke_limit"),
    ("mrd_env/QuarterCar-v1", "soft_stroke_limit", math.nan, "soft_stroke_limit"),
    ("mrd_env/QuarterCar-v1", "soft_stroke_limit", "big", "soft_stroke_limit"),
    ("mrd_env/QuarterCar-v1", "soft_stroke_limit", 0.2, "soft_stroke_limit must not exceed the hard limit"),
    ("mrd_env/HalfCar-v1", "soft_stroke_limit", 0.0, "soft_stroke_limit"),
    ("mrd_env/HalfCar-v1", "soft_stroke_limit", 0.11, "soft_stroke_limit must not exceed"),
    ("mrd_env/Isolator-v1", "soft_stroke_limit", -1.0, "soft_stroke_limit"),
    ("mrd_env/Isolator-v1", "soft_stroke_limit", 0.06, "soft_stroke_limit must not exceed"),
    ("mrd_env/ShearBuilding-v1", "drift_limit", 0.0, "drift_limit"),
    ("mrd_env/ShearBuilding-v1", "drift_limit", 1.5, "drift_limit"),
    ("mrd_env/ShearBuilding-v1", "drift_limit", math.inf, "drift_limit"),
    ("mrd_env/ShearBuilding-v1", "drift_limit", [0.01], "drift_limit"),
])
def test_bad_limit_options_raise_naming_the_option(env_id, option, value, match):
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **{option: value})
    with pytest.raises(ValueError, match=match):
        gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **{option: value})


def test_soft_limits_default_and_follow_the_hard_limit():
    from mrd_env.plants.shear_building.env import DRIFT_LIMIT

    def limits(env_id, **kw):
        costs = gym.make(env_id, **kw).unwrapped.assembly.costs
        return {t: [np.asarray(c.limit).tolist() for c in cons] for t, cons in costs.terms.items()}

    assert limits("mrd_env/QuarterCar-v1")["stroke"] == [SOFT_STROKE_FRACTION * 0.1]
    assert limits("mrd_env/QuarterCar-v1", stroke_limit=0.05)["stroke"] == [SOFT_STROKE_FRACTION * 0.05]
    assert limits("mrd_env/QuarterCar-v1", soft_stroke_limit=0.03)["stroke"] == [0.03]
    assert limits("mrd_env/Isolator-v1")["stroke"] == [SOFT_STROKE_FRACTION * 0.05]
    assert limits("mrd_env/ShearBuilding-v1") == {"drift": [DRIFT_LIMIT]} and DRIFT_LIMIT == 0.01
    assert limits("mrd_env/ShearBuilding-v1", drift_limit=0.02) == {"drift": [0.02]}


def test_costs_part_refuses_bad_constraints():
    with pytest.raises(ValueError, match="side"):
        Constraint("travel", 0.1, "sideways")
    with pytest.raises(ValueError, match="finite and > 0"):
        Constraint("travel", 0.0)
    with pytest.raises(ValueError, match="identifier not starting"):
        Costs({"a b": Constraint("travel", 0.1)})
    with pytest.raises(ValueError, match="must hold one or more Constraint"):
        Costs({"stroke": []})
    env = gym.make("mrd_env/QuarterCar-v1")
    with pytest.raises(ValueError, match="unknown signal 'nothing'"):
        Costs({"x": Constraint("nothing", 1.0)}).bind(env.unwrapped.assembly.signals)
    with pytest.raises(ValueError, match="3 values; the signal has 1 channels"):
        Costs({"x": Constraint("travel", [1.0, 2.0, 3.0])}).bind(env.unwrapped.assembly.signals)
