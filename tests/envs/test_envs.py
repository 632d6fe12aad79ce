"""The Gymnasium environments (mrd_env/QuarterCarPhysical-v0, mrd_env/ShearBuildingPhysical-v0): API conformance for every
damper model, determinism, input validation, termination/truncation with metrics, rendering."""
from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
import scipy.signal
from gymnasium.utils.env_checker import check_env as gym_check_env

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.dampers import available_dampers, make_damper
from mrd_env.disturbances import Record, sine_sweep
from mrd_env.plants import QuarterCarEnv, ShearBuildingEnv
from mrd_env.plants.registry import register_envs
from mrd_env.stepping import DIVERGED
from mrd_env.metrics import weighting_sos
from mrd_env.plants import ShearBuildingParams

register_envs()  # until mrd_env/__init__.py calls it

QC = "mrd_env/QuarterCarPhysical-v0"
SB = "mrd_env/ShearBuildingPhysical-v0"
IDS = (QC, SB)
SHORT = {"episode_seconds": 0.5}
ZERO_FORCE = {"fc_a": 0.0, "fc_b": 0.0, "c0a": 0.0, "c0b": 0.0, "f0": 0.0}


def _check(env) -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SB3 advises a symmetric Box; the physical mode is in V or A by design
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped)


def _run(env, action, seed=0, max_steps=None):
    obs, _ = env.reset(seed=seed)
    out_obs, rewards = [obs], []
    n = 0
    while True:
        obs, r, term, trunc, info = env.step(action)
        out_obs.append(obs)
        rewards.append(r)
        n += 1
        if term or trunc or (max_steps and n >= max_steps):
            return np.array(out_obs), np.array(rewards), term, trunc, info


# ---------------------------------------------------------------------------------------------------------------
# API conformance

@pytest.mark.parametrize("model", available_dampers())
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_every_damper_model(env_id, model):
    env = gym.make(env_id, damper=model, **SHORT)
    _check(env)
    _, rewards, term, trunc, info = _run(env, env.action_space.high)
    assert np.all(np.isfinite(rewards))
    assert trunc and not term, info.get("termination_reason")
    assert all(np.isfinite(v) for v in info["episode_metrics"].values())
    env.close()


@pytest.mark.parametrize("action_mode", ["physical", "normalized"])
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_action_modes(env_id, action_mode):
    env = gym.make(env_id, action_mode=action_mode, **SHORT)
    _check(env)
    if action_mode == "normalized":
        assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    else:
        cs = env.unwrapped.command_spec
        assert env.action_space.low[0] == np.float32(cs.v_min) and env.action_space.high[0] == np.float32(cs.v_max)


@pytest.mark.parametrize("env_id", IDS)
def test_render_modes_pass_the_checker(env_id):
    env = gym.make(env_id, **SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gym_check_env(env.unwrapped)  # also builds the env in every declared render mode
    env.close()


def test_make_and_make_vec_after_import():
    for env_id in IDS:
        env = gym.make(env_id, **SHORT)
        obs, _ = env.reset(seed=1)
        assert env.observation_space.contains(obs)
        env.close()
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **SHORT)
        obs, _ = venv.reset(seed=[1, 2])
        assert obs.shape == (2,) + env.observation_space.shape
        for _ in range(3):
            obs, rew, term, trunc, info = venv.step(venv.action_space.sample())
        assert rew.shape == (2,) and np.all(np.isfinite(rew))
        venv.close()
    register_envs()  # idempotent


def test_unwrapped_exposes_design_data():
    env = gym.make(SB).unwrapped
    assert env.dt == 1e-3 and env.control_dt == 1e-3
    assert env.linear_plant.n_dof == 3 and env.plant_params.n_floors == 3
    assert env.damper.name == "spencer_dyke" and env.command_spec.v_max == 2.25
    names = [name for name, _, _ in env.sensor_layout]
    assert names == ["abs_acc", "drift", "floor_vel", "damper_force", "damper_stroke", "damper_velocity",
                     "ground_acc", "command"]
    assert env.observation_space.shape == (3 + 3 + 3 + 1 + 1 + 1 + 1 + 1,)
    # the output map reproduces the observation from the plant state, forces and inputs
    obs, _ = env.reset(seed=0)
    for _ in range(300):
        obs, *_ = env.step(2.0)
    m = env.output_matrices()
    q = env.plant_state
    F = env.signal("damper_force")[-1]
    w = env.record.data[env.signal("damper_force").shape[0] - 1]
    pred = m["C"] @ q + m["D_F"] @ F + m["D_w"] @ w + m["d0"]
    np.testing.assert_allclose(pred[m["mask"]], obs[m["mask"]], rtol=1e-5, atol=1e-4)
    assert not m["mask"][-1]  # the command row is not a plant output


def test_damper_states_hidden_unless_requested():
    env = QuarterCarEnv(**SHORT)
    assert env.observation_space.shape == (8,)
    assert "damper_states" not in env.sensors
    env2 = QuarterCarEnv(sensors=("travel", "damper_states"), **SHORT)
    assert env2.observation_space.shape == (1 + env2.damper.n_states,)
    obs, _ = env2.reset(seed=0)
    assert obs.shape == (3,)


# ---------------------------------------------------------------------------------------------------------------
# determinism

def test_same_seed_bit_identical_different_seed_differs():
    for kwargs in ({"episode_seconds": 0.3}, {"episode_seconds": 0.3, "sensor_noise": {"sprung_acc": 0.1}}):
        a = QuarterCarEnv(**kwargs)
        b = QuarterCarEnv(**kwargs)
        oa, ra, *_ = _run(a, np.array([0.7]), seed=42)
        ob, rb, *_ = _run(b, np.array([0.7]), seed=42)
        assert np.array_equal(oa, ob) and np.array_equal(ra, rb)
        road_a = a.record.data.copy()
        oc, rc, *_ = _run(a, np.array([0.7]), seed=43)
        assert not np.array_equal(road_a, a.record.data)
        assert not np.array_equal(oa, oc)
    # a second episode from the same env differs (new road), and is reproduced by reseeding
    env = QuarterCarEnv(episode_seconds=0.3)
    env.reset(seed=5)
    r1 = env.record.data.copy()
    env.reset()
    r2 = env.record.data.copy()
    env.reset(seed=5)
    assert np.array_equal(env.record.data, r1) and not np.array_equal(r1, r2)


def test_kanai_tajimi_ground_motion_per_seed():
    env = ShearBuildingEnv(ground_motion="kanai_tajimi", ground_motion_params={"duration": 1.0})
    oa, ra, *_ = _run(env, np.array([1.0]), seed=3)
    ga = env.record.data.copy()
    ob, rb, *_ = _run(env, np.array([1.0]), seed=3)
    assert np.array_equal(oa, ob) and np.array_equal(ra, rb)
    _run(env, np.array([1.0]), seed=4, max_steps=1)
    assert not np.array_equal(ga, env.record.data)
    assert env.record.duration == pytest.approx(1.0)


def test_el_centro_reused_across_episodes():
    env = ShearBuildingEnv()
    env.reset(seed=0)
    rec = env.record
    env.reset(seed=1)
    assert env.record is rec
    # the lab replay: 5x faster than recorded (53.7 s -> 10.7 s)
    assert rec.duration == pytest.approx(10.74, abs=0.02)


# ---------------------------------------------------------------------------------------------------------------
# bad input

@pytest.mark.parametrize("kwargs, match", [
    ({"damper": "no_such_model"}, "unknown damper model 'no_such_model'"),
    ({"damper_preset": "no_such_preset"}, "damper_preset 'no_such_preset'"),
    ({"damper_params": {"nonsense": 1.0}}, "unknown parameter"),
    ({"sensors": ("sprung_acc", "x_ray")}, "unknown sensor 'x_ray'"),
    ({"sensors": ("travel", "travel")}, "must not repeat"),
    ({"plant_params": {"m_s": -300.0}}, "m_s"),
    ({"plant_preset": "set_z"}, "unknown quarter-car preset"),
    ({"road": "cobbles"}, "road: unknown kind 'cobbles'"),
    ({"road_params": {"road_class": "Z"}}, "road_class"),
    ({"road_params": {"colour": "red"}}, r"unknown option\(s\) \['colour'\]"),
    ({"control_dt": 0.0025}, "control_dt must be an integer multiple of dt"),
    ({"action_mode": "fuzzy"}, "action_mode must be"),
    ({"sensor_delay": -1}, "sensor_delay"),
    ({"sensor_noise": {"road": 0.1}}, "not among the chosen sensors"),
    ({"sensor_noise": {"travel": -0.1}}, "sensor_noise"),
    ({"reward_weights": {"speed": 1.0}}, "unknown key"),
    ({"stroke_limit": 0.0}, "stroke_limit"),
    ({"render_mode": "ascii"}, "render_mode"),
])
def test_quarter_car_bad_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        QuarterCarEnv(**kwargs)


def test_building_bad_options(tmp_path):
    with pytest.raises(ValueError, match="masses must all be > 0"):
        ShearBuildingEnv(plant_params={"masses": (98.3, -1.0, 98.3)})
    with pytest.raises(ValueError, match="damper_floors"):
        ShearBuildingEnv(damper_floors=(4,))
    with pytest.raises(ValueError, match="ground_motion must be"):
        ShearBuildingEnv(ground_motion="earthquake")
    with pytest.raises(ValueError, match="time_scale"):
        ShearBuildingEnv(ground_motion_params={"time_scale": -1})
    bad = tmp_path / "bad.AT2"
    bad.write_text("PEER NGA STRONG MOTION DATABASE RECORD\nsome quake\nACCELERATION TIME SERIES IN UNITS OF G\n"
                   "NPTS=    5, DT=   .0100 SEC\n0.1 0.2 0.3\n")
    with pytest.raises(ValueError, match="NPTS = 5 but the file has 3 values"):
        ShearBuildingEnv(ground_motion="at2", ground_motion_params={"path": str(bad)})
    with pytest.raises(ValueError, match="needs ground_motion_params\\['path'\\]"):
        ShearBuildingEnv(ground_motion="at2")


def test_at2_file_is_used(tmp_path):
    good = tmp_path / "good.AT2"
    t = np.arange(400) * 0.01
    acc = 0.1 * np.sin(2 * np.pi * 1.5 * t)
    good.write_text("PEER\nsynthetic\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS=  400, DT=   .0100 SEC\n"
                    + "\n".join(" ".join(f"{v:.6E}" for v in acc[i:i + 5]) for i in range(0, 400, 5)) + "\n")
    env = ShearBuildingEnv(ground_motion="at2", ground_motion_params={"path": str(good)})
    env.reset(seed=0)
    assert env.record.duration == pytest.approx(3.99 * 0.2)  # replayed at the lab speed-up
    assert np.max(np.abs(env.record.channel("xg_ddot"))) == pytest.approx(0.1 * 9.80665, rel=1e-3)


@pytest.mark.parametrize("bad, match", [
    (np.array([1.0, 2.0]), r"shape \(1,\)"),
    (np.zeros((1, 1)), r"shape \(1,\)"),
    ("high", "numeric"),
    (np.array([np.nan]), "finite"),
    (float("inf"), "finite"),
])
def test_bad_actions(bad, match):
    env = QuarterCarEnv(**SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(bad)


def test_bad_action_shape_with_several_dampers():
    env = ShearBuildingEnv(damper_floors=(1, 2), **SHORT)
    env.reset(seed=0)
    assert env.action_space.shape == (2,)
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.step(1.0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([1.0, np.nan]))


def test_step_before_reset_and_after_end():
    env = QuarterCarEnv(episode_seconds=0.002)
    assert env.observation_space.shape == (8,)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0.0)
    env.reset(seed=0)
    env.step(0.0)
    *_, trunc, _ = env.step(0.0)
    assert trunc
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0.0)


# ---------------------------------------------------------------------------------------------------------------
# actions: clipping and mapping

def test_out_of_box_actions_are_clipped():
    env = QuarterCarEnv(sensors=("travel", "command"), **SHORT)
    cs = env.command_spec
    env.reset(seed=0)
    for a, applied in ((10.0, cs.v_max), (-3.0, cs.v_min), ([1.25], 1.25), (np.float32(0.5), 0.5)):
        obs, _, _, _, info = env.step(a)
        assert env.command[0] == pytest.approx(applied, abs=1e-7)
        assert obs[1] == pytest.approx(applied, abs=1e-6)
    env = QuarterCarEnv(action_mode="normalized", **SHORT)
    env.reset(seed=0)
    for a, applied in ((5.0, cs.v_max), (-1.5, cs.v_min), (0.0, 0.5 * (cs.v_min + cs.v_max)), (-1.0, cs.v_min)):
        env.step(np.array([a], dtype=np.float32))
        assert env.command[0] == pytest.approx(applied, abs=1e-7)
    env = ShearBuildingEnv(damper_floors=(1, 2), **SHORT)
    env.reset(seed=0)
    env.step(np.array([9.0, -9.0]))
    np.testing.assert_array_equal(env.command, [2.25, 0.0])


def test_command_is_held_over_the_control_period():
    env = QuarterCarEnv(control_dt=0.005, episode_seconds=0.1)
    assert env.control_dt == pytest.approx(0.005)
    env.reset(seed=0)
    env.step(1.5)
    env.step(0.25)
    cmd = env.signal("command")[:, 0]
    assert cmd.size == 11 and np.all(cmd[1:6] == 1.5) and np.all(cmd[6:11] == 0.25)
    _, _, _, trunc, info = _run(env, 1.0)
    assert trunc and info["t"] == pytest.approx(0.1)


# ---------------------------------------------------------------------------------------------------------------
# sensors

def test_sensor_delay_fifo_and_noise():
    base = QuarterCarEnv(sensors=("travel", "sprung_acc"), episode_seconds=0.05)
    delayed = QuarterCarEnv(sensors=("travel", "sprung_acc"), sensor_delay=3, episode_seconds=0.05)
    o0, *_ = _run(base, 1.0, seed=9)
    o3, *_ = _run(delayed, 1.0, seed=9)
    np.testing.assert_array_equal(o3[3:], o0[:-3])
    np.testing.assert_array_equal(o3[:4], np.repeat(o0[:1], 4, axis=0))
    noisy = QuarterCarEnv(sensors=("travel", "sprung_acc"), sensor_noise={"sprung_acc": 0.2},
                          episode_seconds=0.05)
    on, *_ = _run(noisy, 1.0, seed=9)
    np.testing.assert_array_equal(on[:, 0], o0[:, 0])  # travel is noise-free
    err = on[:, 1] - o0[:, 1]
    assert 0.1 < np.std(err) < 0.3


def test_quarter_car_sensor_values_and_static_equilibrium():
    env = QuarterCarEnv(sensors=("sprung_acc", "travel", "damper_force", "road"), road="bump",
                        road_params={"height": 0.05, "length": 0.5, "speed": 5.0})
    obs, _ = env.reset(seed=0)
    # at rest: no acceleration, no travel, the damper's static (preload) force
    assert obs[0] == pytest.approx(0.0, abs=1e-9) and obs[1] == 0.0
    assert obs[2] == pytest.approx(env.F_static)
    obs_hist, *_ = _run(env, 0.0)
    assert np.max(obs_hist[:, 3]) == pytest.approx(0.05, abs=1e-6)  # the road sensor sees the bump


def test_online_comfort_filter_matches_sosfilt():
    env = QuarterCarEnv(episode_seconds=0.5, control_dt=0.002)
    _run(env, 0.8, seed=2)
    acc = env.signal("sprung_acc")[:, 0]
    online = env.signal("sprung_acc_wk")[:, 0]
    # the online filter starts at the first step (row 0 is the state at rest before it)
    np.testing.assert_allclose(online[1:], scipy.signal.sosfilt(weighting_sos("Wk", env.dt), acc[1:]), rtol=0,
                               atol=1e-12)


# ---------------------------------------------------------------------------------------------------------------
# rewards, termination, truncation, metrics

def _passive_car_mean_squares(env, rows):
    """Mean squares of Wk-weighted sprung acceleration, travel and dynamic tyre load of the conventional passive
    car (the set's dashpot) on the env's current road, simulated independently with ``scipy.signal.lsim``."""
    p = env.plant_params
    ms, mu, ks, kt, ct, c = p.m_s, p.m_u, p.k_s, p.k_t, p.c_t, p.passive_c
    # states z_s, z_u, ż_s, ż_u; inputs z_r, ż_r
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-ks / ms, ks / ms, -c / ms, c / ms],
                  [ks / mu, -(ks + kt) / mu, c / mu, -(c + ct) / mu]])
    B = np.array([[0, 0], [0, 0], [0, 0], [kt / mu, ct / mu]])
    w = env.record.data[:rows]
    t = np.arange(rows) * env.dt
    q0 = np.array([w[0, 0], w[0, 0], w[0, 1], w[0, 1]])
    _, _, X = scipy.signal.lsim((A, B, np.eye(4), np.zeros((4, 2))), w, t, X0=q0)
    acc = X @ A[2] + w @ B[2]
    aw = scipy.signal.sosfilt(weighting_sos("Wk", env.dt), acc)
    travel = X[:, 0] - X[:, 1]
    tyre = kt * (w[:, 0] - X[:, 1]) + ct * (w[:, 1] - X[:, 3])
    return np.mean(aw[1:] ** 2), np.mean(travel[1:] ** 2), np.mean(tyre[1:] ** 2)


def test_quarter_car_reward_definition():
    """r = −∫ Σ w_i h_i² / ⟨h_i²⟩_passive dt over each control period, the passive car simulated apart."""
    env = QuarterCarEnv(episode_seconds=0.2, control_dt=0.004, reward_weights={"travel": 2.0})
    _, rewards, _, trunc, info = _run(env, 0.6, seed=4)
    assert trunc
    aw = env.signal("sprung_acc_wk")[:, 0]
    x = env.signal("travel")[:, 0]
    ft = env.signal("_tyre_load")[:, 0]
    a0, x0, f0 = _passive_car_mean_squares(env, aw.size)
    per_sample = 0.5 * aw ** 2 / a0 + 2.0 * x ** 2 / x0 + 0.25 * ft ** 2 / f0
    expected = -env.dt * per_sample[1:].reshape(-1, 4).sum(axis=1)
    np.testing.assert_allclose(rewards, expected, rtol=1e-6)


def test_the_passive_car_scores_minus_one_per_second():
    """The MR damper replaced by the set's dashpot (a Bingham model with only c0 = passive_c): the reward's
    reference car, so the return is −(episode length in s) on any road."""
    c = QuarterCarEnv(episode_seconds=0.1).plant_params.passive_c
    for road in ({"road_class": "B", "speed": 10.0}, {"road_class": "D", "speed": 25.0}):
        env = QuarterCarEnv(episode_seconds=2.0, road_params=road, damper="bingham",
                            damper_params=dict(fc_a=0.0, fc_b=0.0, c0a=c, c0b=0.0, f0=0.0))
        _, rewards, term, trunc, _ = _run(env, 0.0, seed=7)
        assert trunc and not term
        assert rewards.sum() == pytest.approx(-2.0, rel=2e-3)


@pytest.mark.parametrize("env_id", [QC, SB])
def test_returns_do_not_depend_on_the_control_rate(env_id):
    """A constant command gives the same physics at any control step, hence the same return (to the error
    control's tolerance: the sub-step history restarts with each control period)."""
    ret = {}
    for control_dt in (1e-3, 1e-2):
        env = gym.make(env_id, episode_seconds=1.0, control_dt=control_dt)
        _, rewards, _, trunc, _ = _run(env, 1.0, seed=3)
        assert trunc
        ret[control_dt] = rewards.sum()
    assert ret[1e-3] == pytest.approx(ret[1e-2], rel=1e-4)


def test_quarter_car_episode_metrics_at_truncation():
    env = gym.make(QC, episode_seconds=1.0)
    _, _, term, trunc, info = _run(env, 0.5, seed=0)
    assert trunc and not term
    m = info["episode_metrics"]
    for key in ("acc_weighted_rms", "acc_rms", "acc_vdv", "travel_rms", "travel_peak", "tyre_load_rms",
                "tyre_load_ratio", "damper_force_rms", "duration"):
        assert key in m and np.isfinite(m[key])
    assert m["duration"] == pytest.approx(1.0)
    assert info["t"] == pytest.approx(1.0)


def test_stroke_limit_terminates():
    env = QuarterCarEnv(stroke_limit=1e-3, episode_seconds=5.0)
    _, rewards, term, trunc, info = _run(env, 0.0, seed=0)
    assert term and not trunc
    assert info["termination_reason"] == "stroke_limit"
    assert "episode_metrics" in info and info["episode_metrics"]["travel_peak"] > 1e-3
    assert rewards[-1] < -10 * 5.0  # the termination term: 10 per second of the episode's planned length
    assert np.all(np.isfinite(rewards))


def test_divergence_terminates_with_last_finite_observation():
    env = QuarterCarEnv(**SHORT)
    obs0, _ = env.reset(seed=0)
    obs1, *_ = env.step(0.5)

    d = env.core.driver
    kernel_step = env._kstep

    def boom(*args):  # the compiled step reports a non-finite state at the third physics step
        d.int_state("STATUS")[0] = DIVERGED
        d.int_state("REASON")[0] = 1
        d.int_state("FAIL_STEP")[0] = 2
        return DIVERGED

    env._kstep = boom
    obs2, r, term, trunc, info = env.step(0.5)
    env._kstep = kernel_step
    assert term and not trunc
    assert info["termination_reason"] == ("diverged: damper model 'spencer_dyke': a non-finite state at t = 0.003 s "
                                          "(batch index 0); check the parameters and the input amplitude")
    np.testing.assert_array_equal(obs2, obs1)
    assert np.isfinite(r) and "episode_metrics" in info


def test_building_zero_force_damper_criteria_near_one():
    env = gym.make(SB, damper="bingham", damper_params=ZERO_FORCE)
    _, rewards, term, trunc, info = _run(env, 0.0, seed=0)
    assert trunc and not term
    m = info["episode_metrics"]
    for j in ("J1", "J2", "J3", "J4", "J5", "J6"):
        assert m[j] == pytest.approx(1.0, abs=0.02), j
    for key in ("drift_peak", "acc_rms", "base_shear_peak", "force_over_weight", "stroke_over_disp"):
        assert np.isfinite(m[key])
    # rewards are normalised by the uncontrolled building: -1 per second
    assert rewards.sum() == pytest.approx(-info["episode_metrics"]["duration"], rel=0.02)


def test_building_damper_reduces_response():
    env = ShearBuildingEnv()
    _, rewards, _, trunc, info = _run(env, 2.25, seed=0)
    m = info["episode_metrics"]
    assert trunc and m["J1"] < 0.6 and m["J4"] < 0.6 and rewards.sum() > -0.6 * m["duration"]


def test_n_storey_building_with_several_dampers():
    params = ShearBuildingParams.uniform(5, 1000.0, 2e6, damper_floors=(1, 2))
    env = gym.make(SB, plant_params=params, ground_motion="kanai_tajimi",
                   ground_motion_params={"duration": 2.0, "pga": 2.0}, sensors=("drift", "damper_force"))
    _check(env)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5 + 2,) and env.action_space.shape == (2,)
    assert "(time x1," in env.unwrapped.record.name  # a user's building is not replayed as a lab model
    _, _, _, trunc, info = _run(env, np.array([2.25, 0.0]), seed=0)
    assert trunc and env.unwrapped.damper_force.shape == (2,)


def test_road_from_record_and_sweep():
    rec = sine_sweep(0.01, 1.0, 5.0, 0.5, dt=5e-4)
    env = QuarterCarEnv(road=rec)
    env.reset(seed=0)
    assert env.record.dt == pytest.approx(1e-3) and env.record.duration == pytest.approx(0.5)
    with pytest.raises(ValueError, match="z_r"):
        QuarterCarEnv(road=Record(1e-3, np.zeros((10, 1)), ("xg_ddot",), ("m/s^2",)))
    env = QuarterCarEnv(road="sine_sweep", road_params={"f_end": 8.0}, episode_seconds=0.5)
    _, _, _, trunc, _ = _run(env, 0.0)
    assert trunc


def test_road_from_csv(tmp_path):
    x = np.arange(0.0, 20.0, 0.05)
    path = tmp_path / "profile.csv"
    path.write_text("x [m],z [mm]\n" + "\n".join(f"{a:.3f},{5 * np.sin(a):.4f}" for a in x) + "\n")
    env = QuarterCarEnv(road="csv", road_params={"path": str(path), "height_column": "z", "distance_column": "x",
                                                 "speed": 10.0}, sensors=("road",))
    obs, *_ = _run(env, 0.0)
    assert env.record.duration == pytest.approx(x[-1] / 10.0, abs=1e-3)
    assert np.max(obs[:, 0]) == pytest.approx(0.005, rel=0.01)
    assert env.assembly.options["road_params"]["path"] == str(path)
    with pytest.raises(ValueError, match="height_column"):
        QuarterCarEnv(road="csv", road_params={"path": str(path)})


def test_peer_record_by_name():
    env = ShearBuildingEnv(ground_motion="peer:loma_prieta_1989_corralitos_000",
                           ground_motion_params={"amplitude_scale": 0.5}, episode_seconds=1.0)
    env.reset(seed=0)
    assert "Loma Prieta" in env.record.name or "LOMAP" in env.record.name
    _, _, _, trunc, info = _run(env, 1.0)
    assert trunc and np.isfinite(info["episode_metrics"]["J1"])
    with pytest.raises(ValueError, match="name must be one of"):
        ShearBuildingEnv(ground_motion="peer:atlantis_2024")


def test_damper_instance_and_preset_fallback():
    d = make_damper("bouc_wen", "automotive")
    env = QuarterCarEnv(damper=d, **SHORT)
    assert env.damper is d
    # bingham has no "automotive" preset: the quarter car falls back to its default preset
    env = QuarterCarEnv(damper="bingham", **SHORT)
    assert env.command_spec.v_max == make_damper("bingham").command.v_max


# ---------------------------------------------------------------------------------------------------------------
# rendering

@pytest.mark.parametrize("cls", [QuarterCarEnv, ShearBuildingEnv])
def test_render_rgb_array(cls):
    env = cls(render_mode="rgb_array", episode_seconds=1.0)
    env.reset(seed=0)
    for k in range(300):
        env.step(2.0 if k % 100 < 50 else 0.0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.shape[0] > 100 and frame.shape[1] > 100
    assert frame.std() > 5
    frame2 = env.render()
    assert frame2.shape == frame.shape
    env.close()
    env.close()


def test_render_human_is_non_blocking():
    env = QuarterCarEnv(render_mode="human", episode_seconds=0.2)
    _run(env, 1.0)
    assert env._renderer is not None
    env.close()
    assert env._renderer is None


def test_the_buildings_record_time_scale_is_a_field_of_its_preset_not_a_type_rule():
    """The lab model replays records 5× faster because its preset says so (``record_time_scale`` 0.2), whether the
    building is named or passed as its ``ShearBuildingParams`` (an isinstance rule used to switch a passed preset to
    1×, silently); a building that does not set it replays records at their own rate (issue 38 item 4)."""
    from mrd_env.plants import THREE_STOREY, ShearBuildingParams

    named = gym.make("mrd_env/ShearBuildingPhysical-v0", episode_seconds=0.5).unwrapped
    passed = gym.make("mrd_env/ShearBuildingPhysical-v0", plant_params=THREE_STOREY, episode_seconds=0.5).unwrapped
    assert named.assembly.plant_params.record_time_scale == passed.assembly.plant_params.record_time_scale == 0.2
    (o1, _), (o2, _) = named.reset(seed=0), passed.reset(seed=0)
    assert np.array_equal(o1, o2)
    for _ in range(100):
        s1, s2 = named.step(named.action_space.high), passed.step(passed.action_space.high)
        assert np.array_equal(s1[0], s2[0]) and s1[1] == s2[1]
    full_rate = ShearBuildingParams.uniform(3, 100.0, 1e6)
    assert full_rate.record_time_scale == 1.0
    with pytest.raises(ValueError, match="record_time_scale must be a number in"):
        ShearBuildingParams(**{**THREE_STOREY.__dict__, "record_time_scale": 0.0})
