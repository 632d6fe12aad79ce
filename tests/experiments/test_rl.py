"""RL tooling end to end on tiny budgets: train (RL Zoo layout, validation, best agent, curves), reload with
``controllers.load_agent``, evaluate next to the laws; rewards that rank and never pay for termination."""
from __future__ import annotations

import csv
import json

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from controllers import CONTROLLERS, load_agent, make_controller
from experiments.cli import main
from experiments.common.evaluation import evaluate_batch
from experiments.common.scenarios import HELD_OUT_SEED, held_out_scenarios, validation
from experiments.common.plants import profile

TINY = ["--timesteps", "256", "--eval-freq", "128", "--eval-episodes", "1", "--no-progress",
        "--set", "n_envs=2", "n_steps=64", "batch_size=64", "n_epochs=1"]


# one worker runs the module (--dist loadgroup): its module fixture's trained agents are computed once, not on each
pytestmark = pytest.mark.xdist_group("test_rl")


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("agents")
    assert main(["train", "--plant", "shear_building", "--seeds", "0", "1", "--out", str(out), *TINY]) == 0
    return out


def test_train_writes_agents_curves_and_the_best_validation_agent(trained):
    for seed in (0, 1):
        run = trained / f"shear_building_ppo_s{seed}"
        for f in ("agent.json", "model.zip", "training.monitor.csv", "validation.csv", "learning_curve.png",
                  "best/agent.json", "best/policy.safetensors", "best/normalization.npz", "best/model.zip"):
            assert (run / f).exists(), f
        meta = json.loads((run / "agent.json").read_text())
        # the run folder's own agent: code-free files named by their digest, agent.json naming them, model.zip to
        # resume training; no file of an earlier save left
        assert meta["model"].startswith("policy-") and meta["model"].endswith(".safetensors")
        assert sorted(meta["files"]) == sorted([meta["model"], meta["normalization"]]) and meta["resume"] == "model.zip"
        assert sorted(f.name for f in run.glob("policy-*")) == [meta["model"]]
        assert meta["format"] == "mrd-env-agent" and meta["plant"] == "shear_building" and meta["seed"] == seed
        assert meta["env_kwargs"]["control_dt"] == 0.01 and meta["hyperparameters"]["n_envs"] == 2
        assert meta["command"].startswith(f"mrd-env train --plant shear_building --seeds 0 1 --out {trained}")
        with (run / "validation.csv").open() as fh:
            rows = list(csv.DictReader(fh))
        assert [int(r["timesteps"]) for r in rows][:3] == [0, 128, 256]  # from the untrained policy on
        assert all(np.isfinite(float(r["validation_return"])) for r in rows)


def test_the_best_agent_reproduces_its_validation_return(trained):
    """Reloaded from its folder (raw observations, the saved normalisation), the best agent scores on the
    validation episodes what it scored during training."""
    run = trained / "shear_building_ppo_s0"
    best = load_agent(run / "best")
    sc = validation(profile("shear_building"), 1)[0]
    eps = evaluate_batch(lambda v: best.bind(v), sc, "", **best.observation_kwargs)
    assert eps[0].episode_return == pytest.approx(best.meta["validation_return"], rel=1e-4)


def test_loaded_agent_rebuilds_its_environment_and_acts_in_it(trained):
    agent = load_agent(trained / "shear_building_ppo_s1")
    env = gym.make(agent.env_id, **agent.env_kwargs)
    obs, _ = env.reset(seed=HELD_OUT_SEED)
    action, _ = agent.predict(obs)
    assert env.action_space.contains(np.asarray(action, dtype=np.float32))
    assert agent.observation_kwargs["control_dt"] == 0.01
    with pytest.raises(ValueError, match="trained at 0.01 s"):
        agent.bind(gym.make(agent.env_id, **{**agent.observation_kwargs, "control_dt": 0.001}))


def test_same_seed_same_agent(tmp_path):
    for name in ("a", "b"):
        assert main(["train", "--plant", "quarter_car", "--seeds", "3", "--out", str(tmp_path / name), *TINY,
                     "--eval-freq", "0"]) == 0
    a, b = (load_agent(tmp_path / n / "quarter_car_ppo_s3") for n in ("a", "b"))
    for (ka, va), (kb, vb) in zip(a.model.policy.state_dict().items(), b.model.policy.state_dict().items()):
        assert ka == kb and np.array_equal(va.numpy(), vb.numpy())


def test_the_benchmark_scores_trained_agents_beside_the_laws(trained, tmp_path):
    """Agents from ``mrd-env train`` enter the benchmark as folders: scored on a suite of the environment they were
    trained on, beside the shipped laws, one result file each, shares within what the suite's references allow."""
    agents = [str(trained / f"shear_building_ppo_s{s}") for s in (0, 1)]
    out = tmp_path / "b"
    assert main(["benchmark", "--suite", "building-seismic-v1", "--only", "passive_off", "clipped_optimal",
                 "--controller", agents[0], "--controller", agents[1], "--episodes", "1", "--backend", "serial",
                 "--out", str(out), "--no-progress"]) == 0
    results = sorted((out / "results").glob("*.json"))
    assert len(results) == 4
    for path in results:
        data = json.loads(path.read_text())
        assert data["controller"]["kind"] == ("agent" if "ppo" in path.name else "law")
        assert all(e["share"] <= 1.0 + 1e-9 for e in data["episodes"]), path.name  # none beats the clairvoyant
    assert (out / "leaderboards" / "building-seismic-v1" / "leaderboard.png").stat().st_size > 10_000


def test_recurrent_policies_work_with_the_tooling(tmp_path):
    pytest.importorskip("sb3_contrib")
    assert main(["train", "--plant", "quarter_car", "--algo", "recurrentppo", "--seeds", "0", "--out",
                 str(tmp_path), *TINY, "--set", "policy_kwargs={lstm_hidden_size: 8}"]) == 0
    agent = load_agent(tmp_path / "quarter_car_recurrentppo_s0")
    assert agent.meta["recurrent"]
    sc = held_out_scenarios(profile("quarter_car"), quick=True)[0]
    eps = evaluate_batch(lambda v: agent.bind(v), sc, "", **agent.observation_kwargs)
    assert np.isfinite(eps[0].episode_return)


def test_history_stacks_past_observations_for_memoryless_policies():
    env = gym.make("mrd_env/QuarterCarPhysical-v0", episode_seconds=0.1, history=3, control_dt=0.01)
    one = gym.make("mrd_env/QuarterCarPhysical-v0", episode_seconds=0.1, control_dt=0.01)
    assert env.observation_space.shape[0] == 3 * one.observation_space.shape[0]
    obs, _ = env.reset(seed=0)
    o1, _ = one.reset(seed=0)
    seen = [o1]
    for _ in range(4):
        obs, *_ = env.step(np.array([1.0], dtype=np.float32))
        o1, *_ = one.step(np.array([1.0], dtype=np.float32))
        seen.append(o1)
    np.testing.assert_array_equal(obs, np.concatenate(seen[-3:]))  # oldest first


# --- rewards ------------------------------------------------------------------------------------------------------

def _returns(plant: str, scenario, control_dt: float = 0.01) -> dict[str, list]:
    # nonlinear MPC (not real time: an L-BFGS solve per step) takes most of this test's time and adds no finisher
    # that the laws and linear MPC do not already cover
    laws = [c for c in CONTROLLERS if c != "nmpc" and (c != "skyhook_on_off" or plant == "quarter_car")]
    out = {}
    for name in laws:
        try:
            eps = evaluate_batch(lambda v, n=name: make_controller(n, v), scenario, "", control_dt=control_dt)
        except ValueError as exc:  # a law for the other plant (needs roles or sensors this plant lacks)
            if "needs" not in str(exc):
                raise
            continue
        out[name] = eps
    return out


@pytest.mark.parametrize("plant", ["quarter_car", "shear_building"])
def test_termination_never_pays(plant):
    """On every benchmark scenario: an episode ended by the stroke limit scores below every controller that
    finishes — the penalty (10 per planned second) exceeds any finisher's cost, rough roads included."""
    for sc in held_out_scenarios(profile(plant)):
        res = _returns(plant, sc)
        env = gym.make(sc.env_id, **sc.options, control_dt=0.01)
        asm = env.unwrapped.assembly
        finished = [e.episode_return for eps in res.values() for e in eps if "terminated" not in e.metrics]
        ended = [e.episode_return for eps in res.values() for e in eps if "terminated" in e.metrics]
        assert finished, sc.name
        for seed in sc.seeds:
            env.reset(seed=seed)
            planned = env.unwrapped.core._n_steps[0] * asm.control_dt
            # the best a terminated episode can score: no cost before the limit, then the penalty
            assert -asm.limits.amount(planned) < min(finished), sc.name
        assert all(r < min(finished) for r in ended), sc.name


def test_rewards_separate_random_passive_and_the_best_law():
    """On a class-C road (paired seeds): best law > passive-off > random > passive-on, each gap well beyond
    the seed-to-seed spread of the differences."""
    sc = held_out_scenarios(profile("quarter_car"), seeds=4)[0]
    ret = {n: np.array([e.episode_return for e in evaluate_batch(lambda v, n=n: make_controller(n, v), sc, "",
                                                                   control_dt=0.01)])
           for n in ("skyhook_continuous", "passive_off", "random", "passive_on")}
    order = ["skyhook_continuous", "passive_off", "random", "passive_on"]
    for better, worse in zip(order, order[1:]):
        diff = ret[better] - ret[worse]
        assert diff.mean() > 3 * diff.std() + 1e-9 and diff.min() > 0, (better, worse, diff)


def test_training_distributions_draw_new_episodes():
    for plant, env_id in (("quarter_car", "mrd_env/QuarterCarPhysical-v0"), ("shear_building", "mrd_env/ShearBuildingPhysical-v0")):
        env = gym.make(env_id, **profile(plant).training, control_dt=0.01)
        recs = []
        for seed in (0, 1, 2):
            env.reset(seed=seed)
            recs.append(env.unwrapped.record.data[:2000].copy())
        assert not np.array_equal(recs[0], recs[1]) and not np.array_equal(recs[1], recs[2])
        env.reset(seed=1)
        np.testing.assert_array_equal(env.unwrapped.record.data[:2000], recs[1])


def test_linear_schedules_follow_rl_zoo():
    from experiments.training.sb3_trainer import schedule
    from experiments.training.trainers import check_hyperparameters

    lr = schedule("lin_3e-4")
    assert lr(1.0) == pytest.approx(3e-4) and lr(0.5) == pytest.approx(1.5e-4) and lr(0.0) == 0.0
    assert schedule(0.2) == 0.2 and schedule("MlpPolicy") == "MlpPolicy"
    with pytest.raises(ValueError, match="lin_<x> with a number x > 0"):
        check_hyperparameters("ppo", {"learning_rate": "lin_fast"})
    with pytest.raises(ValueError, match="x > 0"):
        check_hyperparameters("ppo", {"learning_rate": "lin_-3e-4"})
