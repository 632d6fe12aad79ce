"""The suite specs written but not yet built (``experiments/benchmark/pending_specs/``): a build runs for hours, so a
scenario whose options its environment refuses must fail here, not after the other scenarios' batches."""
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import mrd_env.envs  # noqa: F401  (registers the environments)
from mrd_env.plants import suite_spec
from mrd_env.suites import draws

PENDING = Path(__file__).resolve().parents[2] / "experiments" / "benchmark" / "pending_specs"
SPECS = sorted(PENDING.glob("*.json"))


def test_there_are_pending_specs():
    assert SPECS, PENDING


@pytest.mark.parametrize("path", SPECS, ids=lambda p: p.stem)
def test_every_scenario_of_a_pending_spec_builds_its_environment_and_steps(path):
    _, env_id, definition = suite_spec(path)
    suite = definition.suite(env_id=env_id, draws=draws(definition, env_id))
    assert suite.id == path.stem
    for scenario in suite.scenarios:
        seed = scenario.seeds[0]
        options = {**suite.episode_options(scenario, seed), "episode_seconds": 0.02}
        env = gym.make(env_id, control_dt=suite.control_dt, **options)
        try:
            env.reset(seed=seed)
            obs, reward, *_ = env.step(env.action_space.high)
        finally:
            env.close()
        assert np.isfinite(obs).all() and np.isfinite(reward), scenario.name


def test_a_twin_mirrors_its_nominal_suites_episodes():
    """A robustness twin (``<name>-robust-vN``, pending or shipped) scores the episodes of ``<name>-vN``: the same
    scenarios and seeds, options and control step."""
    from mrd_env.plants import suite_definitions

    every = {k: d for k, (_, _, d) in suite_definitions().items()}
    every.update({p.stem: suite_spec(p)[2] for p in SPECS})
    twins = [k for k in every if "-robust-v" in k]
    assert {"building-seismic-robust-v2", "car-comfort-robust-v2", "car-full-robust-v4"} <= set(twins)
    for twin in twins:
        t, nominal = every[twin], every[twin.replace("-robust-v", "-v")]
        assert t.randomise and not nominal.randomise, twin
        assert t.control_dt == nominal.control_dt and t.options == nominal.options, twin
        assert [(s.name, s.options, tuple(s.seeds)) for s in t.scenarios] == \
            [(s.name, s.options, tuple(s.seeds)) for s in nominal.scenarios], twin
