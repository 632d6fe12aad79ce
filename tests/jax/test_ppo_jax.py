"""PPO inside one jit on the JAX quarter car (``experiments.training.ppo_jax``, issue 41 item 3c): reproducible
per seed, finite losses, the optimiser (optax's Adam, annealed per update, clipped), GAE against a plain reference,
the saved agent acting as the trained mean policy, bad command lines refused."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from experiments.training import ppo_jax as pj  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")

#: 4 cars, 5-step episodes (0.05 s), rollouts of 8 steps: every rollout holds truncations and resets.
CFG = pj.Config(num_envs=4, num_steps=8, total_timesteps=64, update_epochs=2, num_minibatches=2, hidden=(8,))


@pytest.fixture(scope="module")
def runs():
    params = pj.env_params(seed=0, n_roads=2, episode_seconds=0.05)
    train = jax.jit(pj.make_train(CFG))
    out = {name: jax.device_get(train(jax.random.PRNGKey(seed), params))
           for name, seed in (("a", 0), ("b", 0), ("c", 1))}
    return out, params


def _leaves(run):
    runner, rows = run
    return jax.tree_util.tree_leaves((runner.params, runner.stats, runner.opt)) + [rows]


def test_reproducible_per_seed_and_different_across_seeds(runs):
    out, _ = runs
    for x, y in zip(_leaves(out["a"]), _leaves(out["b"])):
        np.testing.assert_array_equal(x, y)  # bit for bit (NaN where no episode ended counts as equal)
    assert not np.array_equal(out["a"][0].params["actor"][0][0], out["c"][0].params["actor"][0][0])
    assert not np.array_equal(out["a"][1][:, 2:], out["c"][1][:, 2:])


def test_losses_finite_and_episodes_counted(runs):
    rows = runs[0]["a"][1]
    assert rows.shape == (CFG.num_updates, len(pj.METRICS))
    assert np.all(np.isfinite(rows[:, 2:]))
    episodes = rows[:, pj.METRICS.index("episodes")]
    assert episodes.sum() >= CFG.num_envs * 2  # 16 steps of 5-step episodes: at least 3 ends per car
    assert np.all(np.isfinite(rows[:, 0])) and np.all(rows[:, 0] < 0)  # returns relative to the passive car's cost


def test_optimizer_anneals_per_update_and_clips():
    """optax's Adam under PureJaxRL's schedule: with a constant gradient below the clip, every step moves each weight
    by lr × g/(|g| + ε) (Adam's bias-corrected first step size), the learning rate constant within an update's
    epochs × minibatches steps and falling linearly to 0 over the updates; a gradient above ``max_grad_norm`` is
    scaled to it first (the same step: Adam is scale-free, but the moments hold the clipped gradient)."""
    cfg = pj.Config(num_envs=4, num_steps=8, total_timesteps=4 * 8 * 4, update_epochs=2, num_minibatches=2,
                    lr=1e-2, max_grad_norm=0.5)
    per_update = cfg.update_epochs * cfg.num_minibatches
    tx = pj.optimizer(cfg)
    p, g = {"w": jnp.zeros(3)}, {"w": jnp.asarray([0.1, -0.2, 0.05])}
    state = tx.init(p)
    moves = []
    for _ in range(cfg.num_updates * per_update):
        step, state = tx.update(g, state, p)
        moves.append(np.asarray(step["w"]))
    moves = np.asarray(moves)
    lr = cfg.lr * (1.0 - np.arange(cfg.num_updates) / cfg.num_updates)
    want = -np.repeat(lr, per_update)[:, None] * np.sign(np.asarray(g["w"]))
    np.testing.assert_allclose(moves, want, rtol=1e-3)  # |g|/(|g| + 1e-5): within 1e-4
    big = {"w": 100 * g["w"]}
    _, state = tx.update(big, tx.init(p), p)
    mu = jax.tree_util.tree_leaves(state)  # the first moment holds (1 − β1) × the clipped gradient
    norm = float(np.linalg.norm(100 * np.asarray(g["w"])))
    assert any(np.allclose(np.asarray(x), (1 - pj.ADAM_B1) * 100 * np.asarray(g["w"]) * cfg.max_grad_norm / norm,
                           rtol=1e-12) for x in mu if np.shape(x) == (3,))


def _gae_reference(r, v, last_v, term, trunc, vf, gamma, lam):
    """Each step's advantage as the discounted sum Σ (γλ)^l δ_{t+l} over the rest of its episode, written out."""
    T, N = r.shape
    adv = np.zeros((T, N))
    for i in range(N):
        delta = np.zeros(T)
        for t in range(T):
            if term[t, i]:
                nxt = 0.0                      # the episode has no future
            elif trunc[t, i]:
                nxt = vf[t, i]                 # cut by time: V of its last observation
            else:
                nxt = v[t + 1, i] if t + 1 < T else last_v[i]
            delta[t] = r[t, i] + gamma * nxt - v[t, i]
        for t in range(T):
            for k in range(t, T):
                adv[t, i] += (gamma * lam) ** (k - t) * delta[k]
                if term[k, i] or trunc[k, i]:
                    break
    return adv


def test_gae_against_a_plain_reference():
    rng = np.random.default_rng(3)
    T, N, gamma, lam = 7, 3, 0.9, 0.8
    r, v, vf = rng.normal(size=(T, N)), rng.normal(size=(T, N)), rng.normal(size=(T, N))
    last_v = rng.normal(size=N)
    term, trunc = np.zeros((T, N), bool), np.zeros((T, N), bool)
    term[2, 0] = trunc[4, 0] = True      # car 0: terminated, then truncated
    trunc[1, 1] = term[5, 1] = True      # car 1: truncated, then terminated
    trunc[6, 2] = True                   # car 2: truncated at the rollout's last step
    adv, target = jax.jit(pj.gae, static_argnums=(6, 7))(
        jnp.asarray(r), jnp.asarray(v), jnp.asarray(last_v), jnp.asarray(term), jnp.asarray(trunc), jnp.asarray(vf),
        gamma, lam)
    ref = _gae_reference(r, v, last_v, term, trunc, vf, gamma, lam)
    np.testing.assert_allclose(adv, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(target, ref + v, rtol=1e-12, atol=1e-12)
    # by hand: the steps that end an episode
    assert adv[2, 0] == pytest.approx(r[2, 0] - v[2, 0])                        # terminated: no bootstrap
    assert adv[6, 2] == pytest.approx(r[6, 2] + gamma * vf[6, 2] - v[6, 2])     # truncated: V(final observation)
    assert adv[6, 1] == pytest.approx(r[6, 1] + gamma * last_v[1] - v[6, 1])    # running on: V(s_T)


def test_saved_agent_acts_as_the_mean_policy(runs, tmp_path):
    from controllers import load_agent
    from mrd_env.suites import suite

    runner, rows = runs[0]["a"]
    pj.save(tmp_path / "agent", runner, rows, CFG, {"seed": 0, "timesteps": 64, "env_kwargs": {
        "episode_seconds": 0.05, "action_mode": "normalized", "control_dt": pj.CONTROL_DT}})
    agent = load_agent(tmp_path / "agent")
    assert agent.meta["network"] == {"class": "MLPPolicy", "sizes": [8, 8, 1], "activation": "tanh"}
    assert agent.env_id == suite("car-comfort-v1").env_id  # what mrd-env score needs
    assert agent.observation_kwargs == {"action_mode": "normalized", "control_dt": 0.01}
    stats = runner.stats
    obs = np.asarray(stats.mean) + np.sqrt(np.asarray(stats.var)) * np.random.default_rng(0).normal(0, 2, (16, 8))
    got, _ = agent.predict(obs)
    # the agent normalises in float64 and feeds float32 to the network (TrainedAgent.normalize)
    o = np.asarray(pj.normalize(stats, jnp.asarray(obs), CFG.obs_clip)).astype(np.float32).astype(np.float64)
    want = np.asarray(pj.policy_mean(runner.params["actor"], jnp.asarray(o)))
    np.testing.assert_allclose(got, want.astype(np.float32), rtol=1e-6, atol=1e-7)
    assert np.ptp(want) > 0  # not a constant action


@pytest.mark.parametrize("argv, word", [(["--num-envs", "0"], "num_envs"), (["--num-minibatches", "3"],
                                        "num_minibatches"), (["--scheme", "rk4"], "--scheme"),
                                        (["--total-timesteps", "10"], "total_timesteps"),
                                        (["--speeds", "30", "10"], "speeds"), (["--lr", "-1"], "lr")])
def test_bad_arguments_exit_2_with_one_line(argv, word, capsys):
    assert pj.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and word in err


def test_bad_argument_exit_code_of_the_module():
    p = subprocess.run([sys.executable, "-m", "experiments.training.ppo_jax", "--num-steps", "x"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "--num-steps" in p.stderr
