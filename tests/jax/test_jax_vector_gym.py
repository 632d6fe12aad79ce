"""The JAX vector environment (:mod:`mrd_env.jax.vector`) under Gymnasium's own vector tooling (issue 49, item 8):
its arrays are writable NumPy arrays that Gymnasium's vector wrappers modify in place, its ``np_random_seed`` is
what the native vector environment and ``SyncVectorEnv`` give, its default scheme is the fast one, and Gymnasium's
vector-environment tests (``tests/envs/test_gym_conformance.py`` for the native backend) adapted to it for one id.
Two environments, episodes of 5 steps: the programs compiled are those of ``test_jax_vector.py``."""
from __future__ import annotations

import copy

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
from gymnasium.utils.env_checker import data_equivalence  # noqa: E402
from gymnasium.wrappers import vector as vw  # noqa: E402

import mrd_env  # noqa: E402,F401
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.plants.quarter_car.suites import ROBUST_BANDS  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")

ID = "mrd_env/QuarterCar-v1"
ROAD = iso8608_road("D", 20.0, 0.06, 1e-3, rng=7, method="fft")
#: test_jax_vector.py's quarter car (its compiled programs reused): 5 steps, costs, a stroke-limit end
OPTS = dict(road=ROAD, episode_seconds=0.05, soft_stroke_limit=2e-3, stroke_limit=4e-3)
#: the bands the JAX environment draws in its step: each environment's damper then depends on its key
BANDS = {"damper_params": ROBUST_BANDS["damper_params"], "command": {"eta": ROBUST_BANDS["command"]["eta"]}}


def _jax(num_envs=2, **kw):
    return gym.make_vec(ID, num_envs=num_envs, vectorization_mode="vector_entry_point", backend="jax", **OPTS, **kw)


def _arrays(out, path="out"):
    """Every NumPy array in a step's or reset's output (infos and their nested dicts included), with its path."""
    if isinstance(out, np.ndarray):
        yield path, out
    elif isinstance(out, dict):
        for k, v in out.items():
            yield from _arrays(v, f"{path}[{k!r}]")
    elif isinstance(out, tuple):
        for i, v in enumerate(out):
            yield from _arrays(v, f"{path}[{i}]")


def _assert_writable(out):
    read_only = [p for p, a in _arrays(out) if not a.flags.writeable]
    assert not read_only, read_only


def test_arrays_are_writable_and_gymnasiums_vector_wrappers_run_through_autoresets():
    """Observations, rewards, flags and every info array are writable NumPy arrays (not views of JAX's), so that
    Gymnasium's vector wrappers that write in place (ClipReward) run; RecordEpisodeStatistics counts the episodes
    through NEXT_STEP autoresets, NormalizeReward and NormalizeObservation keep finite statistics."""
    env = _jax()
    out = env.reset(seed=0)
    _assert_writable(out)
    a = np.random.default_rng(0).uniform(-1, 1, (2 * env.max_episode_steps + 2, *env.action_space.shape))
    for act in a[:3]:
        _assert_writable(env.step(act))
    lo, hi = -1e-3, 1e-3
    wrapped = vw.NormalizeObservation(vw.NormalizeReward(vw.RecordEpisodeStatistics(vw.ClipReward(_jax(), lo, hi))))
    wrapped.reset(seed=0)
    lengths = []
    for act in a:
        obs, r, term, trunc, info = wrapped.step(act)
        assert np.isfinite(obs).all() and np.isfinite(r).all()
        if "episode" in info:
            lengths += list(info["episode"]["l"][info["_episode"]])
    assert len(lengths) >= 2 and all(0 < n <= env.max_episode_steps for n in lengths), lengths
    clipped = vw.RecordEpisodeStatistics(vw.ClipReward(_jax(), lo, hi))
    clipped.reset(seed=0)
    for act in a:
        _, r, *_ = clipped.step(act)
        assert np.all((r >= lo) & (r <= hi))
    assert clipped.episode_count >= 2 and all(lo * n <= ret <= hi * n for ret, n in
                                              zip(clipped.return_queue, clipped.length_queue))


def _seeds(env):
    return env.unwrapped.np_random_seed


def test_np_random_seed_is_the_native_vector_envs_and_sync_vector_envs():
    """reset(seed=s) seeds environment i with s + i, reset() keeps the seeds, a reset mask or a list of seeds
    (None: kept) reseeds only those environments — the values and types SyncVectorEnv and the native vector
    environment give; environment i of a reset with seed s is environment 0 of a reset with seed s + i."""
    envs = {"jax": _jax(randomise=BANDS),
            "native": gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", **OPTS),
            "sync": gym.make_vec(ID, num_envs=2, vectorization_mode="sync", **OPTS)}
    calls = [dict(seed=42), dict(), dict(seed=7, options={"reset_mask": np.array([False, True])}),
             dict(seed=[3, None])]
    for call in calls:
        got = {k: (e.reset(**copy.deepcopy(call)), _seeds(e))[1] for k, e in envs.items()}
        assert got["jax"] == got["native"] == got["sync"], (call, got)
        assert all(type(s) is int for s in got["jax"])
    fresh = _jax(randomise=BANDS)
    fresh.reset()  # no seed: one drawn per environment, an int that replays the environment when given back
    drawn = _seeds(fresh)
    assert len(set(drawn)) == 2 and all(type(s) is int and s >= 0 for s in drawn)
    again = _jax(randomise=BANDS)
    again.reset(seed=list(drawn))
    assert np.array_equal(np.asarray(again.unwrapped._P), np.asarray(fresh.unwrapped._P))
    a, b = _jax(randomise=BANDS), _jax(randomise=BANDS)
    a.reset(seed=5)
    b.reset(seed=6)
    assert np.array_equal(np.asarray(a.unwrapped._P)[1], np.asarray(b.unwrapped._P)[0])
    for act in np.random.default_rng(1).uniform(-1, 1, (8, *a.action_space.shape)):
        oa, ra, *_ = a.step(act)
        ob, rb, *_ = b.step(act[::-1])  # b's environment 0 gets a's environment 1's action
        assert np.array_equal(oa[1], ob[0]) and ra[1] == rb[0]
    with pytest.raises(ValueError, match="seed"):
        a.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match="seed"):
        a.reset(seed=[1, -2])


def test_the_default_scheme_is_the_differentiable_one():
    """make_vec(..., backend="jax") without a scheme steps as scheme="differentiable" (the fast scheme, bit for
    bit); scheme="exact" (the native environment's numbers) is a keyword away and steps differently."""
    envs = [_jax(), _jax(scheme="differentiable"), _jax(scheme="exact")]
    runs = []
    for env in envs:
        env.reset(seed=0)
        actions = np.random.default_rng(2).uniform(-1, 1, (6, *env.action_space.shape))
        runs.append([env.step(a)[:4] for a in actions])
    assert envs[0].unwrapped.params.scheme == envs[1].unwrapped.params.scheme != envs[2].unwrapped.params.scheme
    assert data_equivalence(runs[0], runs[1], exact=True)
    assert not data_equivalence(runs[0], runs[2], exact=True)


# Gymnasium's vector-environment tests (tests/vector), as tests/envs/test_gym_conformance.py writes them for the
# native backend, for the JAX backend (NEXT_STEP, its only autoreset mode)

def test_autoreset_next_step():
    """The step after an episode ends returns the next episode's first observation (the reset's, same seed),
    reward 0, both flags false, t = 0 and the disturbance's name."""
    env = _jax()
    first, _ = env.reset(seed=4)
    a = np.zeros(env.action_space.shape)
    for _ in range(env.max_episode_steps):  # (both environments alike: one road, one action)
        _, r, term, trunc, info = env.step(a)
        if (term | trunc).any():
            break
    assert (term | trunc).all()
    obs, r, term, trunc, info = env.step(a)
    assert np.all(r == 0.0) and not (term | trunc).any() and np.all(info["t"] == 0.0) and info["_disturbance"].all()
    assert obs in env.observation_space and np.allclose(obs, first, rtol=1e-6, atol=0)  # one road: one start


def test_partial_reset_and_spaces():
    """A reset mask restarts only the masked environments (as with their seeds), the others go on as if nothing
    happened; observations lie in the observation space; a deep copy steps as its original."""
    env = _jax(num_envs=2, randomise=BANDS)
    initial, _ = env.reset(seed=[0, 1])
    assert initial in env.observation_space
    P0 = np.asarray(env.unwrapped._P)
    env.action_space.seed(123)
    for _ in range(3):
        step_obs, *_ = env.step(env.action_space.sample())
    assert step_obs in env.observation_space
    untouched = copy.deepcopy(env)
    obs, info = env.reset(seed=[0, 5], options={"reset_mask": np.array([True, False])})
    np.testing.assert_array_equal(obs[0], initial[0])
    np.testing.assert_array_equal(np.asarray(env.unwrapped._P)[0], P0[0])
    np.testing.assert_array_equal(obs[1], step_obs[1])
    np.testing.assert_array_equal(info["_t"], [True, False])
    assert _seeds(env) == (0, 1)
    a = env.action_space.sample()
    np.testing.assert_array_equal(env.step(a)[0][1], untouched.step(a)[0][1])
