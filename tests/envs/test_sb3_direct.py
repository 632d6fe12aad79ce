"""Stable-Baselines3 used directly (issue 49, item 1): a process that made an environment while torch ran on several
intra-op threads is told once, with the fix; with one thread, or silenced, it is not. Each case is a fresh process:
torch's threads and the warning's once-per-process state are process-wide."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

MAKE = """
import warnings
warnings.simplefilter("always")  # every warning raised is shown: "once" must come from the library
import torch
torch.set_num_threads({threads})
import gymnasium as gym
import mrd_env
from mrd_env.envs.sb3 import make_sb3_vec_env
from stable_baselines3.common.env_util import make_vec_env
gym.make("mrd_env/QuarterCar-v1").close()
gym.make("mrd_env/QuarterCarPhysical-v0").close()
make_vec_env("mrd_env/QuarterCar-v1", n_envs=2).close()
make_sb3_vec_env("mrd_env/QuarterCar-v1", n_envs=2).close()
print("made")
"""


def _run(threads: int, **env) -> subprocess.CompletedProcess:
    full = {k: v for k, v in os.environ.items() if k not in ("MRD_ENV_TORCH_THREADS_WARNING", "PYTHONWARNINGS")}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", MAKE.format(threads=threads)], capture_output=True, text=True,
                         env=full, timeout=300)
    assert out.returncode == 0 and "made" in out.stdout, out.stderr[-2000:]
    return out


def test_several_threads_warned_once_with_the_fix():
    err = _run(2).stderr
    assert err.count(": TorchThreadsWarning:") == 1, err
    assert "torch.set_num_threads(1)" in err and "MRD_ENV_TORCH_THREADS_WARNING=0" in err
    # attributed to the caller's line (the script's first gym.make), not to the library's
    assert "<string>:10: TorchThreadsWarning" in err, err


def test_the_native_vector_entry_point_warns_too():
    """gym.make_vec(..., vectorization_mode="vector_entry_point") makes no scalar environment: its entry point warns."""
    code = ("import warnings; warnings.simplefilter('always'); import torch; torch.set_num_threads(2); "
            "import gymnasium as gym, mrd_env; gym.make_vec('mrd_env/QuarterCar-v1', num_envs=2, "
            "vectorization_mode='vector_entry_point').close(); print('made')")
    full = {k: v for k, v in os.environ.items() if k not in ("MRD_ENV_TORCH_THREADS_WARNING", "PYTHONWARNINGS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=full, timeout=300)
    assert out.returncode == 0 and "made" in out.stdout, out.stderr[-2000:]
    assert out.stderr.count(": TorchThreadsWarning:") == 1, out.stderr


@pytest.mark.parametrize("threads, env", [(1, {}), (2, {"MRD_ENV_TORCH_THREADS_WARNING": "0"})],
                         ids=["one-thread", "silenced"])
def test_one_thread_or_silenced_not_warned(threads, env):
    err = _run(threads, **env).stderr
    assert "TorchThreadsWarning" not in err, err


def test_without_torch_not_imported():
    """A process without torch is not told, and the check imports no torch."""
    code = ("import warnings, sys; warnings.simplefilter('error'); import gymnasium as gym, mrd_env; "
            "gym.make('mrd_env/QuarterCar-v1').close(); print('torch' in sys.modules)")
    full = {k: v for k, v in os.environ.items() if k != "MRD_ENV_TORCH_THREADS_WARNING"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=full, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "False", out.stderr[-2000:]


# docs/training.md's block "Stable-Baselines3 called directly", run as a user pastes it: each learn() runs one
# rollout and one update, and records its budget and rollout size
DOCS_PRELUDE = """
import json, warnings
warnings.simplefilter("always")
from stable_baselines3 import PPO
_learn, LEARNS = PPO.learn, []
def _one_rollout(self, total_timesteps, **kw):
    LEARNS.append({"budget": int(total_timesteps), "rollout": int(self.n_steps * self.n_envs)})
    return _learn(self, total_timesteps=1, **kw)   # SB3 collects one whole rollout, then updates once
PPO.learn = _one_rollout
"""


def _docs_block() -> str:
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "training.md").read_text(encoding="utf-8")
    section = page.split("## Stable-Baselines3 called directly", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_the_docs_example_runs_fast_with_sensible_rollouts():
    """The docs' SB3 block runs without the warning (it sets one thread first), and every PPO in it collects
    its budget in at least 10 rollouts (n_steps is per environment: PPO's default with 64 environments would
    collect more than the budget in one)."""
    code = DOCS_PRELUDE + _docs_block() + "\nprint(json.dumps(LEARNS))\n"
    full = {k: v for k, v in os.environ.items() if k not in ("MRD_ENV_TORCH_THREADS_WARNING", "PYTHONWARNINGS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=full, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert ": TorchThreadsWarning:" not in out.stderr, out.stderr[-2000:]
    import json

    learns = json.loads(out.stdout.strip().splitlines()[-1])
    assert len(learns) >= 2  # SB3's make_vec_env and make_sb3_vec_env
    for run in learns:
        assert run["budget"] >= 10 * run["rollout"], run


def test_train_validation_lines_state_the_best_constant_command(tmp_path, capsys):
    """Each validation line of ``mrd-env train`` names R_p, the best constant command's return on the same
    validation episode, recomputed here with the scalar environment, and says whether the agent is above it."""
    import re

    import gymnasium as gym
    import numpy as np

    from experiments.cli import main
    from experiments.common.plants import profile
    from experiments.common.scenarios import validation
    from experiments.training.trainers import PASSIVE_GRID, env_options

    assert main(["train", "--plant", "quarter_car", "--algo", "ppo", "--timesteps", "64", "--set", "n_steps=32",
                 "batch_size=32", "n_envs=1", "--eval-freq", "64", "--eval-episodes", "1",
                 "--out", str(tmp_path)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if "validation return" in ln]
    assert len(lines) >= 2
    plant = profile("quarter_car")
    seed = int(validation(plant, 1)[0].seeds[0])
    env = gym.make(plant.env_id, **env_options(plant))
    best = -np.inf
    for f in PASSIVE_GRID:  # the constant commands, one episode each
        a = env.action_space.low + f * (env.action_space.high - env.action_space.low)
        env.reset(seed=seed)
        total, done = 0.0, False
        while not done:
            _, r, term, trunc, _ = env.step(a)
            total, done = total + float(r), term or trunc
        best = max(best, total)
    for line in lines:
        value, rp = re.search(r"validation return (\S+) .*R_p (\S+?):", line).groups()
        assert rp == f"{best:.4g}", line  # as printed
        assert ("not above passive" in line) == (float(value) <= best), line
