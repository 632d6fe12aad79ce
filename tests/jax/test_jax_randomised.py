"""Per-episode randomised parameters of the quarter car's JAX twin (:func:`~mrd_env.plants.quarter_car.jax_twin.
draw_params`, issue 41): a batch of draws steps through one compiled function (a new draw compiles nothing), and
one drawn episode is the native environment's built with the same drawn parameters."""
from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import mrd_env  # noqa: E402,F401
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.plants.quarter_car import jax_twin as qc  # noqa: E402
from mrd_env.plants.quarter_car.suites import ROBUST_BANDS  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
BANDS = {k: ROBUST_BANDS[k] for k in ("damper_params",)} | {"command": {"eta": ROBUST_BANDS["command"]["eta"]}}


def test_draws_do_not_recompile_and_match_the_native_env():
    rec = iso8608_road("D", 20.0, 0.05, 1e-3, rng=4, method="fft")
    params = qc.make_params(roads=[rec], episode_seconds=0.05, scheme="exact")
    draw = jax.jit(jax.vmap(lambda k: qc.draw_params(k, params, BANDS)))
    _, s0 = qc.reset(None, params, record=0)
    roll = jax.jit(jax.vmap(qc.rollout, in_axes=(0, None, None)))
    actions = jnp.asarray(np.random.default_rng(1).uniform(-1, 1, (params.n_steps, 1)).astype(np.float32), jnp.float64)
    batches = [draw(jax.random.split(jax.random.PRNGKey(s), 3)) for s in (0, 1)]
    rewards = [np.asarray(roll(b, s0, actions)[2]) for b in batches]
    assert roll._cache_size() == 1 and draw._cache_size() == 1  # the second draw compiled nothing
    assert not np.allclose(rewards[0], rewards[1], rtol=1e-6)  # and it changed the episodes
    one = jax.tree_util.tree_map(lambda x: x[2], batches[1])
    opts = qc.drawn_options(one, params)
    assert len(opts["damper_params"]) == 7 and 0.7 * 190 <= opts["damper_params"]["command"]["eta"] <= 1.3 * 190
    env = gym.make("mrd_env/QuarterCar-v1", road=rec, episode_seconds=0.05, **opts)
    env.reset(seed=0)
    native = [env.step(np.asarray(a, np.float32))[1] for a in np.asarray(actions)]
    np.testing.assert_allclose(rewards[1][2], native, rtol=1e-9, atol=1e-15)


def test_bands_it_cannot_draw_are_refused_by_name():
    params = qc.make_params(n_roads=1, episode_seconds=0.05)
    with pytest.raises(ValueError, match="plant_params"):
        qc.draw_params(jax.random.PRNGKey(0), params, {"plant_params": {"m_s": (0.9, 1.1)}})
    with pytest.raises(ValueError, match="command.delay"):
        qc.draw_params(jax.random.PRNGKey(0), params, {"command": {"delay": (0.0, 0.005)}})
    with pytest.raises(ValueError, match="zeta"):
        qc.draw_params(jax.random.PRNGKey(0), params, {"damper_params": {"zeta": (0.9, 1.1)}})
