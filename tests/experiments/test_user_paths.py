"""A user's path from one command to the next (issue 22): identify a damper on a record, then use the saved preset
everywhere a model name is accepted — the rig, the environments, training — and enter the benchmark with the agent
trained on it."""
import csv
import json

import gymnasium as gym
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from experiments.cli import main


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A record from the virtual rig (a Bouc–Wen damper with a stiffer hysteresis than the preset), fitted with
    identify and saved as a preset."""
    d = tmp_path_factory.mktemp("user")
    assert main(["rig", "--damper", "bouc_wen", "--preset", "spencer1997", "--commands", "1.0", "--cycles", "2",
                 "--out", str(d / "rig")]) == 0
    record = d / "rig" / "bouc_wen_1V.csv"
    preset = d / "fitted.json"
    assert main(["identify", "--data", str(record), "--model", "bouc_wen", "--preset", "spencer1997",
                 "--maxiter", "20", "--no-progress", "--out", str(d / "fit"), "--save-preset", str(preset)]) == 0
    return d, preset


def test_identify_then_rig_environments_and_train_on_the_preset_then_benchmark_the_agent(fitted):
    d, preset = fitted
    doc = json.loads(preset.read_text())
    assert doc["model"] == "bouc_wen"
    # the rig
    assert main(["rig", "--preset", str(preset), "--cycles", "1", "--out", str(d / "rig2")]) == 0
    with (d / "rig2" / "bouc_wen_summary.csv").open() as fh:
        assert all(float(r["F_max (N)"]) > 0 for r in csv.DictReader(fh))
    # Python: every environment takes the file as its damper
    for env_id in ("mrd_env/QuarterCarPhysical-v0", "mrd_env/ShearBuildingPhysical-v0", "mrd_env/HalfCarPhysical-v0"):
        env = gym.make(env_id, damper=str(preset), episode_seconds=0.05)
        assert env.unwrapped.damper.name == "bouc_wen"
        assert env.unwrapped.damper.params.alpha_b == doc["parameters"]["alpha_b"]["value"]
    with pytest.raises(ValueError, match="preset file"):
        gym.make("mrd_env/QuarterCarPhysical-v0", damper=str(preset), damper_preset="spencer1997")
    # a short training on it
    assert main(["train", "--plant", "shear_building", "--algo", "ppo", "--damper", str(preset), "--timesteps", "64",
                 "--set", "n_steps=32", "batch_size=32", "n_envs=1", "--eval-freq", "0", "--no-progress",
                 "--out", str(d / "agents")]) == 0
    agent = d / "agents" / "shear_building_ppo_s0"
    meta = json.loads((agent / "agent.json").read_text())
    # the preset travels with the agent (a shared agent reads nothing outside its folder): a copy, named by content
    copy = agent / meta["env_kwargs"]["damper"]
    assert copy.parent == agent and copy.read_bytes() == preset.read_bytes()
    # the agent enters the benchmark: a suite fixes its plant and damper, so it is scored on the suite's damper
    assert main(["benchmark", "--suite", "building-seismic-v1", "--no-shipped", "--controller", str(agent),
                 "--episodes", "1", "--backend", "serial", "--out", str(d / "bench"), "--no-progress"]) == 0
    assert len(list((d / "bench" / "results").glob("building-seismic-v1__*.json"))) == 1
    # a suite fixes its damper: the preset as a plant option describes the plant of no shipped suite
    assert main(["benchmark", "--damper", str(preset), "--out", str(d / "bench2")]) == 2


def test_a_bad_preset_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["rig", "--preset", str(bad), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "not a JSON preset" in err and err.count("\n") == 1
    assert main(["benchmark", "--plant", "shear_building", "--damper", str(tmp_path / "missing.json"),
                 "--out", str(tmp_path)]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_the_readme_quickstart_runs_and_warns_of_no_outdated_id():
    """The README's Python quickstart, as a newcomer pastes it: it runs, and its id is not one Gymnasium calls out
    of date (a former -v0 id prints "consider upgrading to version v1" beside the -v1 ids)."""
    import re
    import warnings
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", readme, re.S).group(1)
    scope = {}
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*out of date", category=DeprecationWarning)
        exec(compile(code + "\nobs, *_ = env.step(law.predict(obs)[0])\n", "README.md", "exec"), scope)
    assert scope["env"].observation_space.contains(scope["obs"])


@pytest.mark.parametrize("command", [["rig"], ["inverse", "train", "--out", "n.npz"]])
def test_the_damper_option_is_called_damper_everywhere_and_model_is_still_accepted(command):
    from experiments.cli import build_parser

    parser = build_parser(command[0])
    for flag in ("--damper", "--model"):
        assert parser.parse_args([*command, flag, "bouc_wen"]).model == "bouc_wen"
