"""The code-free agent format (issue 36): every agent's policy as arrays plus a JSON description of its network,
loaded without pickle and acting as the SB3 model it came from, bit for bit; digests; atomic saves; the residual
agent's message (issue 37)."""
import json
import shutil
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from controllers.agents import (AgentDigestError, ObservationNormalizer, TrustedCodeWarning, agent_digest,
                                export_agent, load_agent, same_actions, save_agent, shipped_agents, write_agent)
from experiments.scripts.probe_agent_kill import stub_env
from experiments.common.plants import profile

sb3 = pytest.importorskip("stable_baselines3")
pytest.importorskip("safetensors")
REFERENCE = Path(__file__).parents[1] / "data" / "shipped_agent_actions.npz"
CAR = "mrd_env/QuarterCarPhysical-v0"
N_OBS = 8  # the quarter car's default observation


def Stub():
    """A stand-in environment with the quarter car's spaces (the policies only need the spaces)."""
    return stub_env(N_OBS)


@pytest.mark.parametrize("name", [p.name for p in shipped_agents()])
def test_shipped_agents_act_as_the_models_they_were_exported_from(name):
    """The reference actions were computed from the SB3 models (their model.zip, as trained) and the CMA-ES networks
    before the export (experiments/scripts/export_agent.py --reference), on an AVX2 machine: bit for bit there. On
    another instruction set torch's float32 kernels round differently (an AVX-512 machine moved the PPO agents'
    actions by up to 6e-8, two float32 ulps), so the check is float32 rounding: 16 ulps of the largest action, far
    below any difference a wrong weight, layer or scaling makes."""
    agent = load_agent(Path(shipped_agents()[0]).parent / name)
    with np.load(REFERENCE) as ref:
        obs, actions = ref[f"{name}__obs"], ref[f"{name}__actions"]
    scale = float(np.abs(actions).max())
    assert scale > 0
    np.testing.assert_allclose(np.asarray(agent.predict(obs)[0]), actions, rtol=0,
                               atol=16 * np.finfo(np.float32).eps * scale)


def test_shipped_folders_carry_no_code_and_every_file_is_packaged():
    import fnmatch
    import tomllib

    root = Path(__file__).parents[2]
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["controllers"]
    for folder in shipped_agents():
        meta = json.loads((folder / "agent.json").read_text())
        assert meta["network"]["class"] in ("ActorCriticPolicy", "MLPPolicy")
        assert sorted(meta["files"]) == sorted([meta["model"], meta["normalization"]])
        for f in folder.iterdir():
            assert f.suffix not in (".zip", ".pkl", ".pt", ".pth"), f
            assert any(fnmatch.fnmatch(f"agents/{folder.name}/{f.name}", g) for g in globs), f


def _models():
    from sb3_contrib import ARS, TQC, RecurrentPPO
    from stable_baselines3 import A2C, PPO, SAC, TD3

    return {
        "PPO": lambda: PPO("MlpPolicy", Stub(), device="cpu", seed=1, n_steps=64, batch_size=64,
                           policy_kwargs={"net_arch": {"pi": [16, 16], "vf": [8]}, "log_std_init": -2.0}),
        "A2C": lambda: A2C("MlpPolicy", Stub(), device="cpu", seed=1, policy_kwargs={"net_arch": [16]}),
        "SAC": lambda: SAC("MlpPolicy", Stub(), device="cpu", seed=1, policy_kwargs={"net_arch": [16, 16]}),
        "TD3": lambda: TD3("MlpPolicy", Stub(), device="cpu", seed=1, policy_kwargs={"net_arch": [16, 8]}),
        "TQC": lambda: TQC("MlpPolicy", Stub(), device="cpu", seed=1,
                           policy_kwargs={"net_arch": [16], "n_quantiles": 5}),
        "RecurrentPPO": lambda: RecurrentPPO("MlpLstmPolicy", Stub(), device="cpu", seed=1, n_steps=64, batch_size=64,
                                             policy_kwargs={"lstm_hidden_size": 8, "net_arch": [16]}),
        "ARS": lambda: ARS("LinearPolicy", Stub(), device="cpu", seed=1),
    }


def _jiggle(model):
    """Weights away from their initial values (a zero-initialised output layer would hide a wrong network)."""
    import torch

    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        for p in model.policy.parameters():
            p.add_(0.1 * torch.randn(p.shape, generator=g))


META = {"plant": "quarter_car", "env_id": CAR, "env_kwargs": {}}


@pytest.mark.parametrize("algo", ["PPO", "A2C", "SAC", "TD3", "TQC", "RecurrentPPO", "ARS"])
def test_every_algorithm_family_round_trips_bit_for_bit(tmp_path, algo):
    """Saved code-free, loaded: the actions of the SB3 model itself on the normalised observations (a recurrent
    policy over successive steps, its state carried and reset at episode starts); the SB3 zip of the same model
    loads only with trust and acts the same; export_agent converts it."""
    model = _models()[algo]()
    _jiggle(model)
    norm = ObservationNormalizer(np.linspace(-1, 1, N_OBS), np.linspace(0.5, 2, N_OBS))
    meta = {**META, "algo": algo, "recurrent": algo == "RecurrentPPO"}
    save_agent(tmp_path / "free", meta, policy=model.policy, normalizer=norm, sb3_model=model)
    agent = load_agent(tmp_path / "free")
    assert agent.meta["network"]["class"] == type(model.policy).__name__ and agent.model.algo == algo
    rng = np.random.default_rng(0)
    obs = rng.normal(0, 2, (40, N_OBS))
    state = ref_state = None
    for step in range(4):
        start = np.array([step == 0 or k % 7 == step for k in range(40)])
        kw = {"episode_start": start} if algo == "RecurrentPPO" else {}
        a, state = agent.predict(obs + step, state=state, **kw)
        ref, ref_state = model.predict(norm(obs + step).astype(np.float32), state=ref_state, deterministic=True,
                                       **kw)
        np.testing.assert_array_equal(a, ref)
        if algo == "RecurrentPPO":
            for x, y in zip(state, ref_state):
                np.testing.assert_array_equal(x, y)
    # SB3's zip: trusted only, the same actions; converted once, code-free again
    shutil.copytree(tmp_path / "free", tmp_path / "zip")
    z = json.loads((tmp_path / "zip" / "agent.json").read_text())
    (tmp_path / "zip" / "agent.json").write_text(json.dumps({**z, "model": "model.zip", "network": None,
                                                              "files": None}))
    with pytest.raises(ValueError, match="--trust-agent"):
        load_agent(tmp_path / "zip")
    with pytest.warns(TrustedCodeWarning, match="can run any code"):
        trusted = load_agent(tmp_path / "zip", trust=True)
    assert same_actions(trusted, load_agent(tmp_path / "free"))
    with pytest.warns(TrustedCodeWarning):
        export_agent(tmp_path / "zip", tmp_path / "exported", trust=True)
    exported = load_agent(tmp_path / "exported")
    assert same_actions(exported, agent) and not (tmp_path / "exported" / "model.zip").exists()


def test_off_policy_agents_keep_their_critics_for_the_tools_that_probe_them(tmp_path):
    """probe_critic_direction reads agent.model.actor and agent.model.critic, as on an SB3 model."""
    import torch

    model = _models()["TD3"]()
    _jiggle(model)
    save_agent(tmp_path, {**META, "algo": "TD3"}, policy=model.policy)
    agent = load_agent(tmp_path)
    o = torch.zeros((2, N_OBS))
    a = agent.model.actor(o)
    torch.testing.assert_close(a, model.actor(o), rtol=0, atol=0)
    torch.testing.assert_close(agent.model.critic.q1_forward(o, a), model.critic.q1_forward(o, a), rtol=0, atol=0)


def test_the_run_folders_agent_is_replaced_in_place_by_digest_named_files(tmp_path):
    from controllers.mlp_policy import MLPPolicy

    (tmp_path / "validation.csv").write_text("timesteps,validation_return\n")
    for k in range(3):
        policy = MLPPolicy((N_OBS, 4, 1), np.full(MLPPolicy((N_OBS, 4, 1)).n_params, 0.1 * k))
        norm = ObservationNormalizer(np.full(N_OBS, float(k)), np.ones(N_OBS))
        save_agent(tmp_path, {**META, "algo": "CMA-ES", "version": k}, policy=policy, normalizer=norm, in_place=True)
    meta = json.loads((tmp_path / "agent.json").read_text())
    names = sorted(f.name for f in tmp_path.iterdir())
    assert names == sorted(["agent.json", "validation.csv", meta["model"], meta["normalization"]])
    agent = load_agent(tmp_path)
    assert agent.meta["version"] == 2 and np.all(agent.model.theta == 0.2) and np.all(agent.normalizer.mean == 2)


def test_a_file_from_another_save_is_refused_by_its_digest(tmp_path):
    """Model and statistics from two saves (what a non-atomic save killed half-way leaves) never load together."""
    a, b = (shutil.copytree(shipped_agents("quarter_car")[i], tmp_path / n) for i, n in ((0, "a"), (2, "b")))
    shutil.copy(b / "normalization.npz", a / "normalization.npz")
    with pytest.raises(ValueError, match="normalization.npz is not the file agent.json records"):
        load_agent(a)
    meta = json.loads((b / "agent.json").read_text())
    (b / "agent.json").write_text(json.dumps({**meta, "files": {}}))
    with pytest.raises(AgentDigestError, match="records no digest for policy"):
        load_agent(b)


def test_the_digest_covers_exactly_the_files_that_are_loaded(tmp_path):
    src = shipped_agents("quarter_car")[-1]
    a = shutil.copytree(src, tmp_path / "a")
    d = agent_digest(a)
    assert d == agent_digest(src)
    (a / "model.zip").write_bytes(b"not loaded")      # a file loading never reads
    (a / "notes.txt").write_text("hello")
    assert agent_digest(a) == d
    norm = ObservationNormalizer.load(a / "normalization.npz")
    norm.mean = norm.mean + 1
    norm.save(a / "normalization.npz")
    assert agent_digest(a) != d


def test_write_agent_records_the_digests_of_a_model_saved_beside_it(tmp_path):
    from controllers.mlp_policy import MLPPolicy

    MLPPolicy((N_OBS, 1)).save(tmp_path / "policy.npz")
    write_agent(tmp_path, {**META, "algo": "CMA-ES", "model": "policy.npz"},
                ObservationNormalizer(np.zeros(N_OBS), np.ones(N_OBS)))
    assert load_agent(tmp_path).predict(np.zeros(N_OBS))[0].shape == (1,)


def test_a_residual_agent_on_a_raw_observation_says_to_bind_it():
    """Issue 37: the environment's observation lacks the law's command; the message says what the agent is and how
    to use it (instead of NumPy's broadcast error), and bind(env) acts on the same observation."""
    folder = next(f for f in shipped_agents("quarter_car") if f.name == "quarter_car_ppo_residual")
    agent = load_agent(folder)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(agent.env_id, **agent.observation_kwargs)
    obs, _ = env.reset(seed=1)
    with pytest.raises(ValueError, match=r"residual agent over the law 'skyhook_continuous'.*\(9 values, got 8\).*"
                                         r"agent\.bind\(env\)"):
        agent.predict(obs)
    with pytest.raises(ValueError, match="residual agent"):
        agent.predict(np.stack([obs, obs]))
    a, _ = agent.bind(env).predict(obs)
    assert env.action_space.contains(np.asarray(a, dtype=np.float32))
    with pytest.raises(ValueError, match=r"an observation of shape \(3, 2, 9\)"):
        agent.predict(np.zeros((3, 2, 9)))


def test_the_trainers_saves_load_code_free(tmp_path):
    """mrd-env train's run folder, best/ and checkpoints: code-free agents (model.zip beside them, to resume)."""
    from experiments.training.trainers import train_one

    kw = {"episode_seconds": 0.2, "control_dt": 0.01}
    run = train_one(profile("quarter_car"), "ppo", 0, out=tmp_path, timesteps=64, env_kwargs=kw, eval_freq=32,
                    eval_episodes=1, checkpoint_freq=32, hyper={"n_steps": 32, "batch_size": 32, "n_envs": 1})
    for folder in (run, run / "best", *sorted((run / "checkpoints").iterdir())):
        meta = json.loads((folder / "agent.json").read_text())
        assert meta["model"].endswith(".safetensors") and meta["resume"] == "model.zip", folder
        load_agent(folder)
    assert not [f for f in run.rglob(".*")]  # no temporary file, no staging folder left
