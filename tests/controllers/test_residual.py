"""Residual policies and the paired baseline (issue 23): an agent with zero output is its law exactly, a residual
agent trains and loads through the tooling, paired rewards are the agent's minus the law's on the same
disturbance, and bad options are refused before any training."""
import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from controllers import load_agent, make_controller
from controllers.residual import Residual, ResidualController
from controllers.training_wrappers import PairedBaselineVecEnv, ResidualVecEnv
from experiments.cli import main
from experiments.training.trainers import env_options, train_one
from mrd_env.envs.sb3 import make_sb3_vec_env
from experiments.common.plants import profile

CAR = "mrd_env/QuarterCarPhysical-v0"


class Constant:
    """A stand-in agent: the same correction for every observation."""

    def __init__(self, value):
        self.value = value

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(obs)
        return np.full(obs.shape[:-1] + (1,), self.value, dtype=np.float32), None


def _kw(**extra):
    return {**env_options(profile("quarter_car")), "episode_seconds": 0.5, **extra}


@pytest.mark.parametrize("mode", ["normalized", "physical"])
def test_a_zero_correction_is_the_law_step_for_step(mode):
    kw = _kw(action_mode=mode)
    rewards = []
    for make in (lambda e: make_controller("skyhook_continuous", e),
                 lambda e: ResidualController(e, Constant(0.0), "skyhook_continuous", scale=0.7)):
        env = gym.make(CAR, **kw)
        ctrl = make(env)
        obs, _ = env.reset(seed=3)
        out, done = [], False
        while not done:
            obs, r, term, trunc, _ = env.step(ctrl.predict(obs)[0])
            out.append(r)
            done = term or trunc
        rewards.append(np.array(out))
    np.testing.assert_array_equal(rewards[0], rewards[1])


def test_a_correction_moves_the_command_by_its_share_of_the_range():
    env = gym.make(CAR, **_kw(action_mode="physical"))
    obs, _ = env.reset(seed=0)
    res = Residual(env, "passive_off", scale=0.5)
    spec = env.unwrapped.command_spec
    span = spec.v_max - spec.v_min
    np.testing.assert_allclose(res.actions(obs, [0.4]), [spec.v_min + 0.2 * span], rtol=1e-6)
    # reflected at the range's end: -0.2 of the range below u_min acts as +0.2 above it
    np.testing.assert_allclose(res.actions(obs, [-0.4]), [spec.v_min + 0.2 * span], rtol=1e-6)


def test_clipped_at_the_ends_the_outward_corrections_do_nothing_and_the_inward_ones_act():
    """A law at its upper end (passive-on): reflected, +a and −a give the same lower command (the return is even in
    the correction, so its gradient at the law vanishes); clipped, +a keeps the law's command and −a lowers it."""
    env = gym.make(CAR, **_kw(action_mode="physical"))
    obs, _ = env.reset(seed=0)
    spec = env.unwrapped.command_spec
    span = spec.v_max - spec.v_min
    reflect = Residual(env, "passive_on", scale=0.5)
    clip = Residual(env, "passive_on", scale=0.5, boundary="clip")
    np.testing.assert_allclose(reflect.actions(obs, [0.4]), reflect.actions(obs, [-0.4]), rtol=1e-6)
    np.testing.assert_allclose(reflect.actions(obs, [0.4]), [spec.v_max - 0.2 * span], rtol=1e-6)
    np.testing.assert_allclose(clip.actions(obs, [0.4]), [spec.v_max], rtol=1e-6)
    np.testing.assert_allclose(clip.actions(obs, [-0.4]), [spec.v_max - 0.2 * span], rtol=1e-6)
    # inside the range the two agree
    low = Residual(env, "passive_off", scale=0.5, boundary="clip")
    np.testing.assert_allclose(low.actions(obs, [0.4]), [spec.v_min + 0.2 * span], rtol=1e-6)
    np.testing.assert_allclose(low.actions(obs, [-0.4]), [spec.v_min], rtol=1e-6)
    # a saved agent's residual entry (agent.json) keeps its boundary when it is loaded
    from controllers.agents import agent_controller
    for a, u in ((0.4, spec.v_max), (-0.4, spec.v_max - 0.2 * span)):
        ctrl = agent_controller(env, Constant(a), {"law": "passive_on", "scale": 0.5, "boundary": "clip"})
        np.testing.assert_allclose(ctrl.predict(obs)[0], [u], rtol=1e-6)


def test_a_bad_boundary_is_refused_by_name():
    env = gym.make(CAR, **_kw())
    with pytest.raises(ValueError, match=r"residual boundary must be one of \['reflect', 'clip'\], got 'wrap'"):
        Residual(env, "passive_on", boundary="wrap")
    from experiments.training.trainers import residual_spec
    with pytest.raises(ValueError, match="boundary must be one of"):
        residual_spec({"law": "passive_on", "boundary": "wrap"})
    assert residual_spec({"law": "passive_on", "boundary": "clip"})["boundary"] == "clip"


def _paired_run(correction, steps, seed=0):
    venv = ResidualVecEnv(make_sb3_vec_env(CAR, n_envs=3, seed=seed, **_kw()), "skyhook_continuous")
    venv = PairedBaselineVecEnv(venv, "skyhook_continuous")
    venv.reset()
    paired, raw, done_at = np.zeros(3), [], []
    for k in range(steps):
        _, r, d, infos = venv.step(np.full((3, 1), correction, np.float32))
        paired += r
        for i in np.flatnonzero(d):
            raw.append(infos[i]["episode"]["r"])
            done_at.append(k)
    return paired, np.array(raw)


def test_paired_rewards_are_the_agent_minus_the_law_on_the_same_road():
    # a zero correction is the law: every paired reward is exactly 0, across automatic resets
    paired, raw = _paired_run(0.0, 120)
    assert np.all(paired == 0.0) and raw.size == 6 and np.all(raw < 0)   # the episode infos keep the raw return
    # a constant correction: paired return = its raw return - the law's raw return on the same roads
    paired, raw = _paired_run(0.3, 50)
    _, law = _paired_run(0.0, 50)
    np.testing.assert_allclose(paired, raw - law, rtol=1e-4, atol=1e-5)
    assert np.all(paired < 0)   # a firmer command than skyhook's on every road costs (skyhook is near-optimal)


def test_a_residual_agent_trains_starts_at_its_law_and_loads(tmp_path):
    kw = _kw()
    run = train_one(profile("quarter_car"), "ppo", 0, out=tmp_path, timesteps=64, env_kwargs=kw, eval_freq=10_000,
                    eval_episodes=1, hyper={"n_steps": 32, "batch_size": 32, "n_envs": 2,
                                            "residual": {"law": "skyhook_continuous", "scale": 0.5},
                                            "paired_baseline": "skyhook_continuous"})
    assert run.name == "quarter_car_ppo-residual-paired_s0"
    # its first validation, before any update, is the law's own validation return
    import csv

    from experiments.commands.train import law_references
    first = float(next(csv.DictReader((run / "validation.csv").open()))["validation_return"])
    assert first == law_references(profile("quarter_car"), kw, 1)["skyhook_continuous @ 10 ms"]
    # the saved agent acts as its law plus its correction
    agent = load_agent(run)
    env = gym.make(CAR, **kw)
    ctrl = agent.bind(env)
    assert isinstance(ctrl, ResidualController)
    rule = Residual(env, "skyhook_continuous", scale=0.5)
    obs, _ = env.reset(seed=5)
    for _ in range(20):
        a = ctrl.predict(obs)[0]
        u_law = rule.law_command(obs)
        np.testing.assert_array_equal(a, rule.combine(u_law, agent.predict(rule.observe(obs, u_law))[0]))
        obs, *_ = env.step(a)


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_residual_agents_start_at_their_law(algo):
    from controllers.agents import _algorithm
    from controllers.residual import zero_policy_output
    from experiments.training.trainers import ALGOS

    venv = ResidualVecEnv(make_sb3_vec_env(CAR, n_envs=1, seed=0, **_kw()), "skyhook_continuous")
    model = _algorithm(ALGOS[algo])("MlpPolicy", venv, device="cpu", learning_starts=10)
    zero_policy_output(model)
    obs = venv.reset()
    assert np.all(model.predict(obs, deterministic=True)[0] == 0.0)


@pytest.mark.parametrize("args, message", [
    (["--residual", "banana"], "residual must be one of"),
    (["--paired-baseline", "banana"], "paired_baseline must be one of"),
    (["--residual", "skyhook_continuous", "--residual-scale", "2"], "scale must be a number in (0, 1]"),
    (["--residual-scale", "0.5"], "--residual-scale needs a residual"),
    (["--residual-hold", "10"], "--residual-hold needs a residual"),
    (["--residual", "none", "--residual-hold", "10"], "--residual-hold applies to a residual"),
    (["--residual", "skyhook_continuous", "--residual-hold", "0"], "hold must be an int >= 1"),
    (["--plant", "shear_building", "--residual", "groundhook"], "does not apply"),
    (["--algo", "cmaes", "--residual", "skyhook_continuous"], "not to cmaes"),
    (["--plant", "shear_building", "--preview"], "road preview is a sensor of the quarter car"),
])
def test_bad_residual_options_are_one_line_before_training(args, message, capsys, tmp_path):
    assert main(["train", *args, "--out", str(tmp_path), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not any(tmp_path.iterdir())


def test_a_preview_agent_with_history_keeps_what_it_sees_through_evaluation(tmp_path):
    """--preview and --history reach the agent's record, and an evaluation rebuilds that observation."""
    from experiments.common.evaluation import evaluate_batch
    from experiments.common.scenarios import held_out_scenarios, preview_options

    kw = {**preview_options(profile("quarter_car"), _kw(history=2))}
    run = train_one(profile("quarter_car"), "ppo", 0, out=tmp_path, timesteps=64, env_kwargs=kw, eval_freq=10_000,
                    eval_episodes=1, hyper={"n_steps": 32, "batch_size": 32, "n_envs": 2,
                                            "residual": "skyhook_continuous"})
    assert run.name == "quarter_car_ppo-residual-h2-preview_s0"
    agent = load_agent(run)
    assert agent.name == "PPO residual preview s0"   # what tables and legends call it
    seen = agent.observation_kwargs
    assert tuple(seen["preview"]) == tuple(kw["preview"]) and "road_preview" in seen["sensors"] and seen["history"] == 2
    sc = held_out_scenarios(profile("quarter_car"), quick=True)[0]
    eps = evaluate_batch(lambda v: agent.bind(v), sc, "", name=agent.name, **seen, episode_seconds=0.3)
    assert len(eps) == 1 and np.isfinite(eps[0].episode_return)


@pytest.mark.parametrize("law", ["skyhook_continuous", "clipped_optimal", "groundhook"])
def test_a_law_reads_the_newest_measurement_of_a_stacked_history(law):
    """With history > 1 a law acts as it does on the plain observation (it found the oldest block before)."""
    out = []
    for history in (1, 3):
        env = gym.make(CAR, **_kw(history=history))
        ctrl = make_controller(law, env)
        obs, _ = env.reset(seed=2)
        rewards = []
        for _ in range(30):
            obs, r, *_ = env.step(ctrl.predict(obs)[0])
            rewards.append(r)
        out.append(rewards)
    np.testing.assert_array_equal(out[0], out[1])


def test_the_twin_meets_the_agents_next_road_whoever_ends_first():
    """With a tight stroke limit the agent's episodes and the reference's end at different steps (either first);
    after each of the agent's episodes the twin starts the same road as the agent's next one."""
    kw = _kw(episode_seconds=1.0, stroke_limit=0.02)
    venv = PairedBaselineVecEnv(ResidualVecEnv(make_sb3_vec_env(CAR, n_envs=4, seed=1, **kw), "skyhook_continuous"),
                                "skyhook_continuous")
    venv.reset()
    native = venv._native
    corrections = np.array([[1.0], [-1.0], [0.5], [0.0]], np.float32)
    rng = np.random.default_rng(0)
    twin_first = agent_ends = 0
    for _ in range(300):
        waiting = venv._waiting.copy()
        _, _, dones, infos = venv.step(corrections * (rng.random((4, 1)) < 0.5))
        twin_first += int((venv._waiting & ~waiting).sum())
        for b in np.flatnonzero(dones):
            agent_ends += 1
            np.testing.assert_array_equal(native.core.episodes[b].record.data,
                                          venv.twin.core.episodes[b].record.data)
            assert not venv._waiting[b]
    assert twin_first > 0 and agent_ends > twin_first   # both orders happened


def test_an_agents_environment_options_survive_its_json(tmp_path):
    """agent.json keeps tuples (ranges drawn from) apart from lists (choices): env_kwargs rebuilds the training
    distribution, for a new agent and for the shipped ones."""
    from controllers import shipped_agents
    from controllers.agents import agent_files, write_agent

    kw = env_options(profile("quarter_car"))
    assert isinstance(kw["road"]["speed"], tuple) and isinstance(kw["road"]["road_class"], list)
    write_agent(tmp_path, {"plant": "quarter_car", "env_id": CAR, "algo": "PPO", "env_kwargs": kw,
                           "model": "agent.json"})  # any file of the folder stands in for the model here
    assert agent_files(tmp_path)[1]["env_kwargs"] == kw
    for folder in shipped_agents():
        agent = load_agent(folder)
        assert agent.env_kwargs == {**env_options(profile(agent.plant)), **agent.observation_kwargs}


class Counter:
    """A stand-in recurrent agent: its state counts the steps of each row since its episode began."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        n = np.zeros(len(obs)) if state is None else state.copy()
        if episode_start is not None:
            n[np.asarray(episode_start, bool)] = 0
        return np.zeros((len(obs), 1), np.float32), n + 1


def test_reset_of_some_rows_keeps_the_other_rows_memory():
    venv = gym.make_vec(CAR, num_envs=3, vectorization_mode="vector_entry_point", **_kw())
    ctrl = ResidualController(venv, Counter(), "skyhook_continuous")
    obs, _ = venv.reset(seed=[1, 2, 3])
    for _ in range(4):
        _, state = ctrl.predict(obs)
    ctrl.reset(np.array([False, True, False]))
    np.testing.assert_array_equal(ctrl.predict(obs)[1], [5, 1, 5])
    ctrl.reset()
    np.testing.assert_array_equal(ctrl.predict(obs)[1], [1, 1, 1])


# --- a correction held over the law at its own rate (hold > 1) -----------------------------------------------------
class Linear:
    """A stand-in agent whose correction follows its observation (so that when it is asked matters), and that
    counts how often it is asked."""

    calls = 0

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        Linear.calls += 1
        obs = np.asarray(obs)
        return np.tanh(0.3 * obs[..., :1] - 0.1 * obs[..., -1:]).astype(np.float32), None


def _held(n_envs, hold, seed=0, law="skyhook_continuous", paired=None, **extra):
    kw = _kw(control_dt=0.01 / hold, **extra)
    venv = ResidualVecEnv(make_sb3_vec_env(CAR, n_envs=n_envs, seed=seed, **kw), law, hold=hold)
    return PairedBaselineVecEnv(venv, paired) if paired else venv


def test_reset_of_some_rows_restarts_their_hold_as_episode_start_does():
    """reset(mask) and episode_start mark a new episode alike: the masked row is asked for a new correction at its
    next step, the others keep the one they hold."""
    venv = gym.make_vec(CAR, num_envs=3, vectorization_mode="vector_entry_point", **_kw())
    obs, _ = venv.reset(seed=[1, 2, 3])
    out = []
    for how in ("reset", "episode_start"):
        ctrl = ResidualController(venv, Linear(), "skyhook_continuous", hold=3)
        for _ in range(2):
            ctrl.predict(obs)
        calls = Linear.calls
        mask = np.array([True, False, False])
        if how == "reset":
            ctrl.reset(mask)
            action, _ = ctrl.predict(obs)
        else:
            action, _ = ctrl.predict(obs, episode_start=mask)
        assert Linear.calls == calls + 1, how  # row 0 is due again; rows 1 and 2 are not
        np.testing.assert_array_equal(ctrl._k, [1, 3, 3])
        out.append(action)
    np.testing.assert_array_equal(out[0], out[1])


def test_a_held_zero_correction_is_the_law_at_its_own_rate():
    """hold 10 at 1 ms: an agent's step is 10 of the law's, its reward their sum; a zero correction is the law at
    1 ms exactly, and paired rewards against that law are exactly 0 across automatic resets."""
    venv = _held(2, 10, seed=4)
    venv.reset()
    held = []
    for _ in range(50):  # one 0.5 s episode of 50 agent steps each
        _, r, d, infos = venv.step(np.zeros((2, 1), np.float32))
        held.append(r)
        assert all(i["held_steps"] == 10 for i in infos)
    assert d.all()
    law_env = gym.make_vec(CAR, num_envs=2, vectorization_mode="vector_entry_point", **_kw(control_dt=0.001))
    law = make_controller("skyhook_continuous", law_env)
    obs, _ = law_env.reset(seed=[4, 5])
    ret = np.zeros(2)
    for _ in range(500):
        obs, r, *_ = law_env.step(law.predict(obs)[0])
        ret += r
    np.testing.assert_allclose(np.sum(held, axis=0), ret, rtol=1e-5)

    paired = _held(3, 10, paired="skyhook_continuous")
    paired.reset()
    for _ in range(120):
        _, r, _, infos = paired.step(np.zeros((3, 1), np.float32))
        assert np.all(r == 0.0) and all(i["paired"] for i in infos)


def test_a_held_residual_controller_acts_as_the_agent_was_trained():
    """The controller of a held residual agent (evaluation) and the training wrapper (training) give the same
    commands and returns: the agent is asked every 10th step, its correction held while the law follows (no
    stroke limit here: an episode that ends part-way through a step shortens that step for every environment)."""
    venv = _held(2, 10, seed=7, stroke_limit=1.0)
    obs = venv.reset()
    Linear.calls = 0
    trained = np.zeros(2)
    for _ in range(50):
        obs, r, d, _ = venv.step(Linear().predict(obs)[0])
        trained += r
    assert Linear.calls == 50
    env = gym.make_vec(CAR, num_envs=2, vectorization_mode="vector_entry_point",
                       **_kw(control_dt=0.001, stroke_limit=1.0))
    ctrl = ResidualController(env, Linear(), "skyhook_continuous", hold=10)
    obs, _ = env.reset(seed=[7, 8])
    ctrl.reset()
    Linear.calls = 0
    evaluated = np.zeros(2)
    for _ in range(500):
        obs, r, *_ = env.step(ctrl.predict(obs)[0])
        evaluated += r
    assert Linear.calls == 50
    np.testing.assert_allclose(evaluated, trained, rtol=1e-5)
    plain = ResidualController(env, Linear(), "skyhook_continuous")  # asked at every 1 ms step: another policy
    obs, _ = env.reset(seed=[7, 8])
    other = np.zeros(2)
    for _ in range(500):
        obs, r, *_ = env.step(plain.predict(obs)[0])
        other += r
    assert not np.allclose(other, evaluated, rtol=1e-3)


def test_held_the_twin_meets_the_agents_next_road_whoever_ends_first():
    """As test_the_twin_meets_the_agents_next_road_whoever_ends_first, with the agent's step 10 of the law's and
    episodes that end at a stroke limit part-way through an agent's step."""
    venv = _held(4, 10, seed=1, paired="skyhook_continuous", episode_seconds=1.0, stroke_limit=0.02)
    venv.reset()
    native = venv._native
    corrections = np.array([[1.0], [-1.0], [0.5], [0.0]], np.float32)
    rng = np.random.default_rng(0)
    twin_first = agent_ends = short = 0
    for _ in range(300):
        waiting = venv._waiting.copy()
        _, _, dones, infos = venv.step(corrections * (rng.random((4, 1)) < 0.5))
        twin_first += int((venv._waiting & ~waiting).sum())
        short += infos[0]["held_steps"] < 10
        for b in np.flatnonzero(dones):
            agent_ends += 1
            np.testing.assert_array_equal(native.core.episodes[b].record.data,
                                          venv.twin.core.episodes[b].record.data)
            np.testing.assert_array_equal(native.core.obs[b], venv.twin.core.obs[b])  # both at the episode's start
            assert not venv._waiting[b]
    assert twin_first > 0 and agent_ends > twin_first and short > 0


def test_a_bad_hold_is_refused_by_name(capsys, tmp_path):
    from experiments.training.trainers import residual_spec

    for bad in (0, 2.5, True):
        with pytest.raises(ValueError, match="hold must be an int >= 1"):
            residual_spec({"law": "skyhook_continuous", "hold": bad})
        with pytest.raises(ValueError, match="hold must be an int >= 1"):
            ResidualController(gym.make(CAR, **_kw()), Constant(0.0), "skyhook_continuous", hold=bad)
    assert main(["train", "--set", "residual={law: skyhook_continuous, hold: 0}", "--out", str(tmp_path),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "hold must be an int >= 1" in err and err.count("\n") == 1 and not any(tmp_path.iterdir())


def test_a_held_residual_agent_trains_starts_at_its_law_at_1ms_and_loads(tmp_path):
    """mrd-env train's path with a hold: the run is named for it, its first validation is the law at 1 ms, and the
    saved agent binds to a 1 ms environment as a held residual controller."""
    import csv

    from experiments.commands.train import law_references

    kw = _kw(control_dt=0.001)
    run = train_one(profile("quarter_car"), "ppo", 0, out=tmp_path, timesteps=64, env_kwargs=kw, eval_freq=10_000,
                    eval_episodes=1, hyper={"n_steps": 32, "batch_size": 32, "n_envs": 2,
                                            "residual": {"law": "skyhook_continuous", "scale": 0.5, "hold": 10},
                                            "paired_baseline": "skyhook_continuous"})
    assert run.name == "quarter_car_ppo-residual-hold10-paired_s0"
    first = float(next(csv.DictReader((run / "validation.csv").open()))["validation_return"])
    assert first == law_references(profile("quarter_car"), kw, 1)["skyhook_continuous @ 1 ms"]
    ctrl = load_agent(run).bind(gym.make(CAR, **kw))
    assert isinstance(ctrl, ResidualController) and ctrl.hold == 10
    with pytest.raises(ValueError, match="trained at 0.001 s"):
        load_agent(run).bind(gym.make(CAR, **_kw()))


def test_residual_hold_from_the_cli_holds_the_yamls_residual(tmp_path):
    """--residual-hold sets the hold of the YAML's residual (its law and scale kept), and the agent records it."""
    import json
    from pathlib import Path

    args = ["train", "--plant", "quarter_car", "--algo", "ppo", "--hyperparams",
            str(Path(__file__).parents[2] / "experiments" / "hyperparams" / "ppo-residual.yml"), "--residual-hold",
            "10", "--control-dt", "0.001",
            "--timesteps", "64", "--set", "n_envs=2", "--set", "n_steps=32", "--set", "batch_size=32",
            "--eval-freq", "0", "--seeds", "0", "--out", str(tmp_path), "--no-progress"]
    assert main(args) == 0
    meta = json.loads((tmp_path / "quarter_car_ppo-residual-hold10-paired_s0" / "agent.json").read_text())
    assert meta["residual"] == {"law": "skyhook_continuous", "scale": 0.5, "hold": 10}
    assert meta["env_kwargs"]["control_dt"] == 0.001
