"""CMA-ES agents (``mrd-env train --algo cmaes``): the policy network, behaviour cloning, paired comparisons with
common random numbers, and the training run end to end on a tiny budget; the benchmark building's damper place."""
from __future__ import annotations

import csv
import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from controllers import load_agent, make_controller
from controllers.mlp_policy import MLPPolicy
from experiments.cli import main
from experiments.common.evaluation import evaluate_batch
from experiments.training.evolution import NormalizedPolicy, _returns, check
from experiments.common.scenarios import HELD_OUT_SEED, held_out_scenarios, validation
from experiments.training.warm_start import fit_policy
from experiments.common.plants import profile

TINY = ["--algo", "cmaes", "--timesteps", "1500", "--eval-freq", "500", "--eval-episodes", "2", "--no-progress",
        "--set", "popsize=4", "episodes=2", "hidden=[4]", "env_kwargs={episode_seconds: 0.3}"]


def test_policy_network_is_the_documented_tanh_mlp():
    rng = np.random.default_rng(0)
    pol = MLPPolicy((3, 5, 2), rng.normal(size=MLPPolicy((3, 5, 2)).n_params))
    assert pol.n_params == 3 * 5 + 5 + 5 * 2 + 2
    (W1, b1), (W2, b2) = [(W[0], b[0]) for W, b in pol.layers(pol.theta)]
    o = rng.normal(size=(7, 3))
    expected = np.tanh(np.tanh(o @ W1 + b1) @ W2 + b2)
    batch, _ = pol.predict(o)
    assert np.allclose(batch, expected, atol=1e-6) and batch.dtype == np.float32
    assert np.allclose(pol.predict(o[2])[0], expected[2], atol=1e-6)
    # a population: candidate p's actions are those of the policy with its weights
    thetas = rng.normal(size=(4, pol.n_params))
    acts = MLPPolicy.forward(pol.layers(thetas), np.broadcast_to(o, (4, 7, 3)))
    assert np.allclose(acts[2], MLPPolicy((3, 5, 2), thetas[2]).predict(o)[0], atol=1e-6)
    with pytest.raises(ValueError, match="theta must have 32"):
        MLPPolicy((3, 5, 2), np.zeros(5))
    with pytest.raises(ValueError, match="sizes"):
        MLPPolicy((3,))


def test_policy_network_saves_and_loads_exactly(tmp_path):
    pol = MLPPolicy((4, 3, 1), np.random.default_rng(1).normal(size=19))
    pol.save(tmp_path / "p.npz")
    back = MLPPolicy.load(tmp_path / "p.npz")
    assert back.sizes == pol.sizes and np.array_equal(back.theta, pol.theta)


def test_behaviour_cloning_fits_a_smooth_law():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(4000, 3))
    y = np.tanh(0.8 * X[:, :1] - 0.5 * X[:, 1:2])
    theta = fit_policy((3, 8, 1), X, y, seed=0)
    pred, _ = MLPPolicy((3, 8, 1), theta).predict(X)
    assert np.sqrt(np.mean((pred - y) ** 2)) < 0.05


def test_common_random_numbers_make_the_comparison_paired():
    """Candidates with the same weights meet the same disturbances, so they score exactly alike; other seeds give
    other returns."""
    P, E = 3, 2
    venv = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=P * E, vectorization_mode="vector_entry_point",
                        **{**profile("quarter_car").training, "episode_seconds": 0.3}, action_mode="normalized",
                        control_dt=0.01)
    pol = MLPPolicy((venv.single_observation_space.shape[0], 4, 1))
    n = venv.single_observation_space.shape[0]
    norm = NormalizedPolicy(pol, np.zeros(n), np.ones(n), 10.0)
    theta = np.random.default_rng(0).normal(scale=0.3, size=pol.n_params)
    r, steps = _returns(venv, pol, norm, np.tile(theta, (P, 1)), [11, 12])
    assert steps == P * E * 30 and np.all(r == r[0])
    r2, _ = _returns(venv, pol, norm, np.tile(theta, (P, 1)), [13, 14])
    assert r2[0] != r[0]


def test_bad_hyperparameters_are_named():
    for bad, name in (({"popsize": 2}, "popsize"), ({"sigma0": 0}, "sigma0"), ({"hidden": [0]}, "hidden"),
                      ({"episodes": 1.5}, "episodes"), ({"learning_rate": 1e-3}, "learning_rate"),
                      ({"warm_start": "skyhok"}, "warm_start")):
        with pytest.raises(ValueError, match=name):
            check(bad)


def test_warm_start_is_for_cmaes_only(capsys):
    assert main(["train", "--plant", "quarter_car", "--warm-start", "skyhook_continuous", "--timesteps", "10",
                 "--no-progress"]) == 2
    assert "--warm-start applies to --algo cmaes" in capsys.readouterr().err


def _short_validation():
    """The validation episodes of the tiny runs (0.3 s long)."""
    val = validation(profile("quarter_car"), 2)[0]
    return dataclasses.replace(val, options={**val.options, "episode_seconds": 0.3})


# one worker runs the module (--dist loadgroup): its module fixture's CMA-ES agents are computed once, not on each
pytestmark = pytest.mark.xdist_group("test_evolution")


@pytest.fixture(scope="module")
def es_runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("es")
    for name in ("a", "b"):
        assert main(["train", "--plant", "quarter_car", "--seeds", "0", "--out", str(out / name), *TINY]) == 0
    return out


def test_cmaes_training_writes_an_agent_the_tooling_loads(es_runs, tmp_path):
    run = es_runs / "a" / "quarter_car_cmaes_s0"
    for f in ("agent.json", "training.monitor.csv", "validation.csv", "learning_curve.png", "best/agent.json",
              "best/policy.npz", "best/normalization.npz"):
        assert (run / f).exists(), f
    meta = json.loads((run / "agent.json").read_text())
    # the run folder's own agent: its files named by their digest (saved in place, atomically)
    assert meta["model"].startswith("policy-") and (run / meta["model"]).exists()
    assert meta["normalization"].startswith("normalization-") and (run / meta["normalization"]).exists()
    assert meta["algo"] == "CMA-ES" and meta["hyperparameters"]["warm_start"] == "skyhook_continuous"
    with (run / "validation.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert int(rows[0]["timesteps"]) == 0 and len(rows) >= 3
    agent = load_agent(run / "best")
    env = gym.make(agent.env_id, **agent.env_kwargs)
    obs, _ = env.reset(seed=HELD_OUT_SEED)
    action, _ = agent.predict(obs)
    assert env.action_space.contains(np.asarray(action, dtype=np.float32))
    # the best agent reproduces its validation return, reloaded from its folder
    val = _short_validation()
    eps = evaluate_batch(lambda v: agent.bind(v), val, "", **agent.observation_kwargs)
    assert np.mean([e.episode_return for e in eps]) == pytest.approx(agent.meta["validation_return"], rel=1e-6)
    # the trained agent enters the benchmark: scored on a suite of its environment beside a shipped law
    assert main(["benchmark", "--suite", "car-comfort-v1", "--only", "skyhook_continuous", "--controller", str(run),
                 "--episodes", "1", "--backend", "serial", "--out", str(tmp_path / "bench"), "--no-progress"]) == 0
    assert len(list((tmp_path / "bench" / "results").glob("car-comfort-v1__*.json"))) == 2
    assert str(run) in (tmp_path / "bench" / "leaderboards" / "car-comfort-v1" / "leaderboard.md").read_text()


def test_cmaes_same_seed_same_agent(es_runs):
    a, b = (load_agent(es_runs / n / "quarter_car_cmaes_s0") for n in ("a", "b"))
    assert np.array_equal(a.model.theta, b.model.theta)


def test_the_warm_start_begins_where_the_law_is(es_runs):
    """The step-0 validation return (the cloned network) is close to the law's own on the same episodes."""
    run = es_runs / "a" / "quarter_car_cmaes_s0"
    with (run / "validation.csv").open() as fh:
        start = float(next(csv.DictReader(fh))["validation_return"])
    val = _short_validation()
    law = np.mean([e.episode_return for e in evaluate_batch(
        lambda v: make_controller("skyhook_continuous", v), val, "", control_dt=0.01, action_mode="normalized")])
    assert start == pytest.approx(law, rel=0.1)


def test_benchmark_building_has_its_damper_where_the_command_matters():
    """Every experiment's building has its damper in storey 2; there the best law at 1 ms beats passive-on by more
    than 10 % on El Centro N-S, while in storey 1 (the lab model's own place) it is within 1 %."""
    building = profile("shear_building")
    assert building.training["damper_floors"] == building.options["damper_floors"] == (2,)
    assert all(sc.options["damper_floors"] == (2,) for sc in held_out_scenarios(building))
    returns = {}
    for where, options in (("storey 2", None), ("storey 1", {})):
        sc = held_out_scenarios(building, plant_options=options)[0]
        for law in ("passive_on", "clipped_optimal"):
            returns[where, law] = evaluate_batch(lambda v, n=law: make_controller(n, v), sc, "",
                                                 control_dt=0.001)[0].episode_return
    gain2 = returns["storey 2", "clipped_optimal"] / returns["storey 2", "passive_on"]
    gain1 = returns["storey 1", "clipped_optimal"] / returns["storey 1", "passive_on"]
    assert gain2 < 0.9 and abs(gain1 - 1) < 0.01


def test_a_preview_agent_is_named_and_filed_apart_from_the_plain_one(es_runs, tmp_path):
    """--preview: its own run folder (a plain run in the same --out is not overwritten) and a name that says so in
    every table; loaded, it reads the road-preview sensor."""
    assert main(["train", "--plant", "quarter_car", "--seeds", "0", "--preview", "--out", str(tmp_path), *TINY]) == 0
    assert not (tmp_path / "quarter_car_cmaes_s0").exists()
    agent = load_agent(tmp_path / "quarter_car_cmaes-preview_s0" / "best")
    assert agent.name == "CMA-ES preview s0"
    assert load_agent(es_runs / "a" / "quarter_car_cmaes_s0").name == "CMA-ES s0"
    assert "road_preview" in agent.env_kwargs["sensors"]
