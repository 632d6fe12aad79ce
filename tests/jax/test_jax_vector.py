"""The Gymnasium vector environment over the JAX step against the native vector environment (issue 41)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402

import mrd_env  # noqa: E402,F401
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.plants.quarter_car.jax_vector import QuarterCarJaxVectorEnv  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")


def test_matches_the_native_vector_env_through_an_autoreset():
    """One road, 2 cars, 5-step episodes, 12 steps: observations, rewards, flags and the NEXT_STEP autoreset; the
    JAX one made by make_vec with backend="jax" (the RL id's options: 10 ms, normalised actions)."""
    rec = iso8608_road("D", 20.0, 0.05, 1e-3, rng=7, method="fft")
    native = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=2, vectorization_mode="vector_entry_point", road=rec)
    twin = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=2, vectorization_mode="vector_entry_point", road=rec,
                        episode_seconds=0.05, backend="jax")
    assert isinstance(twin, QuarterCarJaxVectorEnv) and twin.control_dt == pytest.approx(0.01)
    assert twin.observation_space == native.observation_space and twin.action_space == native.action_space
    o_n, _ = native.reset(seed=0)
    o_j, _ = twin.reset(seed=0)
    np.testing.assert_allclose(o_j, o_n, rtol=1e-6, atol=1e-9)
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(12):
        a = rng.uniform(-1, 1, (2, 1)).astype(np.float32)
        o_n, r_n, te_n, tr_n, _ = native.step(a)
        o_j, r_j, te_j, tr_j, info = twin.step(a)
        np.testing.assert_allclose(o_j, o_n, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(r_j, r_n, rtol=1e-9, atol=1e-15)
        assert np.array_equal(te_j, te_n) and np.array_equal(tr_j, tr_n)
        ends += int(tr_n.sum())
    assert ends == 4  # two episodes of each car ended (steps 5 and 11), each followed by its reset step
    native.close()


def test_bad_actions_are_refused_and_change_nothing():
    rec = iso8608_road("C", 20.0, 0.05, 1e-3, rng=1, method="fft")
    twin = QuarterCarJaxVectorEnv(2, roads=[rec], episode_seconds=0.05)
    twin.reset(seed=0)
    before = twin._state  # (the JAX arrays are immutable: a refused step must leave the same object)
    with pytest.raises(ValueError, match="actions"):
        twin.step(np.array([[0.0], [np.nan]]))
    assert twin._state is before and not twin._restart.any()
    with pytest.raises(ValueError, match="num_envs"):
        QuarterCarJaxVectorEnv(0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        QuarterCarJaxVectorEnv(1, autoreset_mode="same_step")


def test_make_vec_backends():
    """The physics-level id's JAX environment has the native one's defaults (1 ms, physical commands); an unknown
    backend is refused by name; the native backend does not import JAX (a subprocess: this one has)."""
    import subprocess
    import sys

    rec = iso8608_road("C", 20.0, 0.02, 1e-3, rng=2, method="fft")
    env = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=1, vectorization_mode="vector_entry_point",
                       backend="jax", road=rec, episode_seconds=0.02)
    assert env.control_dt == pytest.approx(1e-3) and env.single_action_space.high[0] > 1.0
    with pytest.raises(ValueError, match="backend"):
        gym.make_vec("mrd_env/QuarterCar-v1", num_envs=1, vectorization_mode="vector_entry_point", backend="torch")
    code = ("import sys, gymnasium as gym, mrd_env; e = gym.make_vec('mrd_env/QuarterCar-v1', num_envs=2, "
            "vectorization_mode='vector_entry_point', backend='native'); print(type(e).__name__, 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout.split()
    assert out == ["QuarterCarVectorEnv", "False"]
    with pytest.raises(ValueError, match="not available"):  # a plant without a JAX twin
        gym.make_vec("mrd_env/ShearBuildingPhysical-v0", num_envs=1, vectorization_mode="vector_entry_point",
                     backend="jax")
