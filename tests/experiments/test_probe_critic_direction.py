"""experiments/scripts/probe_critic_direction.py (issue 23): on a tiny TD3 residual it writes the critic's-direction
table (the law, ε along the gradient and at random for each ε, the argmax) and the agreement table; bad options are
one line of usage error naming the option."""
import csv

import pytest

from experiments.scripts.probe_critic_direction import main
from experiments.training.trainers import env_options, train_one
from experiments.common.plants import profile


@pytest.fixture(scope="module")
def agent(tmp_path_factory):
    return train_one(profile("quarter_car"), "td3", 0, out=tmp_path_factory.mktemp("agents"), timesteps=64, eval_freq=0,
                     env_kwargs={**env_options(profile("quarter_car")), "episode_seconds": 0.5},
                     hyper={"n_envs": 2, "learning_starts": 32, "batch_size": 16, "train_freq": 1,
                            "policy_kwargs": {"net_arch": [8, 8]}, "actor_warmup_steps": 8,
                            "residual": {"law": "skyhook_continuous", "scale": 0.5}})


def _rows(path):
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_the_tables_have_a_row_per_correction_and_per_agent(agent, tmp_path):
    assert main(["--agent", str(agent), "--eps", "0.05", "--episodes", "2", "--final", str(agent),
                 "--final-episodes", "1", "--out", str(tmp_path)]) == 0
    rows = _rows(tmp_path / "critic_direction.csv")
    assert [r["correction to the law"] for r in rows] == [
        "the law (skyhook_continuous)", "ε = 0.05 along the critic's gradient", "ε = 0.05, random sign",
        "the critic's argmax over [-0.3, 0.3]"]
    assert float(rows[0]["minus the law (per episode)"]) == 0.0 and all(r["episodes"] == "2" for r in rows)
    md = (tmp_path / "critic_direction.md").read_text().splitlines()
    assert sum(line.startswith("|") for line in md) == 6   # header, rule, 4 rows
    [final] = _rows(tmp_path / "critic_agreement.csv")
    assert final["agent"] == str(agent) and int(final["steps"]) == 50          # 0.5 s at 100 Hz
    assert 0.0 <= float(final["Q1(s, π(s)) − Q1(s, 0) > 0 (% of steps)"]) <= 100.0


def test_same_seed_same_table(agent, tmp_path):
    for name in ("a", "b"):
        assert main(["--agent", str(agent), "--eps", "0.3", "--episodes", "1", "--out", str(tmp_path / name)]) == 0
    assert (tmp_path / "a" / "critic_direction.csv").read_text() == (tmp_path / "b" / "critic_direction.csv").read_text()


@pytest.mark.parametrize("args, message", [
    ([], "give --agent PATH"),
    (["--agent", "x", "--eps", "0"], "--eps must be in (0, 1]"),
    (["--agent", "x", "--eps", "0.02", "1.5"], "--eps must be in (0, 1]"),
    (["--agent", "x", "--episodes", "0"], "--episodes must be >= 1"),
    (["--final", "x", "--final-episodes", "0"], "--final-episodes must be >= 1"),
    (["--agent", "x", "--seed", "-1"], "--seed must be >= 0"),
])
def test_bad_options_are_usage_errors(args, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main([*args, "--out", str(tmp_path / "out")])
    assert exc.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_an_agent_without_a_residual_critic_is_refused(tmp_path, capsys):
    run = train_one(profile("quarter_car"), "td3", 0, out=tmp_path, timesteps=32, eval_freq=0,
                    env_kwargs={**env_options(profile("quarter_car")), "episode_seconds": 0.5},
                    hyper={"n_envs": 1, "learning_starts": 16, "batch_size": 8, "policy_kwargs": {"net_arch": [8]}})
    with pytest.raises(SystemExit):
        main(["--agent", str(run), "--out", str(tmp_path / "out")])
    assert "needs a TD3 agent trained with a residual" in capsys.readouterr().err
