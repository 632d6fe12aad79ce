"""Malicious agents (issue 36): a shared agent folder runs no code and reads nothing outside itself.

- A copy of a shipped PPO agent whose SB3 ``model.zip`` carries a pickle that creates a marker file is refused by
  ``load_agent``, ``mrd-env score`` and ``mrd-env benchmark`` without running it (no marker; exit 2, one line); with
  trust it is loaded and the payload runs (the marker appears: the test can fail).
- An ``agent.json`` naming a file outside its folder (absolute, ``..``, a symlink out) is refused, naming the file.
- An ``agent.json`` whose environment options would exhaust memory is refused by the environment's own check.
"""
import base64
import json
import pickle
import shutil
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from controllers.agents import (TrustedCodeWarning, UntrustedAgentError, agent_digest, agent_files, load_agent,
                                shipped_agents)
from experiments.cli import main

pytestmark = pytest.mark.hostile  # every case here is a hostile file (a count: pytest -m hostile)

pytest.importorskip("stable_baselines3")
pytest.importorskip("safetensors")
SHIPPED = next(f for f in shipped_agents("quarter_car") if f.name == "quarter_car_ppo_residual")
SCORE = ["score", "--suite", "car-comfort-v1", "--episodes", "1", "--no-progress", "--backend", "serial"]


class Payload:
    """Unpickled, it opens (creates) the marker file: any code could run in its place."""

    def __init__(self, marker: str):
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _sb3_zip(agent, path: Path, marker: Path) -> None:
    """SB3's model.zip of ``agent``'s policy (a PPO model built with its spaces and network, its weights loaded),
    with a pickled payload in the zip's ``data`` member, where SB3 keeps pickled objects as {":serialized:":
    base64}; SB3's loader unpickles every such entry."""
    import gymnasium as gym
    from stable_baselines3 import PPO

    from controllers.policy_format import space_of

    net = agent.meta["network"]

    class Stub(gym.Env):
        observation_space = space_of(net["observation_space"], "observation")
        action_space = space_of(net["action_space"], "action")

        def reset(self, seed=None, options=None):
            return self.observation_space.sample(), {}

        def step(self, action):
            return self.observation_space.sample(), 0.0, False, False, {}

    kw = net["kwargs"]
    model = PPO("MlpPolicy", Stub(), device="cpu", policy_kwargs={"net_arch": kw["net_arch"],
                                                                  "log_std_init": kw["log_std_init"]})
    model.policy.load_state_dict(agent.model.policy.state_dict())
    clean = path.with_name("clean.zip")
    model.save(clean)
    with zipfile.ZipFile(clean) as src, zipfile.ZipFile(path, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "data":
                d = json.loads(data)
                d["payload"] = {":type:": "<class 'Payload'>",
                                ":serialized:": base64.b64encode(pickle.dumps(Payload(str(marker)))).decode()}
                data = json.dumps(d).encode()
            dst.writestr(item, data)
    clean.unlink()


@pytest.fixture(scope="module")
def malicious(tmp_path_factory):
    """(folder, marker): a copy of the shipped residual PPO agent in SB3's format (agent.json naming model.zip, as
    agents were saved before the code-free format) whose model.zip creates ``marker`` when unpickled."""
    root = tmp_path_factory.mktemp("malicious")
    folder = shutil.copytree(SHIPPED, root / "agent")
    marker = root / "PWNED"
    _sb3_zip(load_agent(SHIPPED), folder / "model.zip", marker)
    meta = json.loads((folder / "agent.json").read_text())
    for key in ("network", "files", "converted_from"):
        meta.pop(key, None)
    (folder / "policy.safetensors").unlink()
    (folder / "agent.json").write_text(json.dumps({**meta, "model": "model.zip"}))
    return folder, marker


def test_load_agent_refuses_an_sb3_zip_without_running_it(malicious):
    folder, marker = malicious
    with pytest.raises(UntrustedAgentError, match=r"model\.zip is a Stable-Baselines3 zip.*--trust-agent"):
        load_agent(folder)
    agent_files(folder), agent_digest(folder)  # reading its metadata and hashing it run nothing either
    assert not marker.exists()


def test_score_refuses_it_in_one_line_with_exit_code_2(malicious, tmp_path, capsys):
    folder, marker = malicious
    assert main([*SCORE, "--controller", str(folder), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--trust-agent" in err and "model.zip" in err and "Traceback" not in err
    assert not marker.exists()
    assert not list(tmp_path.glob("*.json"))  # nothing scored


def test_only_trust_loads_it_and_then_its_payload_runs(malicious, tmp_path, capsys):
    """The proof that the tests above can fail: trusted, the zip is unpickled and the payload creates the marker.
    The agent acts as the shipped one, and score --trust-agent scores its code-free copy."""
    folder, marker = malicious
    with pytest.warns(TrustedCodeWarning, match="can run any code"):
        agent = load_agent(folder, trust=True)
    assert marker.exists()
    shipped = load_agent(SHIPPED)
    obs = np.random.default_rng(0).normal(0, 1, (16, 9))
    np.testing.assert_array_equal(agent.predict(obs)[0], shipped.predict(obs)[0])
    marker.unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrustedCodeWarning)
        assert main([*SCORE, "--controller", str(folder), "--out", str(tmp_path), "--trust-agent"]) == 0
    assert marker.exists() and len(list(tmp_path.glob("car-comfort-v1__*.json"))) == 1
    converted = list((tmp_path / "converted-agents").iterdir())
    assert len(converted) == 1 and not (converted[0] / "model.zip").exists()
    assert json.loads((converted[0] / "agent.json").read_text())["converted_from"]["file"] == "model.zip"
    marker.unlink()


def _edited(tmp_path, **changes) -> Path:
    folder = shutil.copytree(SHIPPED, tmp_path / "agent")
    meta = json.loads((folder / "agent.json").read_text())
    (folder / "agent.json").write_text(json.dumps({**meta, **changes}))
    return folder


@pytest.mark.parametrize("key, name", [
    ("model", "/etc/passwd.safetensors"), ("model", "../elsewhere/policy.safetensors"),
    ("normalization", "../other/normalization.npz"), ("normalization", "/tmp/normalization.npz"),
    ("resume", "../model.zip"),
])
def test_a_file_named_outside_the_folder_is_refused(tmp_path, key, name, capsys):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    shutil.copy(SHIPPED / "policy.safetensors", outside)
    folder = _edited(tmp_path, **{key: name})
    for read in (load_agent, agent_digest, agent_files):
        with pytest.raises(ValueError, match=rf"{key} file '{name}'.*only a name inside the folder"):
            read(folder)
    assert main([*SCORE, "--controller", str(folder), "--out", str(tmp_path / "out")]) == 2
    assert "only a name inside the folder" in capsys.readouterr().err


def test_a_digest_entry_outside_the_folder_is_refused(tmp_path):
    meta = json.loads((SHIPPED / "agent.json").read_text())
    folder = _edited(tmp_path, files={**meta["files"], "../x": "0" * 64})
    with pytest.raises(ValueError, match=r"files file '\.\./x'"):
        load_agent(folder)


def test_a_symlink_leaving_the_folder_is_refused(tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    shutil.copy(SHIPPED / "normalization.npz", outside / "normalization.npz")
    folder = shutil.copytree(SHIPPED, tmp_path / "agent")
    (folder / "normalization.npz").unlink()
    (folder / "normalization.npz").symlink_to(outside / "normalization.npz")
    with pytest.raises(ValueError, match=r"normalization file 'normalization.npz'.*a link that leaves the folder"):
        load_agent(folder)
    with pytest.raises(ValueError, match="a link that leaves the folder"):
        agent_digest(folder)


def test_algo_alone_does_not_route_a_folder_through_sb3s_loader(tmp_path, malicious):
    """A code-free agent whose agent.json says "algo": "PPO" loads from its arrays; a "model.zip" under another
    name is still refused."""
    folder, marker = malicious
    other = shutil.copytree(folder, tmp_path / "renamed")
    (other / "model.zip").rename(other / "weights.safetensors")
    meta = json.loads((other / "agent.json").read_text())
    (other / "agent.json").write_text(json.dumps({**meta, "model": "weights.safetensors"}))
    with pytest.raises(ValueError, match="network"):
        load_agent(other)
    assert not marker.exists()


@pytest.mark.parametrize("network, message", [
    ({"class": "builtins.eval"}, "policy class 'builtins.eval' is not one of"),
    ({"kwargs": {"activation_fn": "os.system"}}, "activation_fn must be one of"),
    ({"kwargs": {"features_extractor_class": "NatureCNN"}}, "features_extractor_class must be one of"),
    ({"kwargs": {"optimizer_class": "Adam"}}, r"policy options \['optimizer_class'\] are not options"),
    ({"kwargs": {"net_arch": [4096] * 16}}, "parameters"),
])
def test_a_network_description_names_only_allowed_classes_and_sizes(tmp_path, network, message):
    meta = json.loads((SHIPPED / "agent.json").read_text())
    net = {**meta["network"], **{k: v for k, v in network.items() if k != "kwargs"}}
    net["kwargs"] = {**net["kwargs"], **network.get("kwargs", {})}
    with pytest.raises(ValueError, match=message):
        load_agent(_edited(tmp_path, network=net))


def test_huge_environment_options_in_agent_json_are_refused(tmp_path):
    """The environment's constructor estimates the memory an option set asks for (mrd_env.resources) and refuses
    it before allocating; load_agent builds the environment once from agent.json's env_kwargs, so the agent is
    refused there, naming the option."""
    meta = json.loads((SHIPPED / "agent.json").read_text())
    folder = _edited(tmp_path, env_kwargs={**meta["env_kwargs"], "episode_seconds": 1e9})
    with pytest.raises(ValueError, match="env_kwargs are refused by .*episode_seconds"):
        load_agent(folder)
    with pytest.raises(ValueError, match="unknown option"):
        load_agent(_edited(tmp_path / "b", env_kwargs={"banana": 1}))


def test_benchmark_refuses_it_too_and_trust_is_its_only_way_in(malicious, tmp_path, capsys):
    folder, marker = malicious
    bench = ["benchmark", "--suite", "car-comfort-v1", "--only", "passive_off", "--episodes", "1", "--backend", "serial",
             "--no-progress", "--controller", str(folder), "--out", str(tmp_path)]
    assert main(bench) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--trust-agent" in err and "model.zip" in err and "Traceback" not in err
    assert not marker.exists() and not list(tmp_path.iterdir())
    with pytest.warns(TrustedCodeWarning):
        assert main([*bench, "--trust-agent"]) == 0
    assert marker.exists() and (tmp_path / "converted-agents").is_dir()


# --- files named by agent.json's environment options (issue 48, item 3) ------------------------------------------
def _road_csv(path: Path) -> None:
    x = np.linspace(0.0, 100.0, 501)
    path.write_text("x [m],z [m]\n" + "\n".join(f"{a!r},{float(0.01 * np.sin(a))!r}" for a in x.tolist()))


@pytest.mark.hostile
@pytest.mark.parametrize("path", ["/dev/zero", "/etc/passwd", "../road.csv"])
def test_a_road_path_outside_the_agent_folder_is_refused(tmp_path, path):
    """A road ``path`` in env_kwargs is confined to the agent's folder: /dev/zero is never read, /etc/passwd never
    opened (nothing of it in the message), a name climbing out refused, before the environment is built."""
    _road_csv(tmp_path / "road.csv")
    meta = json.loads((SHIPPED / "agent.json").read_text())
    road = {"kind": "csv", "path": path, "height_column": "z", "distance_column": "x", "speed": 10.0}
    folder = _edited(tmp_path, env_kwargs={**meta["env_kwargs"], "road": road})
    with pytest.raises(ValueError, match=r"env_kwargs: road\['path'\] .*only a name inside the folder") as info:
        load_agent(folder)
    assert ":x:" not in str(info.value)  # what every line of /etc/passwd holds


@pytest.mark.hostile
def test_a_road_file_inside_the_agent_folder_is_read_from_there(tmp_path, monkeypatch):
    """A relative name is the agent's own file, read from its folder whatever the working directory."""
    meta = json.loads((SHIPPED / "agent.json").read_text())
    road = {"kind": "csv", "path": "road.csv", "height_column": "z", "distance_column": "x", "speed": 10.0}
    folder = _edited(tmp_path, env_kwargs={**meta["env_kwargs"], "road": road})
    _road_csv(folder / "road.csv")
    monkeypatch.chdir(tmp_path)
    agent = load_agent(folder)
    assert agent.env_kwargs["road"]["path"] == str(folder.resolve() / "road.csv")
    (folder / "road.csv").unlink()
    (folder / "road.csv").symlink_to(tmp_path / "elsewhere.csv")
    _road_csv(tmp_path / "elsewhere.csv")
    with pytest.raises(ValueError, match="a link that leaves the folder"):
        load_agent(folder)
