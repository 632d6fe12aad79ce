"""Speed of the environments' ``env.step`` next to Gymnasium's CartPole-v1, measured in the same run.

Run: ``python -m experiments.measurements.speed.envs [--steps 20000] [--repeats 3] [--out results/bench]``.

All environments are built through ``gymnasium.make`` (so every row pays the same wrapper overhead:
OrderEnforcing and PassiveEnvChecker). Rows: the default quarter car (class-C ISO 8608 road at 20 m/s,
Spencer–Dyke automotive damper, 1 ms control step), the same at a 10 ms control step (per control step and per
simulated millisecond), the default shear building (three-storey lab model, El Centro ×0.2 time scale), and
CartPole-v1; then the wall time of one full El Centro building episode (reset + every step at 1 ms). Each
figure is the median of ``--repeats`` runs, the rows interleaved within each repeat; the ratio to CartPole-v1
(the figure to compare across machines) is the median of the ratios of each run to the CartPole run right
after it, so that a machine that slows down for a while slows both sides of a ratio alike. The compiled kernels are
warmed up first. The commands alternate between v_min and v_max every 50 steps so that the damper works
through its whole range.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from mrd_env import storage
from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def make_env(env_id: str, **kwargs):
    from mrd_env.plants.registry import register_envs

    register_envs()
    return gym.make(env_id, **kwargs)


def time_steps(env, n: int, actions) -> float:
    """µs per env.step over n steps (resetting when an episode ends, reset time excluded)."""
    env.reset(seed=0)
    total = 0.0
    k = 0
    while k < n:
        t0 = time.perf_counter()
        while k < n:
            _, _, term, trunc, _ = env.step(actions[(k // 50) % 2])
            k += 1
            if term or trunc:
                break
        total += time.perf_counter() - t0
        if k < n:
            env.reset()
    return total / n * 1e6


def bench(steps: int = 20000, repeats: int = 9) -> tuple[list[dict], float]:
    cases = [
        ("QuarterCarPhysical-v0 (default, control 1 ms)", "mrd_env/QuarterCarPhysical-v0", {"episode_seconds": 60.0}, 1),
        ("QuarterCarPhysical-v0 (control_dt 10 ms)", "mrd_env/QuarterCarPhysical-v0",
         {"episode_seconds": 60.0, "control_dt": 0.01}, 10),
        ("ShearBuildingPhysical-v0 (default, control 1 ms)", "mrd_env/ShearBuildingPhysical-v0", {}, 1),
    ]
    rows = []
    envs = []
    for label, env_id, kwargs, n_sub in cases:
        env = make_env(env_id, **kwargs)
        lo, hi = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
        envs.append((label, env, (lo, hi), n_sub))
        time_steps(env, 200, (lo, hi))  # warm-up: compile / load the kernels
    cart = gym.make("CartPole-v1")
    time_steps(cart, 2000, (0, 1))
    runs: dict[str, list] = {}
    ratios: dict[str, list] = {}
    for _ in range(repeats):
        for label, env, acts, n_sub in envs:
            n = max(steps // n_sub, 500)
            us = time_steps(env, n, acts)
            cp_us = time_steps(cart, steps // 4, (0, 1))
            runs.setdefault(label, []).append(us)
            runs.setdefault("cartpole", []).append(cp_us)
            ratios.setdefault(label, []).append(us / cp_us)
    best = {k: float(np.median(v)) for k, v in runs.items()}
    cp = best["cartpole"]
    for label, env, acts, n_sub in envs:
        us = best[label]
        rows.append({"environment": label, "us_per_env_step": us, "us_per_simulated_ms": us / n_sub,
                     "x_cartpole": float(np.median(ratios[label]))})
    rows.append({"environment": "CartPole-v1", "us_per_env_step": cp, "us_per_simulated_ms": float("nan"),
                 "x_cartpole": 1.0})

    # one full El Centro episode of the building, reset included
    env = envs[2][1]
    hi = env.action_space.high
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        env.reset(seed=0)
        n = 0
        while True:
            _, _, term, trunc, _ = env.step(hi)
            n += 1
            if term or trunc:
                break
        walls.append(time.perf_counter() - t0)
    wall = float(np.median(walls))
    episode = {"steps": n, "simulated_s": n * env.unwrapped.control_dt, "wall_s": wall}
    for _, e, _, _ in envs:
        e.close()
    return rows, episode


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20000, help="env.step calls per timing run (per simulated ms)")
    ap.add_argument("--repeats", type=int, default=9, help="timing runs per row; the median is reported")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    rows, ep = bench(args.steps, args.repeats)
    md, _ = write_table(rows, args.out / "env_speed", title="Environment step speed (gymnasium.make, same run)",
                        floatfmt=".3g")
    text = md.read_text()
    text += (f"\nFull El Centro episode of ShearBuildingPhysical-v0 (reset + {ep['steps']} steps, "
             f"{ep['simulated_s']:.2f} s simulated at 1 kHz): {ep['wall_s']:.3f} s wall time.\n")
    storage.write_text(md, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
