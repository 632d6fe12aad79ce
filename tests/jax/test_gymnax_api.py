"""The JAX environment as gymnax users hold it (:mod:`mrd_env.jax.gymnax`): gymnax's methods and signatures over the
twin's own functions (the same numbers bit for bit, the auto-reset's key split as gymnax's), its spaces, and
PureJaxRL's single-file PPO (``experiments.training.purejaxrl_ppo``, the example of ``docs/jax.md``) running on it
unchanged inside one jit."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("optax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from mrd_env.jax import env as je  # noqa: E402
from mrd_env.jax import make_gymnax  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
#: 5-step episodes (0.05 s) on 2 roads: a few steps hold ends and auto-resets.
OPTIONS = {"episode_seconds": 0.05, "seeds": range(2)}


@pytest.fixture(scope="module")
def env():
    return make_gymnax("mrd_env/QuarterCar-v1", **OPTIONS)


def test_attributes_and_spaces(env):
    p = env.default_params
    assert env.name == "mrd_env/QuarterCar-v1" and env.num_actions == 1
    assert p.scheme == "differentiable" and p.W.shape[0] == 2  # the vector environment's default scheme
    a_space, o_space = env.action_space(p), env.observation_space(p)
    assert a_space.shape == (1,) and float(a_space.low[0]) == -1.0 and float(a_space.high[0]) == 1.0
    assert o_space.shape == (8,) and np.all(np.isinf(o_space.low))
    keys = jax.random.split(jax.random.PRNGKey(0), 64)
    a = jax.vmap(a_space.sample)(keys)
    assert a.shape == (64, 1) and bool(jnp.all(a >= -1)) and bool(jnp.all(a <= 1)) and float(jnp.std(a)) > 0.3
    assert bool(a_space.contains(a[0])) and not bool(a_space.contains(jnp.asarray([1.5])))
    o = jax.vmap(o_space.sample)(keys)
    assert o.shape == (64, 8) and bool(jnp.all(jnp.isfinite(o)))
    physical = make_gymnax("mrd_env/QuarterCar-v1", action_mode="physical", **OPTIONS)
    box = physical.action_space()
    assert float(box.low[0]) == pytest.approx(physical.default_params.v_min)
    assert float(box.high[0]) == pytest.approx(physical.default_params.v_max) and box.high[0] > 1.0


def test_methods_are_the_twins_functions(env):
    """reset, step (auto-reset), reset_env and step_env against mrd_env.jax.env's functions, bit for bit, through
    an episode's end: done = terminated | truncated, the returned state the next episode's, the key split as
    gymnax's (step's part, reset's part)."""
    p = env.default_params

    @jax.jit
    def both(key, state, action):
        return (env.step(key, state, action, p), je.step_autoreset(key, state, action, p),
                env.step_env(key, state, action), je.step(key, state, action, p))

    obs, state = env.reset(jax.random.PRNGKey(1))
    obs_j, state_j = je.reset(jax.random.PRNGKey(1), p)
    assert obs.shape == env.observation_space(p).shape
    np.testing.assert_array_equal(obs, obs_j)
    key = jax.random.PRNGKey(2)
    ends = 0
    for k in range(7):
        key, sub = jax.random.split(key)
        a = jnp.asarray([0.5 * np.sin(k)])
        (o, s, r, d, info), (o2, s2, r2, term, trunc, _), (oe, se, re, de, _), (o3, s3, r3, _, _, _) = both(
            sub, state, a)
        for x, y in zip(jax.tree_util.tree_leaves((o, s, r)), jax.tree_util.tree_leaves((o2, s2, r2))):
            np.testing.assert_array_equal(x, y)
        for x, y in zip(jax.tree_util.tree_leaves((oe, se, re)), jax.tree_util.tree_leaves((o3, s3, r3))):
            np.testing.assert_array_equal(x, y)
        assert bool(d) == bool(term | trunc) == bool(de)
        assert bool(info["terminated"]) == bool(term) and bool(info["truncated"]) == bool(trunc)
        assert float(info["discount"]) == (0.0 if term else 1.0)
        if d:
            ends += 1
            assert int(s.k) == 0 and int(se.k) == 5  # the next episode's first state; step_env's the ended one's
            np.testing.assert_array_equal(info["final_observation"], oe)
        state = s
    assert ends == 1  # a 5-step episode ends once in 7 steps


def test_bad_option_is_named():
    with pytest.raises(ValueError, match="episode_seconds"):
        make_gymnax("mrd_env/QuarterCar-v1", episode_seconds=-1.0, seeds=range(1))
    with pytest.raises(ValueError, match="scheme"):
        make_gymnax("mrd_env/QuarterCar-v1", scheme="rk4", seeds=range(1))


def test_purejaxrl_ppo_runs_unchanged_on_it():
    """PureJaxRL's PPO, environment reached only through gymnax's methods: a handful of updates in one jit with
    N = 4; the metrics' shapes, every loss finite, episodes ended and logged, the critic learning (its loss falls),
    the policy's weights moved."""
    from experiments.training import purejaxrl_ppo as pp

    cfg = {**pp.CONFIG, "NUM_ENVS": 4, "NUM_STEPS": 8, "TOTAL_TIMESTEPS": 4 * 8 * 6, "UPDATE_EPOCHS": 2,
           "NUM_MINIBATCHES": 2, "ENV_KWARGS": OPTIONS}
    out = jax.device_get(jax.jit(pp.make_train(cfg))(jax.random.PRNGKey(0)))
    m = out["metrics"]
    assert m["total_loss"].shape == (6, 2, 2) and m["returned_episode"].shape == (6, 8, 4)
    assert np.all(np.isfinite(m["total_loss"])) and np.all(np.isfinite(m["value_loss"]))
    assert m["value_loss"][-1].mean() < 0.5 * m["value_loss"][0].mean()
    returns = pp.episode_returns(m)
    assert returns.shape == (6,) and np.all(np.isfinite(returns)) and np.all(returns < 0)
    lengths = m["returned_episode_lengths"][m["returned_episode"]]
    assert lengths.size >= 6 * 4 and np.all(lengths == 5)  # every 5-step episode logged at its end
    params = out["runner_state"][0]
    init = pp.network_init(jax.random.split(jax.random.PRNGKey(0))[1], 8, 1)
    assert not np.array_equal(params["actor"][0]["kernel"], init["actor"][0]["kernel"])
