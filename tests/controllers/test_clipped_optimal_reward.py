"""The named variant ``clipped_optimal_reward``: clipped-optimal control designed for the environment's own reward
(drifts and absolute accelerations on the building) as the sampled-data LQR of the control step. On the benchmark
building (damper in storey 2) at the agents' 10 ms it must beat the default design (drifts only, continuous LQR)
on the same ground motions, by damping less; bad options are refused by name."""
import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from controllers import available_controllers, make_controller
from controllers.model_based import ClippedOptimal

BUILDING = "mrd_env/ShearBuildingPhysical-v0"
OPTIONS = dict(damper_floors=(2,), control_dt=0.01, ground_motion="kanai_tajimi", episode_seconds=6.0)


def _run(name, seeds):
    """Per seed: the environment's return and the mean command of law ``name`` on the same Kanai–Tajimi record."""
    returns, commands = [], []
    for seed in seeds:
        env = gym.make(BUILDING, **OPTIONS)
        law = make_controller(name, env)
        obs, _ = env.reset(seed=seed)
        total, us = 0.0, []
        while True:
            u, _ = law.predict(obs)
            us.append(float(np.ravel(u)[0]))
            obs, r, term, trunc, _ = env.step(u)
            total += r
            if term or trunc:
                break
        returns.append(total)
        commands.append(np.mean(us))
        env.close()
    return np.array(returns), np.array(commands)


def test_the_variant_is_listed_and_is_the_reward_aligned_sampled_design():
    assert "clipped_optimal_reward" in available_controllers()
    env = gym.make(BUILDING, **OPTIONS).unwrapped
    law = make_controller("clipped_optimal_reward", env)
    assert isinstance(law, ClippedOptimal)
    assert law.design_kind == "sampled"
    # the reward's cost weighs the absolute floor accelerations too, which the default objective (drifts) does not
    assert "abs_acc" in law.weights and "abs_acc" not in ClippedOptimal(env).weights


def test_the_reward_aligned_law_beats_the_default_on_the_same_ground_motions():
    """Paired on three Kanai–Tajimi records at 10 ms: a higher return on each, with a softer mean command (the
    default, designed on the drifts alone, damps more than the reward's acceleration term pays for)."""
    seeds = (11, 12, 13)
    r_reward, u_reward = _run("clipped_optimal_reward", seeds)
    r_default, u_default = _run("clipped_optimal", seeds)
    assert np.all(r_reward > r_default), (r_reward, r_default)
    assert np.mean(u_reward) < np.mean(u_default)


def test_bad_options_of_the_variant_are_refused_by_name():
    env = gym.make(BUILDING, **OPTIONS).unwrapped
    with pytest.raises(ValueError, match="design must be 'continuous' or 'sampled'"):
        make_controller("clipped_optimal_reward", env, design="banana")
    with pytest.raises(ValueError, match="force_ref must be > 0"):
        make_controller("clipped_optimal_reward", env, force_ref=-1.0)
    with pytest.raises(ValueError, match="clipped_optimal_reward"):  # an unknown name lists the variants
        make_controller("clipped_optimal_rewards", env)
