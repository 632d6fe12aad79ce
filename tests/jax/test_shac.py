"""SHAC, the agent trained through the JAX twin (issue 41, item 3b): the twin's road-preview observation against the
native sensor, the short-horizon loss's gradient against finite differences, a tiny training run's determinism and
the saved agent acting as the trained JAX policy."""
from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import mrd_env  # noqa: E402,F401
import mrd_env.jax  # noqa: E402,F401  (float64)
from experiments.common import shac  # noqa: E402
from experiments.common.plants import profile  # noqa: E402
from experiments.common.scenarios import preview_options  # noqa: E402
from experiments.common.trainers import env_options  # noqa: E402
from mrd_env.plants.quarter_car import jax_twin as qc  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
CAR = profile("quarter_car")
TINY = {"n_envs": 2, "horizon": 5, "critic_warmup": 1, "critic_iterations": 2, "critic_minibatches": 2,
        "critic_hidden": [8], "actor_lr": 1e-2}


def test_preview_observation_is_the_native_sensor():
    """A training road drawn as the native environment draws it at reset(seed=s), then 25 random actions: the
    twin's road_preview equals the native record's preview channels (float64) exactly, and the whole observation
    (exact scheme) rounds to the native float32 observation."""
    kw = preview_options(CAR, env_options(CAR))
    env = gym.make(CAR.env_id, **{**kw, "episode_seconds": 0.3})
    seed = 4242
    params = qc.make_params(roads=qc.native_roads(kw["road"], [seed], episode_seconds=0.3), episode_seconds=0.3,
                            preview=kw["preview"])
    assert params.W.shape[2] == 2 + 10 + 1  # z_r, ż_r, the road at 10 times ahead, the preload's constant
    env.reset(seed=seed)
    rec = env.unwrapped.record
    o_j, state = qc.reset(None, params, record=0)
    step = jax.jit(qc.step)
    rng = np.random.default_rng(0)
    for k in range(1, 26):
        a = np.float32(rng.uniform(-1, 1))
        o_n, *_ = env.step(np.asarray([a]))
        o_j, state, *_ = step(None, state, a, params)
        o_j = np.asarray(o_j)
        assert o_j.shape == (18,)
        assert np.max(np.abs(o_j[8:] - rec.data[k * 10, 2:])) < 1e-12  # the sensor reads the record ahead
        np.testing.assert_allclose(o_j.astype(np.float32), o_n, rtol=1e-6, atol=1e-9)
    # the inputs, preview channels included, are the native episode's record (with_preview's rows ahead)
    rows = params.n_steps * params.n_sub + 1
    assert np.array_equal(np.asarray(params.W[0, :rows, :-1]), rec.data[:rows])
    env.close()


def test_native_roads_are_the_training_mixture():
    """Seeds draw the classes and speeds of the training option (B–D at 10–30 m/s), the same for the same seed."""
    road = CAR.training["road"]
    a, b = qc.native_roads(road, [1, 2, 3], episode_seconds=2.0), qc.native_roads(road, [1], episode_seconds=2.0)
    assert np.array_equal(a[0].data, b[0].data) and not np.array_equal(a[0].data, a[1].data)
    assert all(r.dt == 1e-3 and r.channels == ("z_r", "zdot_r") for r in a)


@pytest.fixture(scope="module")
def tiny():
    """The tiny set-up the training test also uses (one compilation): the no-preview car on 2 roads of 0.2 s."""
    h = shac.check(TINY)
    kw = {**env_options(CAR), "episode_seconds": 0.2}
    folder, agent = shac.warm_start_agent("cmaes", CAR, kw)
    params = shac.twin_params(qc, kw, [3, 4], h)
    n = agent.normalizer
    sizes = agent.model.sizes
    setup = shac.setup_for(qc, params, sizes, (sizes[0] + 1, 8, 1), (n.mean, n.scale, n.clip), h)
    return setup, params, agent, kw, h


@pytest.mark.slow
def test_short_horizon_gradient_matches_finite_differences(tiny):
    """d/dθ of a window's loss (5 control steps through the differentiable scheme, the critic at the end) along
    random directions, against fourth-order central differences."""
    setup, params, agent, _, _ = tiny
    obs, states = setup.start(params)
    theta = jnp.asarray(agent.model.theta)
    phi = shac._init_critic(jax.random.PRNGKey(0), setup.critic_sizes)
    grad = jax.jit(jax.grad(lambda th: setup.loss(th, phi, states, obs, params)[0]))
    g = np.asarray(grad(theta))
    assert np.linalg.norm(g) > 0
    rng = np.random.default_rng(1)
    h = 1e-4
    for _ in range(2):
        d = rng.standard_normal(theta.shape)
        d /= np.linalg.norm(d)
        f = [float(setup.loss(theta + k * h * d, phi, states, obs, params)[0]) for k in (-2, -1, 1, 2)]
        fd = (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h)
        assert g @ d == pytest.approx(fd, rel=1e-6, abs=1e-6 * np.linalg.norm(g))


@pytest.mark.slow
def test_tiny_training_is_reproducible_and_saves_the_trained_policy(tiny, tmp_path):
    """Two runs of one seed give the same weights bit for bit, another seed other weights; the weights moved from
    the warm start; the saved agent (controllers.load_agent: NumPy network and normalisation) acts as the JAX policy
    the trainer differentiated."""
    from controllers import load_agent

    setup, params, agent, kw, h = tiny

    def run(seed, name):
        return shac.train_shac(CAR, "shac", seed, out=tmp_path / name, timesteps=20, hyper=TINY, env_kwargs=kw,
                               eval_freq=0)

    a, b, c = run(0, "a"), run(0, "b"), run(1, "c")
    ta, tb, tc = (load_agent(f).model.theta for f in (a, b, c))
    assert np.array_equal(ta, tb) and not np.array_equal(ta, tc)
    assert not np.array_equal(ta, agent.model.theta)
    saved = load_agent(a)
    assert saved.meta["algo"] == "SHAC" and saved.meta["plant"] == "quarter_car"
    obs = np.random.default_rng(2).normal(agent.normalizer.mean, 3 * agent.normalizer.scale, (16, 8))
    n = saved.normalizer
    want = np.asarray(shac.mlp(jnp.asarray(ta), setup.sizes, jnp.clip((obs - n.mean) / n.scale, -n.clip, n.clip)))
    got = np.stack([saved.predict(o)[0] for o in obs.astype(np.float32)])
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


def test_bad_hyperparameters_are_named():
    with pytest.raises(ValueError, match="horizon"):
        shac.check({"horizon": 0})
    with pytest.raises(ValueError, match="gamma"):
        shac.check({"gamma": 1.5})
    with pytest.raises(ValueError, match="not SHAC options"):
        shac.check({"popsize": 4})
    with pytest.raises(ValueError, match="twin"):
        shac.twin_params(qc, {**env_options(CAR), "sensor_noise": {"travel": 1e-3}}, [0], shac.check({}))
    with pytest.raises(ValueError, match="twin"):
        shac.twin_of(profile("shear_building"))
