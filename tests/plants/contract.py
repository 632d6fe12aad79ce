"""The checks every plant added through its folder passes the same way (the Gymnasium contract of its two ids,
its native vector env against scalar ones, and the commands training an agent on it and scoring it), shared by
the plants' test files so that each states only what is its own."""
from __future__ import annotations

import json
import warnings

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env

from experiments.cli import main


def check_reset_reproduces_an_episode(env_id: str, options: dict, steps: int):
    """Gymnasium's checker passes on ``env_id``; reset(seed) replays an episode bit for bit (observations,
    rewards, metrics), which ends by truncation at ``steps``; another seed draws another disturbance. Returns the
    environment for the plant's own checks."""
    env = gym.make(env_id, **options)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the physical id's Box is in V, not symmetric, by design
        check_env(env.unwrapped)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=11)
        first = env.unwrapped.record.data
        env.action_space.seed(3)
        out = [obs]
        while True:
            obs, r, term, trunc, info = env.step(env.action_space.sample())
            out.append(np.append(obs, r))
            if term or trunc:
                break
        runs.append((np.concatenate(out), info["episode_metrics"]))
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1] == runs[1][1]
    assert trunc and not term
    assert env.spec.max_episode_steps == steps
    env.reset(seed=12)
    assert not np.array_equal(env.unwrapped.record.data, first)   # another seed, another disturbance
    return env


def check_vector_steps_as_scalar_ones(env_id: str, options: dict, n_dampers: int, n: int = 3) -> None:
    """The native vector env of ``n`` equals ``n`` scalar envs reset with the same seeds, bit for bit, under
    random commands in [0, 2] V."""
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **options)
    envs = [gym.make(env_id, **options) for _ in range(n)]
    seeds = [4, 5, 6][:n]
    obs, _ = venv.reset(seed=seeds)
    for e, s, o in zip(envs, seeds, obs):
        assert np.array_equal(e.reset(seed=s)[0], o)
    rng = np.random.default_rng(0)
    for _ in range(100):
        a = rng.uniform(0.0, 2.0, (n, n_dampers)).astype(np.float32)
        vo, vr, vt, vtr, _ = venv.step(a)
        for i, e in enumerate(envs):
            o, r, t, tr, _ = e.step(a[i])
            assert np.array_equal(o, vo[i]) and r == vr[i] and (t, tr) == (vt[i], vtr[i])


def check_train_then_score(plant: str, env_id: str, tmp_path) -> None:
    """``mrd-env train --plant plant`` (PPO, a few steps) writes an agent of ``env_id`` that acts on the plant's
    episodes, and that ``mrd-env benchmark`` scores on the plant's first suite where it has one."""
    from controllers import load_agent
    from mrd_env.suites import suites

    from experiments.common.evaluation import evaluate_batch
    from experiments.common.plants import profile
    from experiments.common.scenarios import held_out_scenarios

    assert main(["train", "--plant", plant, "--algo", "ppo", "--timesteps", "64", "--set", "n_steps=32",
                 "batch_size=32", "n_envs=1", "n_epochs=1", "--eval-freq", "0", "--no-progress",
                 "--out", str(tmp_path / "agents")]) == 0
    agent = tmp_path / "agents" / f"{plant}_ppo_s0"
    meta = json.loads((agent / "agent.json").read_text())
    assert meta["env_id"] == env_id
    loaded = load_agent(agent)
    sc = held_out_scenarios(profile(plant), quick=True)[0]
    eps = evaluate_batch(lambda v: loaded.bind(v), sc, "", **loaded.observation_kwargs)
    assert eps and all(np.isfinite(e.episode_return) for e in eps)
    mine = [sid for sid, s in suites().items() if s.env_id == env_id]
    if mine:  # scored on the suites whose sensors are the training's (a preview suite's are not)
        assert main(["benchmark", *(a for sid in mine for a in ("--suite", sid)), "--no-shipped", "--controller",
                     str(agent), "--episodes", "1", "--backend", "serial", "--out", str(tmp_path / "bench"),
                     "--no-progress"]) == 0
        assert list((tmp_path / "bench" / "results").glob("*.json"))
