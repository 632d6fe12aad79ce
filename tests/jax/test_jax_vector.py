"""The Gymnasium vector environment over the JAX environment (:mod:`mrd_env.jax.vector`) against the native vector
environment of the same id and options, for the quarter car, the shear building and the half car, on one fixed
record each: observations, rewards, flags, infos (keys, masks, costs, termination reasons) through the NEXT_STEP
autoreset; seeding, per-episode draws without recompiling, copies, make_vec's backends and refused options."""
from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
from gymnasium.utils.env_checker import data_equivalence  # noqa: E402

import mrd_env  # noqa: E402,F401
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.jax import env as je  # noqa: E402
from mrd_env.jax import vector as jv  # noqa: E402
from mrd_env.plants.quarter_car.suites import ROBUST_BANDS  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")

ROAD = iso8608_road("D", 20.0, 0.06, 1e-3, rng=7, method="fft")
#: the half car's road (front and rear wheel tracks): the one its native environment meets at reset(seed=7)
AXLES = je.native_records(je.assembly_of("mrd_env/HalfCar-v1", {"episode_seconds": 0.06})[0], [7])[0]
#: (RL id, options for both backends, the JAX one's own: the exact scheme, the native numbers); 2 environments,
#: limits small enough that costs accrue and an episode ends on its limit
CASES = {
    "quarter_car": ("mrd_env/QuarterCar-v1", dict(road=ROAD, episode_seconds=0.05, soft_stroke_limit=2e-3,
                                                  stroke_limit=4e-3), {"scheme": "exact"}),
    "shear_building": ("mrd_env/ShearBuilding-v1", dict(ground_motion="el_centro", episode_seconds=0.3,
                                                        drift_limit=1e-4, stroke_limit=1e-5), {"scheme": "exact"}),
    "half_car": ("mrd_env/HalfCar-v1", dict(road=AXLES, episode_seconds=0.05, soft_stroke_limit=2e-3,
                                            stroke_limit=4e-3), {"scheme": "exact"}),
}
EXTRA = ("effective_command", "_effective_command")  # the JAX environment's own info
NATIVE_ONLY = ("episode_metrics", "_episode_metrics")  # not computed in JAX


def _pair(case, num_envs=2):
    env_id, opts, own = CASES[case]
    native = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **opts)
    twin = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", backend="jax", **opts,
                        **own)
    return native, twin


def _policy(space, n, seed=0):
    """n random batches of actions, environment 0's softest (its stroke the largest: it meets the limit)."""
    a = np.random.default_rng(seed).uniform(space.low, space.high, (n, *space.shape))
    a[:, 0] = space.low[0]
    return a.astype(np.float32)


def _assert_same_infos(ij, inn):
    assert sorted(set(ij) - set(EXTRA)) == sorted(set(inn) - set(NATIVE_ONLY))
    for key, value in inn.items():
        if key in NATIVE_ONLY:
            continue
        if isinstance(value, dict):
            _assert_same_infos(ij[key], value)
        elif value.dtype == object:
            assert list(ij[key]) == list(value), key
        elif value.dtype == bool:
            assert np.array_equal(ij[key], value), key
        else:
            np.testing.assert_allclose(ij[key], value, rtol=1e-12, atol=1e-12, err_msg=key)


@pytest.mark.parametrize("case", CASES)
def test_matches_the_native_vector_env_through_an_autoreset(case):
    native, twin = _pair(case)
    assert isinstance(twin, jv.JaxVectorEnv) and twin.control_dt == pytest.approx(native.control_dt)
    assert twin.observation_space == native.observation_space and twin.action_space == native.action_space
    o_n, i_n = native.reset(seed=0)
    o_j, i_j = twin.reset(seed=0)
    assert o_j.dtype == np.float32 and twin.observation_space.contains(o_j)
    scale = 1e-9 * np.abs(o_n).max(axis=0)  # observations at rest: roundoff around 0
    np.testing.assert_allclose(o_j, o_n, rtol=1e-6, atol=scale.max())
    _assert_same_infos(i_j, i_n)
    n = 2 * native.max_episode_steps + 2
    ends = costs = 0
    reasons = set()
    for a in _policy(native.action_space, n):
        o_n, r_n, te_n, tr_n, inn = native.step(a)
        o_j, r_j, te_j, tr_j, ij = twin.step(a)
        np.testing.assert_allclose(o_j, o_n, rtol=1e-6, atol=1e-9 * np.abs(o_n).max())
        np.testing.assert_allclose(r_j, r_n, rtol=1e-9, atol=1e-15)
        assert np.array_equal(te_j, te_n) and np.array_equal(tr_j, tr_n)
        _assert_same_infos(ij, inn)
        ends += int((te_n | tr_n).sum())
        costs += int(np.count_nonzero(inn["cost"]))
        reasons |= set(inn.get("termination_reason", [None])) - {None}
    assert ends >= 2 and costs > 0 and "stroke_limit" in reasons, (ends, costs, reasons)
    native.close()
    twin.close()


#: the quarter car's robustness bands that the JAX environment draws (its damper and command lag)
BANDS = {"damper_params": ROBUST_BANDS["damper_params"], "command": {"eta": ROBUST_BANDS["command"]["eta"]}}


def _run(env, actions):
    """Observations, rewards, flags and the damper parameters drawn, step by step."""
    out = []
    for a in actions:
        out.append((*env.step(a)[:4], np.asarray(env._P), np.asarray(env._lag)))
    return out


def test_seeded_resets_replay_and_draws_differ_per_env_and_episode_without_compiling():
    """reset(seed) replays bit for bit; randomise draws each environment's damper at every reset and autoreset,
    within the bands, through the program the nominal environment compiled (jit's cache: no new entry)."""
    env_id, opts, _ = CASES["quarter_car"]
    nominal = jv.JaxVectorEnv(env_id, 2, **opts)
    nominal.reset(seed=1)
    actions = _policy(nominal.action_space, 2 * nominal.max_episode_steps + 2, seed=3)
    plain = _run(nominal, actions)
    compiled = (jv._advance_all._cache_size(), jv._start_all._cache_size())
    env = jv.JaxVectorEnv(env_id, 2, randomise={**BANDS, "seed": 39}, **opts)
    env.reset(seed=1)
    first = _run(env, actions)
    env.reset(seed=1)
    assert data_equivalence(_run(env, actions), first, exact=True)
    assert (jv._advance_all._cache_size(), jv._start_all._cache_size()) == compiled
    P0 = np.asarray(nominal.params.P)[0, 0]  # (episodes' plants, dampers, parameters)
    draws = {tuple(step[-2][b, 0, 0]) for step in first for b in range(2)}
    starts = 2 + sum(int((step[2] | step[3]).sum()) for step in first[:-1])  # the resets, then the autoresets
    assert starts >= 4 and len(draws) == starts  # a draw per episode
    cols = [nominal.params.param_names.index(n) for n in BANDS["damper_params"]]
    ratio = np.array([np.asarray(d)[cols] / P0[cols] for d in draws])
    assert np.all((ratio >= 0.85) & (ratio <= 1.15))
    eta = np.array([step[-1][:, 0, 0, 0] for step in first]) / np.asarray(nominal.params.lag)[0, 0, 0]
    assert np.all((eta >= 0.7) & (eta <= 1.3)) and len(np.unique(eta)) == starts
    other = [i for i in range(len(P0)) if i not in cols]
    assert np.all(np.array([np.asarray(d)[other] for d in draws]) == P0[other])
    assert not np.allclose([s[1] for s in first], [s[1] for s in plain], rtol=1e-6)  # the draws change the physics
    env.reset(seed=2)
    assert not np.array_equal(np.asarray(env._P), first[0][-2])
    env.reset(options={"reset_mask": np.array([False, True])})  # only environment 1 starts again (a new draw)
    P = np.asarray(env._P)
    env.reset(options={"reset_mask": np.array([False, True])})
    assert np.array_equal(np.asarray(env._P)[0], P[0]) and not np.array_equal(np.asarray(env._P)[1], P[1])


@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_copies_step_identically(how):
    """A copy made mid-episode steps as its original through an autoreset, bit for bit, and compiles nothing."""
    env_id, opts, _ = CASES["quarter_car"]
    env = jv.JaxVectorEnv(env_id, 2, randomise=BANDS, **opts)
    env.reset(seed=5)
    actions = _policy(env.action_space, 12, seed=4)
    _run(env, actions[:3])
    twin = pickle.loads(pickle.dumps(env)) if how == "pickle" else copy.deepcopy(env)
    compiled = jv._advance_all._cache_size()
    a, b = [], []
    for act in actions[3:]:
        a.append(env.step(act))
        b.append(twin.step(act))
    assert data_equivalence(a, b, exact=True) and jv._advance_all._cache_size() == compiled


def test_bad_options_and_actions_are_refused_by_name():
    env_id, opts, _ = CASES["quarter_car"]
    env = jv.JaxVectorEnv(env_id, 2, **opts)
    env.reset(seed=0)
    before = env._state  # (JAX arrays are immutable: a refused step must leave the same object)
    with pytest.raises(ValueError, match="actions"):
        env.step(np.array([[0.0], [np.nan]]))
    with pytest.raises(ValueError, match="actions"):
        env.step(np.zeros((3, 1)))
    assert env._state is before and not env._ended.any()
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=-1)
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_maks": np.ones(2, bool)})
    refused = {"num_envs": dict(num_envs=0), "autoreset_mode": dict(autoreset_mode="same_step"),
               "render_mode": dict(render_mode="rgb_array"),
               "zeta": dict(randomise={"damper_params": {"zeta": (0.9, 1.1)}}),
               "c0a": dict(randomise={"damper_params": {"c0a": (1.1, 0.9)}}), "scheme": dict(scheme="rk4"),
               "substeps": dict(scheme="differentiable", substeps=3), "seeds": dict(seeds=[0], records=[ROAD]),
               "max_episode_steps": dict(max_episode_steps=0), "sensor_noyse": dict(sensor_noyse={})}
    for name, bad in refused.items():
        with pytest.raises(ValueError, match=name.replace(".", r"\.")):
            jv.JaxVectorEnv(env_id, **{"num_envs": 2, **opts, **bad})


def test_make_vec_backends():
    """The physics-level id's JAX environment has the native one's defaults (1 ms, commands in V); an unknown
    backend is refused by name; the native backend does not import JAX (a subprocess: this one has)."""
    import subprocess
    import sys

    env = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=1, vectorization_mode="vector_entry_point",
                       backend="jax", road=ROAD, episode_seconds=0.02)
    native = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=1, vectorization_mode="vector_entry_point",
                          road=ROAD, episode_seconds=0.02)
    assert env.control_dt == pytest.approx(1e-3) and env.action_space == native.action_space
    for opts in ({"history": 3, "sensor_delay": 1}, {"damper_floors": [1, 2]}):  # (made, not compiled)
        env_id = "mrd_env/ShearBuilding-v1" if "damper_floors" in opts else "mrd_env/QuarterCar-v1"
        made = [gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", backend=b, **opts)
                for b in ("jax", "native")]
        assert made[0].observation_space == made[1].observation_space
        assert made[0].action_space == made[1].action_space
    with pytest.raises(ValueError, match="backend"):
        gym.make_vec("mrd_env/QuarterCar-v1", num_envs=1, vectorization_mode="vector_entry_point", backend="torch")
    code = ("import sys, gymnasium as gym, mrd_env; e = gym.make_vec('mrd_env/QuarterCar-v1', num_envs=2, "
            "vectorization_mode='vector_entry_point', backend='native'); print(type(e).__name__, 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout.split()
    assert out == ["QuarterCarVectorEnv", "False"]


def test_host_drawn_bands_give_each_episode_its_native_draw():
    """The robustness twin's every band (masses, stiffnesses, delays, noise): each environment's episode is the
    native environment built with the draw of the bank's seed it started on (rewards to 1e-9; the sensors' noise
    differs, the rewards do not see it)."""
    from mrd_env.plants.quarter_car.suites import ROBUST_BANDS
    from mrd_env.suites import draw_episode, nominal_values

    opts = {"episode_seconds": 0.2}
    seeds = [11, 12, 13]
    env = jv.JaxVectorEnv("mrd_env/QuarterCar-v1", 2, seeds=seeds, randomise=ROBUST_BANDS, scheme="exact", **opts)
    assert env.params.drawn and env.params.W.shape[0] == 3
    env.reset(seed=5)
    records = np.asarray(env._state.record)
    nominal = nominal_values("mrd_env/QuarterCar-v1", opts)
    natives = []
    for b in records:
        n = gym.make("mrd_env/QuarterCar-v1", **opts, **draw_episode(ROBUST_BANDS, nominal, 0, seeds[b]))
        n.reset(seed=seeds[b])
        natives.append(n)
    rng = np.random.default_rng(0)
    for _ in range(10):
        a = rng.uniform(-1, 1, (2, 1)).astype(np.float32)
        _, r, *_ = env.step(a)
        for i, n in enumerate(natives):
            assert r[i] == pytest.approx(n.step(a[i])[1], rel=1e-9, abs=1e-12)
    with pytest.raises(ValueError, match="seeds, not records"):
        jv.JaxVectorEnv("mrd_env/QuarterCar-v1", 2, records=[iso8608_road("C", 20.0, 0.2, 1e-3, rng=0)],
                        randomise=ROBUST_BANDS, **opts)
