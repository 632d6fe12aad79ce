"""SHAC, the agent trained through a plant's JAX twin (:mod:`mrd_env.jax.env`): the training bank against the
native episodes (inputs, road-preview observation), the short-horizon loss's gradient against finite differences,
noisy sensors' keys, a tiny training run's determinism and the saved agent acting as the trained JAX policy, on the
quarter car and on the shear building."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import mrd_env  # noqa: E402,F401
import mrd_env.jax  # noqa: E402,F401  (float64)
from experiments.training import shac  # noqa: E402
from experiments.common.plants import profile  # noqa: E402
from experiments.common.scenarios import preview_options  # noqa: E402
from experiments.training.trainers import env_options  # noqa: E402
from mrd_env.jax import env as je  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
CAR = profile("quarter_car")
BUILDING = profile("shear_building")
TINY = {"n_envs": 2, "horizon": 5, "critic_warmup": 1, "critic_iterations": 2, "critic_minibatches": 2,
        "critic_hidden": [8], "actor_lr": 1e-2}


def test_preview_observation_is_the_native_sensor():
    """A training road drawn as the native environment draws it at reset(seed=s), then 25 random actions: the
    twin's road_preview equals the native record's preview channels (float64) exactly, and the whole observation
    (the exact scheme) rounds to the native float32 observation."""
    kw = {**preview_options(CAR, env_options(CAR)), "episode_seconds": 0.3}
    env = gym.make(CAR.env_id, **kw)
    seed = 4242
    params = shac.twin_params(CAR, kw, [seed], shac.check({}))
    assert params.scheme == "differentiable" and params.W.shape[2] == 2 + 10 + 1  # z_r, ż_r, 10 ahead, constant
    env.reset(seed=seed)
    rec = env.unwrapped.record
    rows = params.n_steps * params.n_sub + 1
    assert np.array_equal(np.asarray(params.W[0, :rows, :-1]), rec.data[:rows])  # preview channels included
    params = dataclasses.replace(params, scheme="exact")
    o_j, state = je.reset(None, params, record=0)
    step = jax.jit(je.step)
    rng = np.random.default_rng(0)
    for k in range(1, 26):
        a = np.float32(rng.uniform(-1, 1))
        o_n, *_ = env.step(np.asarray([a]))
        o_j, state, *_ = step(None, state, a, params)
        o_j = np.asarray(o_j)
        assert o_j.shape == (18,)
        assert np.max(np.abs(o_j[8:] - rec.data[k * 10, 2:])) < 1e-12  # the sensor reads the record ahead
        np.testing.assert_allclose(o_j.astype(np.float32), o_n, rtol=1e-6, atol=1e-9)
    env.close()


def test_training_bank_is_the_native_episodes_padded():
    """The building's bank: each seed's ground motion is the one the native environment meets at reset(seed=s)
    (records of several lengths: each keeps its own episode length); padded to a longer bank, the last input row
    is held and nothing else changes."""
    kw = env_options(BUILDING)
    h = shac.check({})
    seeds = [int(s) for s in np.random.default_rng(5).integers(0, 10_000, 6)]
    params = shac.twin_params(BUILDING, kw, seeds, h)
    env = gym.make(BUILDING.env_id, **kw)
    lengths = set()
    for b, s in enumerate(seeds):
        env.reset(seed=s)
        rec = env.unwrapped.record
        n = int(params.steps[b])
        lengths.add(n)
        rows = n * params.n_sub + 1
        assert np.array_equal(np.asarray(params.W[b, :rows, :-1]), rec.data[:rows])
    env.close()
    assert len(lengths) > 1 and params.n_steps == max(lengths)
    longer = shac.twin_params(BUILDING, kw, seeds, h, n_steps=params.n_steps + 7)
    assert longer.n_steps == params.n_steps + 7 and np.array_equal(np.asarray(longer.steps), np.asarray(params.steps))
    W, W2 = np.asarray(params.W), np.asarray(longer.W)
    assert np.array_equal(W2[:, :W.shape[1]], W) and np.all(W2[:, W.shape[1]:] == W[:, -1:])


@pytest.fixture(scope="module")
def tiny():
    """The tiny set-up the training test also uses (one compilation): the no-preview car on 2 roads of 0.2 s."""
    h = shac.check(TINY)
    kw = {**env_options(CAR), "episode_seconds": 0.2}
    folder, agent = shac.warm_start_agent("cmaes", CAR, kw)
    params = shac.twin_params(CAR, kw, [3, 4], h)
    n = agent.normalizer
    sizes = agent.model.sizes
    setup = shac.setup_for(sizes, (sizes[0] + 1, 8, 1), (n.mean, n.scale, n.clip), h)
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


@pytest.mark.slow
def test_warm_up_moves_nothing_then_adam_takes_its_first_step(tiny):
    """The actor's optax Adam: a window at learning rate 0 (the critic's warm-up) leaves the weights and the whole
    optimiser state (moments, step count) as they were; the next window at lr is Adam's first step, which moves
    every weight with a non-negligible gradient by lr × |ĝ|/(|ĝ| + ε) ≈ lr (a count advanced by the warm-up would
    give about 0.74 lr)."""
    setup, params, agent, _, _ = tiny
    obs, states = setup.start(params)
    theta = jnp.asarray(agent.model.theta)
    phi = shac._init_critic(jax.random.PRNGKey(0), setup.critic_sizes)
    opt0 = setup.actor_opt.init(theta)
    th, opt, *_ = setup.actor_update(theta, opt0, 0.0, phi, states, obs, params)
    assert np.array_equal(np.asarray(th), np.asarray(theta))
    for x, y in zip(jax.tree_util.tree_leaves(opt), jax.tree_util.tree_leaves(opt0)):
        np.testing.assert_array_equal(x, y)
    lr = 1e-3
    th, opt, _, gnorm, *_ = setup.actor_update(theta, opt, lr, phi, states, obs, params)
    g = np.asarray(jax.grad(lambda t: setup.loss(t, phi, states, obs, params)[0])(theta))
    assert float(gnorm) == pytest.approx(np.linalg.norm(g), rel=1e-12)
    ghat = g * min(1.0, setup.h["grad_clip"] / np.linalg.norm(g))
    step = theta - np.asarray(th)
    np.testing.assert_allclose(step, lr * ghat / (np.abs(ghat) + 1e-8), rtol=1e-9, atol=1e-18)
    big = np.abs(ghat) > 1e-4
    assert big.sum() > 10 and np.allclose(np.abs(step[big]), lr, rtol=1e-3)


def test_noisy_sensors_draw_their_noise_from_the_key(tiny):
    """With sensor_noise the twin's observations are noisy: the window's loss needs a key, is the same for the same
    key and differs for another; without noise the loss is the noise-free one whatever the key."""
    setup, params, agent, kw, h = tiny
    noisy = shac.twin_params(CAR, {**kw, "sensor_noise": {"travel": 1e-3}}, [3, 4], h)
    assert noisy.noisy and not params.noisy
    theta = jnp.asarray(agent.model.theta)
    phi = shac._init_critic(jax.random.PRNGKey(0), setup.critic_sizes)
    k1, k2 = jax.random.split(jax.random.PRNGKey(7))
    obs, states = setup.start(noisy, k1)
    loss = [float(setup.loss(theta, phi, states, obs, noisy, k)[0]) for k in (k1, k1, k2)]
    assert loss[0] == loss[1] and loss[0] != loss[2]
    with pytest.raises(ValueError, match="key"):
        setup.loss(theta, phi, states, obs, noisy)


@pytest.mark.slow
def test_tiny_building_training_saves_an_agent_that_acts_in_the_native_env(tmp_path):
    """SHAC on the shear building (the RL set-up, 0.2 s episodes) from its shipped CMA-ES agent: the weights move;
    the saved agent loads (controllers.load_agent) and acts in the native environment as the JAX policy the trainer
    differentiated, the episode running to its end."""
    from controllers import load_agent

    kw = {**env_options(BUILDING), "episode_seconds": 0.2}
    folder = shac.train_shac(BUILDING, "shac", 0, out=tmp_path, timesteps=40, hyper=TINY, env_kwargs=kw, eval_freq=0)
    saved = load_agent(folder)
    start = load_agent(saved.meta["hyperparameters"]["warm_start"])
    assert saved.meta["algo"] == "SHAC" and saved.meta["plant"] == "shear_building"
    assert start.meta["plant"] == "shear_building" and saved.model.sizes == start.model.sizes
    assert not np.array_equal(saved.model.theta, start.model.theta)
    env = gym.make(saved.env_id, **saved.env_kwargs)
    obs, _ = env.reset(seed=123_456)
    n = saved.normalizer
    steps, done = 0, False
    while not done:
        action = saved.predict(obs)[0]
        want = shac.mlp(jnp.asarray(saved.model.theta), saved.model.sizes,
                        jnp.clip((obs - n.mean) / n.scale, -n.clip, n.clip))
        np.testing.assert_allclose(action, np.asarray(want), rtol=1e-5, atol=1e-6)
        obs, reward, terminated, truncated, _ = env.step(action)
        assert np.isfinite(reward)
        done, steps = terminated or truncated, steps + 1
    env.close()
    assert steps == 20 and truncated


def test_bad_hyperparameters_are_named():
    with pytest.raises(ValueError, match="horizon"):
        shac.check({"horizon": 0})
    with pytest.raises(ValueError, match="gamma"):
        shac.check({"gamma": 1.5})
    with pytest.raises(ValueError, match="not SHAC options"):
        shac.check({"popsize": 4})
    with pytest.raises(ValueError, match="action_mode"):  # the twin's refusal, as it words it
        shac.twin_params(CAR, {**env_options(CAR), "action_mode": "force"}, [0], shac.check({}))
