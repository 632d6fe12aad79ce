"""Training a user can watch and interrupt (issue 22): offered algorithms, bad hyperparameters refused before
training, an interrupted run leaves a usable agent, the console reports the best validation so far."""
import json

import pytest

from experiments.cli import main
from experiments.training.trainers import available_algos, env_options, train_one
from experiments.training.trainers import HYPERPARAMS
from experiments.common.plants import profile


def test_only_algorithms_with_hyperparameters_are_offered(capsys):
    assert "ppo" in available_algos() and "cmaes" in available_algos()
    assert main(["train", "--algo", "banana"]) == 2
    assert "--algo must be one of" in capsys.readouterr().err
    missing = sorted({"a2c", "td3", "tqc"} - set(available_algos()))
    if missing:
        assert main(["train", "--algo", missing[0]]) == 2
        err = capsys.readouterr().err
        assert "--hyperparams" in err and "Traceback" not in err


def test_a_value_sb3_rejects_is_a_bad_option_named_before_training(capsys, tmp_path):
    assert main(["train", "--algo", "ppo", "--set", "learning_rate=banana", "--out", str(tmp_path),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "learning_rate='banana'" in err and err.count("\n") == 1
    assert not any(tmp_path.iterdir())                     # nothing trained, nothing written


def test_an_interrupted_run_leaves_an_agent_evaluate_accepts(tmp_path, capsys):
    from controllers import load_agent

    kw = {**env_options(profile("quarter_car")), "episode_seconds": 0.2}

    def interrupt(steps, value):  # Ctrl-C at the first validation
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_one(profile("quarter_car"), "ppo", 0, out=tmp_path, timesteps=64, env_kwargs=kw, eval_episodes=1,
                  hyper={"n_steps": 32, "batch_size": 32, "n_envs": 1}, report=interrupt, progress=True)
    run = tmp_path / "quarter_car_ppo_s0"
    meta = json.loads((run / "agent.json").read_text())
    assert meta["interrupted"] is True and meta["timesteps_done"] == 0
    assert load_agent(run).name == "PPO s0"
    cap = capsys.readouterr()
    assert "saved the agent so far" in cap.err
    assert "validation return" in cap.out and "best so far" in cap.out   # the console line of each validation


@pytest.mark.parametrize("path", sorted(HYPERPARAMS.glob("*.yml")), ids=lambda p: p.name)
def test_every_shipped_hyperparameter_file_passes_the_checks_made_before_training(path):
    """What `mrd-env train --hyperparams <shipped file>` checks before it trains (the keys, the residual's and the
    baseline's laws on the plant, a model SB3 builds), for every environment entry of every shipped file: a recipe
    the docs print must not end in a bad-option error. The algorithm is the file name's first word."""
    import yaml

    from experiments.common.plants import by_env_id
    from experiments.commands.train import check_before_training
    from experiments.training.trainers import TRAINERS, hyperparameters

    algo = path.stem.split("-")[0]
    assert algo in TRAINERS, f"{path.name}: no algorithm {algo!r}"
    entries = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert entries, path.name
    for env_id in entries:
        plant = by_env_id(env_id)
        assert plant is not None, f"{path.name}: {env_id} is not a plant's environment"
        hyper = hyperparameters(algo, env_id, path)  # the trainer's own check of every key and value
        check_before_training(algo, hyper, env_id, env_options(plant))


def test_sigterm_saves_a_loadable_agent_and_exits_143(tmp_path):
    """SIGTERM (SLURM, docker stop, timeout) is handled like Ctrl-C: the run so far is saved as an agent that
    loads, and the command exits 143 (issue 36: the process died silently, leaving no agent.json)."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    from controllers import load_agent

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "experiments.cli", "train", "--algo", "ppo", "--timesteps",
                             "10000000", "--set", "n_envs=1", "n_steps=64", "batch_size=64", "--eval-freq", "0",
                             "--no-progress", "--out", str(tmp_path)], env=env, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        # training has begun once SB3's monitor writes an episode's row under its two header lines
        if any(p.read_text().count("\n") >= 3 for p in tmp_path.glob("*/*monitor.csv")):
            break
        time.sleep(0.5)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "saved the agent so far" in err and err.rstrip().endswith("mrd-env train: terminated"), err
    run = next(p.parent for p in tmp_path.glob("*/agent.json"))
    assert json.loads((run / "agent.json").read_text())["interrupted"] is True
    assert load_agent(run).predict([0.0] * load_agent(run).normalizer.shape[0])[0].shape == (1,)


def test_a_run_leaves_nothing_in_the_systems_temporary_folder(tmp_path, monkeypatch):
    """SB3 makes an empty ``SB3-<time>`` folder in the temporary folder for every run without a log folder; the
    trainer gives it a logger that writes nothing instead (what SB3 logs at verbose 0), so a run leaves none."""
    import tempfile

    system_tmp = tmp_path / "system_tmp"
    system_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)  # the suite points it elsewhere (tests/conftest.py)
    kw = {"episode_seconds": 0.2, "control_dt": 0.01}
    run = train_one(profile("quarter_car"), "ppo", 0, out=tmp_path / "runs", timesteps=64, env_kwargs=kw,
                    eval_freq=32, eval_episodes=1, hyper={"n_steps": 32, "batch_size": 32, "n_envs": 1})
    assert (run / "agent.json").is_file()
    assert not [p.name for p in system_tmp.iterdir() if p.name.startswith("SB3-")]
