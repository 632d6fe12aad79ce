"""The defaults a user meets (issue 22): the v1 ids are what an RL user expects out of the box; the Physical-v0 ids
keep the physics-level defaults (issue 36: under their own names, not as an outdated version)."""
import warnings

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from mrd_env.plants.registry import renamed, v1

RENAMED, V1 = renamed(), v1()

SHORT = {"episode_seconds": 0.5}


@pytest.mark.parametrize("env_id", sorted(V1))
def test_v1_is_the_rl_set_up_and_passes_sb3s_checker_without_warnings(env_id):
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(env_id, **SHORT)
    base = env.unwrapped
    assert base.control_dt == 0.01 and base.action_mode == "normalized"
    assert env.action_space.low.min() == -1.0 and env.action_space.high.max() == 1.0
    assert env.spec.max_episode_steps == 50                          # 0.5 s at 10 ms
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*(normali[sz]ed|symmetric).*")   # SB3's action-space warning
        check_env(base, warn=True)
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **SHORT)
    assert venv.control_dt == 0.01 and venv.single_action_space == env.action_space
    # an option still overrides the version's default
    assert gym.make(env_id, control_dt=0.001, **SHORT).unwrapped.control_dt == 0.001


def test_v1_building_has_the_benchmarks_damper_storey_and_v0_the_labs():
    from experiments.common.plants import profile

    v1 = gym.make("mrd_env/ShearBuilding-v1", **SHORT).unwrapped
    v0 = gym.make("mrd_env/ShearBuildingPhysical-v0", **SHORT).unwrapped
    benchmark_floors = profile("shear_building").options["damper_floors"]
    assert tuple(v1.assembly.options["damper_floors"]) == tuple(benchmark_floors) == (2,)
    assert np.array_equal(v0.linear_plant.S, [[1.0, 0.0, 0.0]])     # storey 1: the ground floor's drift
    assert np.array_equal(v1.linear_plant.S, [[-1.0, 1.0, 0.0]])    # storey 2: floor 2 relative to floor 1
    assert v0.control_dt == 0.001 and v0.action_mode == "physical"


@pytest.mark.parametrize("former", sorted(RENAMED))
def test_a_former_physical_id_warns_with_the_new_name_and_makes_the_same_environment(former):
    """The physics-level set-up has its own name (Gymnasium called a -v0 beside a -v1 out of date): its former id
    still makes the same environment, step for step, after a warning naming the id to use now."""
    now = RENAMED[former]
    with pytest.warns(DeprecationWarning, match=f"{former} is the former name of {now}"):
        old = gym.make(former, episode_seconds=0.05)
    new = gym.make(now, episode_seconds=0.05)
    assert old.unwrapped.spec.kwargs == new.unwrapped.spec.kwargs and type(old.unwrapped) is type(new.unwrapped)
    (o1, _), (o2, _) = old.reset(seed=3), new.reset(seed=3)
    assert np.array_equal(o1, o2)
    a = new.action_space.sample()
    assert all(np.array_equal(x, y) for x, y in zip(old.step(a)[:4], new.step(a)[:4]))


def test_no_registered_id_is_called_out_of_date_but_the_former_ones():
    for env_id in [i for i in gym.registry if i.startswith("mrd_env/") and i not in RENAMED]:
        with warnings.catch_warnings():
            warnings.filterwarnings("error", message=".*out of date", category=DeprecationWarning)
            gym.make(env_id, episode_seconds=0.02).close()
