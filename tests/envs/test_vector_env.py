"""The native vector environments and the Stable-Baselines3 bridge: Gymnasium's vector API and autoreset,
environment i of a vector environment equal to a scalar environment with the same seed (bit for bit), SB3's
VecEnv conventions, and a PPO update through the bridge."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.plants import QuarterCarVectorEnv, ShearBuildingVectorEnv
from mrd_env.envs.vector import env_info

QC, SB = "mrd_env/QuarterCarPhysical-v0", "mrd_env/ShearBuildingPhysical-v0"


def _scalar_episode(env_id, seed, actions, **kw):
    env = gym.make(env_id, **kw)
    obs, _ = env.reset(seed=seed)
    out, rewards = [obs], []
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append(obs)
        rewards.append(r)
        if term or trunc:
            return np.array(out), np.array(rewards), info
    return np.array(out), np.array(rewards), None


@pytest.mark.parametrize("env_id,kw", [
    (QC, dict(episode_seconds=0.3, sensor_noise={"sprung_acc": 0.05}, sensor_delay=2, history=3)),
    (SB, dict(ground_motion="kanai_tajimi", episode_seconds=0.3, control_dt=0.002)),
])
def test_env_i_equals_a_scalar_env_with_the_same_seed_bit_for_bit(env_id, kw):
    N = 4
    venv = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kw)
    rng = np.random.default_rng(0)
    n_steps = int(round(kw["episode_seconds"] / venv.unwrapped.control_dt))
    acts = rng.uniform(venv.single_action_space.low, venv.single_action_space.high, (n_steps, N, venv.nd))
    obs, _ = venv.reset(seed=10)
    vobs, vrew, vinfo = [obs], [], None
    for k in range(n_steps):
        obs, r, term, trunc, info = venv.step(acts[k])
        vobs.append(obs)
        vrew.append(r)
        if (term | trunc).any():
            assert (term | trunc).all()  # same-length episodes end together
            vinfo = info
    vobs, vrew = np.array(vobs), np.array(vrew)
    for i in range(N):
        sobs, srew, sinfo = _scalar_episode(env_id, 10 + i, acts[:, i], **kw)
        np.testing.assert_array_equal(vobs[:, i], sobs)
        np.testing.assert_array_equal(vrew[:, i], srew)
        assert env_info(vinfo, i)["episode_metrics"] == sinfo["episode_metrics"]


def test_vector_env_api_and_next_step_autoreset():
    venv = gym.make_vec(QC, num_envs=3, vectorization_mode="vector_entry_point", episode_seconds=0.01,
                        control_dt=0.005)
    assert isinstance(venv.unwrapped, QuarterCarVectorEnv)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert venv.observation_space.shape == (3, 8) and venv.action_space.shape == (3, 1)
    obs, info = venv.reset(seed=[1, 2, 3])
    assert obs.shape == (3, 8) and obs.dtype == np.float32
    a = np.ones((3, 1), dtype=np.float32)
    _, r, term, trunc, info = venv.step(a)
    assert not (term | trunc).any() and np.all(r < 0)
    _, r, term, trunc, info = venv.step(a)
    assert trunc.all() and not term.any() and info["_episode_metrics"].all()
    assert info["episode_metrics"]["duration"] == pytest.approx([0.01] * 3)
    obs2, r, term, trunc, info = venv.step(a)  # the autoreset step: first observation, reward 0, no flags
    assert np.all(r == 0) and not (term | trunc).any()
    np.testing.assert_allclose(obs2[:, :4], 0.0, atol=1e-9)  # at rest again
    with pytest.raises(ValueError, match="actions must be finite"):
        venv.step(np.full((3, 1), np.nan))
    with pytest.raises(ValueError, match=r"actions must have shape \(3, 1\)"):
        venv.step(np.ones(4))


def test_termination_in_one_env_does_not_stop_the_others():
    venv = ShearBuildingVectorEnv(2, episode_seconds=0.5, stroke_limit=1e-4)
    venv.reset(seed=0)
    ended_at = None
    for k in range(500):
        _, r, term, trunc, info = venv.step(np.array([[0.0], [2.25]]))
        if term[0]:
            ended_at = k
            assert info["termination_reason"][0] == "stroke_limit" and r[0] < -10 * 0.5  # 10 per planned second
            assert info["_termination_reason"].tolist() == [True, False]
            break
    assert ended_at is not None and ended_at < 499
    assert not term[1] and not trunc[1]  # env 1 (the stiff damper) runs on
    t1 = info["t"][1]
    _, _, term, trunc, info = venv.step(np.array([[0.0], [2.25]]))  # env 0 restarts (next-step autoreset)
    assert info["t"][0] == 0.0 and info["t"][1] == pytest.approx(t1 + venv.control_dt)
    assert not term[1] and not trunc[1]


def test_sb3_bridge_follows_sb3_conventions_and_trains():
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env  # noqa: F401  (the scalar checker, see test_envs)
    from stable_baselines3.common.vec_env import VecNormalize

    from mrd_env.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env(QC, n_envs=4, seed=3, episode_seconds=0.02, control_dt=0.01, action_mode="normalized")
    obs = venv.reset()
    assert obs.shape == (4, 8)
    dones_seen = False
    for _ in range(3):
        venv.step_async(np.zeros((4, 1), dtype=np.float32))
        obs, rew, dones, infos = venv.step_wait()
        assert rew.dtype == np.float32 and len(infos) == 4
        if dones.any():
            dones_seen = True
            i = int(np.flatnonzero(dones)[0])
            assert infos[i]["terminal_observation"].shape == (8,)
            assert infos[i]["TimeLimit.truncated"] is True
            assert "episode_metrics" in infos[i]
    assert dones_seen
    model = PPO("MlpPolicy", VecNormalize(venv), n_steps=16, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=64)
    assert model.num_timesteps >= 64


def test_a_plant_added_in_two_files_works_with_every_part_and_the_laws():
    """The half car (its folder mrd_env/plants/half_car/ and one registry line): two dampers,
    four road inputs, the checker, the vector env, and the classical laws through its declared roles."""
    from gymnasium.utils.env_checker import check_env

    from controllers import make_controller

    env = gym.make("mrd_env/HalfCarPhysical-v0", episode_seconds=0.2,
                   sensors=("body_acc", "travel", "travel_rate", "body_vel_at_axles", "wheel_vel", "damper_force"))
    check_env(env.unwrapped, skip_render_check=True)
    assert env.action_space.shape == (2,)
    for name in ("skyhook_on_off", "groundhook", "clipped_optimal", "max_energy_dissipation"):
        ctrl = make_controller(name, env)
        obs, _ = env.reset(seed=0)
        while True:
            obs, r, term, trunc, info = env.step(ctrl.predict(obs)[0])
            if term or trunc:
                break
        assert trunc and np.isfinite(info["episode_metrics"]["acc_weighted_rms"])
    venv = gym.make_vec("mrd_env/HalfCarPhysical-v0", num_envs=3, vectorization_mode="vector_entry_point",
                        episode_seconds=0.05)
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (3, 1 + 1 + 2 + 2 + 2)


def test_threads_change_the_speed_not_the_results():
    """``threads``: one thread or numba's threads step 64 environments alike, bit for bit; a bad count is refused
    with an error naming it."""
    runs = []
    for threads in (1, 2):
        venv = gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=64, vectorization_mode="vector_entry_point",
                            control_dt=0.01, episode_seconds=0.5, threads=threads)
        assert venv.unwrapped.core.driver.threads == threads
        obs, _ = venv.reset(seed=4)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(30):
            a = rng.uniform(venv.single_action_space.low, venv.single_action_space.high, (64, 1))
            obs, r, term, trunc, _ = venv.step(a)
            out += [obs, r, term, trunc]
        runs.append(out)
        venv.close()
    assert all(np.array_equal(a, b) for a, b in zip(*runs))
    with pytest.raises(ValueError, match="threads must be an int >= 1"):
        gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=4, vectorization_mode="vector_entry_point", threads=0)
