"""Stable-Baselines3's PPO called directly, as a user would, with torch's default threads and with one thread (a
script, not a test): the figure behind the ``torch.set_num_threads(1)`` line of the docs' SB3 snippets.

    python -m experiments.measurements.speed.sb3_threads [--timesteps 2048] [--repeats 3] [--out results/bench/sb3_threads]

Each run is a fresh Python process (torch's thread count is per process and set once) that builds
``make_vec_env("mrd_env/QuarterCar-v1", n_envs=4, seed=0)`` (SB3's own helper: a ``DummyVecEnv`` of the scalar
environments) and trains ``PPO("MlpPolicy", env, n_steps=timesteps // 4, seed=0, device="cpu")`` — SB3's defaults
otherwise (batch 64, 10 epochs) — for ``timesteps`` steps: one rollout and one update. The figure is steps per
second of ``model.learn`` (simulation and learning together, process start and imports excluded); the two settings
alternate, ``repeats`` times each, and the median is reported with the ratio and the load average before and after.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = """
import json, sys, time
import torch
if {one}:
    torch.set_num_threads(1)
import gymnasium as gym
import mrd_env  # noqa: F401
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
env = make_vec_env("mrd_env/QuarterCar-v1", n_envs=4, seed=0)
model = PPO("MlpPolicy", env, n_steps={timesteps} // 4, seed=0, device="cpu", verbose=0)
t0 = time.perf_counter()
model.learn(total_timesteps={timesteps})
wall = time.perf_counter() - t0
print(json.dumps({{"steps": int(model.num_timesteps), "wall": wall, "threads": torch.get_num_threads()}}))
"""


def one_run(one_thread: bool, timesteps: int) -> dict:
    code = CHILD.format(one=one_thread, timesteps=int(timesteps))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--timesteps", type=int, default=2048, help="steps per run, a multiple of 4 (default 2048)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=None, help="write <out>.md and <out>.csv")
    args = ap.parse_args(argv)
    if args.timesteps < 4 or args.timesteps % 4:
        ap.error(f"--timesteps must be a positive multiple of 4 (4 environments), got {args.timesteps}")
    load0 = os.getloadavg()
    runs = {"torch default": [], "torch.set_num_threads(1)": []}
    threads = {}
    for _ in range(args.repeats):
        for name, one in (("torch default", False), ("torch.set_num_threads(1)", True)):
            r = one_run(one, args.timesteps)
            runs[name].append(r["steps"] / r["wall"])
            threads[name] = r["threads"]
            print(f"{name} ({r['threads']} threads): {r['steps']} steps in {r['wall']:.2f} s = "
                  f"{r['steps'] / r['wall']:.0f} steps/s (load {os.getloadavg()[0]:.2f})", flush=True)
    load1 = os.getloadavg()
    base = statistics.median(runs["torch default"])
    rows = [{"setting": name, "torch threads": threads[name], "steps/s (median)": statistics.median(r),
             "steps/s (each run)": " ".join(f"{x:.0f}" for x in r), "ratio to default": statistics.median(r) / base}
            for name, r in runs.items()]
    from mrd_env.report import markdown_table, write_table

    title = (f"SB3 PPO on make_vec_env('mrd_env/QuarterCar-v1', 4), {args.timesteps} steps per run, {args.repeats} "
             f"runs each, {os.cpu_count()} cores, load average {load0[0]:.2f} → {load1[0]:.2f}")
    print(markdown_table(rows, title=title))
    if args.out:
        for path in write_table(rows, args.out, title=title):
            print("wrote", path)


if __name__ == "__main__":
    main()
