"""Copies of the environments (issue 21, item 1): a pickled, deep-copied or cloudpickled environment steps bit
for bit like its original from any reachable state, scalar and vector, and the two are independent."""
from __future__ import annotations

import copy
import pickle

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.plants.registry import envs as _envs

ENVS = _envs()
from mrd_env.plants.quarter_car.env import DEFAULT_SENSORS

IDS = tuple(ENVS)
SHORT = dict(episode_seconds=0.1, control_dt=0.01)
COPIES = {"pickle": lambda e: pickle.loads(pickle.dumps(e)), "deepcopy": copy.deepcopy,
          "cloudpickle": lambda e: cloudpickle.loads(cloudpickle.dumps(e))}
#: option sets whose state a copy must carry: sensor noise, delay and history; the force mode's inverse (its
#: observer's memory); the preview's record channels; a random disturbance per episode
VARIANTS = {
    "mrd_env/QuarterCarPhysical-v0": [{}, dict(sensor_noise={"travel": 1e-3}, sensor_delay=2, history=3),
                              dict(action_mode="force", inverse="heaviside"), dict(preview=(0.02, 0.05),
                                                              sensors=(*DEFAULT_SENSORS, "road_preview"))],
    "mrd_env/ShearBuildingPhysical-v0": [{}, dict(ground_motion="kanai_tajimi", sensor_noise={"drift": 1e-6}),
                                 dict(action_mode="force", inverse="heaviside", stroke_limit=4e-6)],
    "mrd_env/HalfCarPhysical-v0": [{}, dict(sensor_noise={"damper_force": 5.0}, history=2, stroke_limit=4e-3)],
}
CASES = [(env_id, i) for env_id, variants in VARIANTS.items() for i in range(len(variants))]
PROPERTY = settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _actions(space, seed: int, n: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(space.low, space.high, (n, *space.shape))


def _advance(env, actions) -> None:
    """Steps from wherever ``env`` is; a finished episode restarts at the next action (unseeded), so that the
    state reached may be mid-episode, at an episode's end or just after a reset."""
    done = False
    for a in actions:
        if done:
            env.reset()
        _, _, term, trunc, _ = env.step(a)
        done = term or trunc


def _lockstep(env, twin, actions) -> None:
    """Both step with the same actions, alternately (shared state would show), and agree exactly."""
    done = env.unwrapped._done
    for a in actions:
        if done:
            assert data_equivalence(env.reset(), twin.reset(), exact=True)
        out, out_twin = env.step(a), twin.step(a)
        assert data_equivalence(out, out_twin, exact=True), (out, out_twin)
        done = out[2] or out[3]


@PROPERTY
@given(case=st.sampled_from(CASES), how=st.sampled_from(sorted(COPIES)), before=st.integers(0, 25),
       seed=st.integers(0, 2 ** 16))
def test_a_copied_env_steps_like_its_original(case, how, before, seed):
    env_id, variant = case
    env = gym.make(env_id, **SHORT, **VARIANTS[env_id][variant])
    env.reset(seed=seed)
    acts = _actions(env.action_space, seed, before + 25)
    _advance(env, acts[:before])
    twin = COPIES[how](env)
    _lockstep(env, twin, acts[before:])


@PROPERTY
@given(env_id=st.sampled_from(IDS), how=st.sampled_from(sorted(COPIES)),
       mode=st.sampled_from([AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP]), before=st.integers(0, 25),
       seed=st.integers(0, 2 ** 16))
def test_a_copied_vector_env_steps_like_its_original(env_id, how, mode, before, seed):
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                        sensor_noise={"damper_force": 3.0}, **SHORT)
    venv.reset(seed=seed)
    acts = _actions(venv.action_space, seed, before + 25)
    for a in acts[:before]:
        venv.step(a)
    twin = COPIES[how](venv)
    for a in acts[before:]:
        out, out_twin = venv.step(a), twin.step(a)
        assert data_equivalence(out, out_twin, exact=True), (out, out_twin)


@pytest.mark.parametrize("how", sorted(COPIES))
@pytest.mark.parametrize("env_id", IDS)
def test_a_copy_made_before_reset_and_one_that_renders(env_id, how):
    """A fresh environment copies (and resets as the original with the same seed); so does one that has drawn
    frames (the copy draws its own)."""
    env = gym.make(env_id, render_mode="rgb_array", **SHORT)
    twin = COPIES[how](env)
    assert data_equivalence(env.reset(seed=3), twin.reset(seed=3), exact=True)
    env.step(env.action_space.sample())
    frame = env.render()
    twin = COPIES[how](env)
    np.testing.assert_array_equal(twin.render(), frame)
    _lockstep(env, twin, _actions(env.action_space, 0, 12))


@pytest.mark.parametrize("inverse", ["model", "sid"])
@pytest.mark.parametrize("how", sorted(COPIES))
def test_force_mode_with_an_observer_inverse_copies(inverse, how):
    """The inverses that step a damper model (their compiled one-step module is reloaded, not pickled)."""
    env = gym.make("mrd_env/QuarterCarPhysical-v0", action_mode="force", inverse=inverse, **SHORT)
    env.reset(seed=0)
    env.step([100.0])
    _lockstep(env, COPIES[how](env), _actions(env.action_space, 0, 12))


@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_vector_env_that_renders_copies(how):
    venv = gym.make_vec("mrd_env/HalfCarPhysical-v0", num_envs=2, render_mode="rgb_array", **SHORT)
    venv.reset(seed=0)
    venv.step(venv.action_space.sample())
    frames = venv.render()
    twin = COPIES[how](venv)
    for a, b in zip(frames, twin.render()):
        np.testing.assert_array_equal(a, b)
    a = venv.action_space.sample()
    assert data_equivalence(venv.step(a), twin.step(a), exact=True)


def test_copies_are_independent():
    """Stepping a copy leaves the original where it was (the views of the compiled state are re-bound)."""
    env = gym.make("mrd_env/QuarterCarPhysical-v0", **SHORT)
    env.reset(seed=0)
    obs0 = env.unwrapped._obs0.copy()
    twin = cloudpickle.loads(cloudpickle.dumps(env))
    for _ in range(3):
        obs, *_ = twin.step([2.0])
        assert not np.array_equal(obs, obs0)  # the copy's observation moves (it used to stay frozen)
    np.testing.assert_array_equal(env.unwrapped._obs0, obs0)
    np.testing.assert_array_equal(twin.unwrapped._obs0, obs)
    assert twin.unwrapped._obs0.base is twin.unwrapped.core.obs or twin.unwrapped._obs0.base is \
        twin.unwrapped.core.obs.base
