"""PPO training throughput through the SB3 bridge over the native vector environment, next to SB3's own
``DummyVecEnv`` of the same environments, same process and run.

Run: ``python -m experiments.measurements.speed.training [--n-envs 1 8 64] [--timesteps 20000] [--repeats 3]``.

Both paths train the same PPO (MlpPolicy, n_steps = 2048 / n_envs rounded up to 16, batch 64, 2 epochs, CPU,
``torch.set_num_threads(1)`` so that the network does not take the second core from the environments) on
``mrd_env/QuarterCarPhysical-v0`` at a 10 ms control step with normalised actions; the figure is env-steps per second of
``model.learn`` (simulation and learning together), the median of the repeats.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode

ENV_ID = "mrd_env/QuarterCarPhysical-v0"
ENV_KW = dict(control_dt=0.01, action_mode="normalized")


def _learn_rate(venv, n_envs: int, timesteps: int) -> float:
    from stable_baselines3 import PPO

    n_steps = max(16, int(np.ceil(2048 / n_envs / 16)) * 16)
    model = PPO("MlpPolicy", venv, n_steps=n_steps, batch_size=64, n_epochs=2, seed=0, device="cpu", verbose=0)
    t0 = time.perf_counter()
    model.learn(total_timesteps=timesteps)
    return model.num_timesteps / (time.perf_counter() - t0)


def bench(n_envs=(1, 8, 64), timesteps: int = 20000, repeats: int = 3) -> list[dict]:
    import gymnasium as gym
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv

    import mrd_env  # noqa: F401
    from mrd_env.envs.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)
    rows = []
    for n in n_envs:
        rates = {"bridge": [], "dummy": []}
        for r in range(repeats):
            rates["bridge"].append(_learn_rate(make_sb3_vec_env(ENV_ID, n_envs=n, seed=r, **ENV_KW), n, timesteps))
            dummy = DummyVecEnv([lambda: gym.make(ENV_ID, **ENV_KW) for _ in range(n)])
            dummy.seed(r)
            rates["dummy"].append(_learn_rate(dummy, n, timesteps))
        b, d = float(np.median(rates["bridge"])), float(np.median(rates["dummy"]))
        rows.append({"n_envs": n, "bridge_env_steps_per_s": b, "DummyVecEnv_env_steps_per_s": d, "ratio": b / d})
    return rows


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-envs", type=int, nargs="+", default=[1, 8, 64])
    ap.add_argument("--timesteps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    rows = bench(args.n_envs, args.timesteps, args.repeats)
    md, _ = write_table(rows, args.out / "training_speed", title="PPO training throughput (QuarterCarPhysical-v0, 10 ms "
                        "control; median of repeats)", floatfmt=".4g")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
