"""The actor's pace in SAC, TD3 and TQC (issue 23): with ``actor_warmup_steps`` the actor and a learned entropy
coefficient stay as they are for the first K gradient steps while the critic and its target train, and move after;
``actor_learning_rate`` is the actor's alone; both reach the training through a hyperparameter entry, and bad values
are refused before training."""
import copy
import json

import numpy as np
import pytest
import torch

import mrd_env  # noqa: F401
from controllers.agents import algorithm_class
from controllers.residual import zero_policy_output
from controllers.training_wrappers import ResidualVecEnv
from experiments.training.actor_warmup import with_actor_warmup
from experiments.cli import main
from experiments.training.trainers import env_options, train_one
from mrd_env.envs.sb3 import make_sb3_vec_env
from experiments.common.plants import profile

CAR = "mrd_env/QuarterCarPhysical-v0"


def _kw():
    return {**env_options(profile("quarter_car")), "episode_seconds": 0.5}


def _state(module):
    return [p.detach().clone() for p in module.parameters()]


def _same(a, b):
    return all(torch.equal(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize("label, extra", [("TD3", {"policy_delay": 1}), ("TD3", {"policy_delay": 3}),
                                         ("SAC", {"ent_coef": "auto"})])
def test_the_actor_stays_during_the_warm_up_while_the_critic_learns_and_moves_after(label, extra):
    venv = ResidualVecEnv(make_sb3_vec_env(CAR, n_envs=1, seed=0, **_kw()), "skyhook_continuous", 0.5)
    model = with_actor_warmup(algorithm_class(label))("MlpPolicy", venv, device="cpu", seed=0, learning_starts=1000,
                                                      batch_size=16, policy_kwargs={"net_arch": [8, 8]}, **extra)
    model.actor_warmup_steps = 6
    zero_policy_output(model)
    model.learn(40)   # fills the buffer, no gradient step yet: they come one call at a time below
    actor, critic, critic_target = _state(model.actor), _state(model.critic), _state(model.critic_target)
    adam = copy.deepcopy(model.actor.optimizer.state_dict())
    ent = model.log_ent_coef.detach().clone() if label == "SAC" else None
    model.train(gradient_steps=4, batch_size=16)   # the whole call inside the warm-up
    assert model._n_updates == 4
    assert _same(actor, _state(model.actor)) and not _same(critic, _state(model.critic))
    assert not _same(critic_target, _state(model.critic_target))            # the targets still follow the critic
    assert model.actor.optimizer.state_dict()["state"] == adam["state"]     # no Adam moments from the warm-up
    if ent is not None:
        assert torch.equal(ent, model.log_ent_coef.detach())
    # deterministic actions are still the law's (zero correction) after the warm-up's critic updates
    assert np.all(model.predict(venv.reset(), deterministic=True)[0] == 0.0)
    model.train(gradient_steps=6, batch_size=16)   # straddles the end: 2 frozen steps, then 4 with the actor
    assert model._n_updates == 10
    assert not _same(actor, _state(model.actor))
    if ent is not None:
        assert not torch.equal(ent, model.log_ent_coef.detach())
    assert "step" not in vars(model.actor.optimizer)   # the optimizer's own step is back


def test_without_the_warm_up_the_actor_moves_at_once():
    venv = make_sb3_vec_env(CAR, n_envs=1, seed=0, **_kw())
    model = with_actor_warmup(algorithm_class("TD3"))("MlpPolicy", venv, device="cpu", seed=0, learning_starts=1000,
                                                      batch_size=16, policy_kwargs={"net_arch": [8, 8]})
    model.learn(40)
    actor = _state(model.actor)
    model.train(gradient_steps=2, batch_size=16)   # TD3's default policy_delay is 2
    assert not _same(actor, _state(model.actor))


def test_the_option_reaches_training_and_the_agent_loads_as_plain_td3(tmp_path):
    from controllers import load_agent

    run = train_one(profile("quarter_car"), "td3", 0, out=tmp_path, timesteps=96, env_kwargs=_kw(), eval_freq=0,
                    hyper={"n_envs": 2, "learning_starts": 32, "batch_size": 16, "train_freq": 1,
                           "policy_kwargs": {"net_arch": [8, 8]}, "actor_warmup_steps": 1000,
                           "residual": {"law": "skyhook_continuous", "scale": 0.5}})
    meta = json.loads((run / "agent.json").read_text())
    assert meta["algo"] == "TD3" and meta["hyperparameters"]["actor_warmup_steps"] == 1000
    agent = load_agent(run)
    # code-free (the policy rebuilt from its arrays: controllers.policy_format), TD3's own policy class
    assert agent.model.algo == "TD3" and type(agent.model.policy).__name__ == "TD3Policy"
    assert meta["resume"] == "model.zip" and type(algorithm_class("TD3").load(run / "model.zip").policy) is \
        type(agent.model.policy)   # SB3's zip beside it, to resume training
    # the actor never moved (all 32 gradient steps inside the warm-up): the agent is still exactly its law
    obs = np.zeros((3, agent.model.observation_space.shape[0]), dtype=np.float32)
    assert np.all(agent.model.predict(obs, deterministic=True)[0] == 0.0)


def test_the_actor_learning_rate_is_the_actors_alone():
    venv = make_sb3_vec_env(CAR, n_envs=1, seed=0, **_kw())
    model = with_actor_warmup(algorithm_class("SAC"))("MlpPolicy", venv, device="cpu", seed=0, learning_starts=1000,
                                                      batch_size=16, learning_rate=3e-4,
                                                      policy_kwargs={"net_arch": [8, 8]})
    model.actor_learning_rate = 3e-5
    model.learn(40)
    model.train(gradient_steps=1, batch_size=16)
    assert [g["lr"] for g in model.actor.optimizer.param_groups] == [3e-5]
    assert [g["lr"] for g in model.critic.optimizer.param_groups] == [3e-4]


@pytest.mark.parametrize("args, message", [
    (["--algo", "td3", "--set", "actor_warmup_steps=-1"], "actor_warmup_steps must be an integer >= 0"),
    (["--algo", "sac", "--set", "actor_warmup_steps=2.5"], "actor_warmup_steps must be an integer >= 0"),
    (["--algo", "sac", "--set", "actor_warmup_steps=many"], "actor_warmup_steps must be an integer >= 0"),
    (["--algo", "sac", "--set", "actor_warmup_steps=true"], "actor_warmup_steps must be an integer >= 0"),
    (["--algo", "ppo", "--set", "actor_warmup_steps=1000"], "applies to the off-policy algorithms"),
    (["--algo", "td3", "--set", "actor_learning_rate=0"], "actor_learning_rate must be a number > 0"),
    (["--algo", "sac", "--set", "actor_learning_rate=fast"], "actor_learning_rate must be a number > 0"),
    (["--algo", "ppo", "--set", "actor_learning_rate=1e-4"], "applies to the off-policy algorithms"),
])
def test_bad_warm_up_values_are_one_line_before_training(args, message, capsys, tmp_path):
    extra = []
    if args[1] == "td3":   # td3 has no shipped hyperparameter file
        path = tmp_path / "td3.yml"
        path.write_text("mrd_env/QuarterCarPhysical-v0:\n  n_envs: 1\n  policy: MlpPolicy\n", encoding="utf-8")
        extra = ["--hyperparams", str(path)]
    assert main(["train", *args, *extra, "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_warm_up_of_a_float_integer_is_accepted():
    from experiments.training.actor_warmup import actor_options, check_actor_warmup

    assert check_actor_warmup("td3", {"actor_warmup_steps": 2e4}) == 20_000
    assert check_actor_warmup("ppo", {}) == 0
    assert actor_options("sac", {"actor_warmup_steps": 0}) == {}   # nothing set: the plain algorithm
