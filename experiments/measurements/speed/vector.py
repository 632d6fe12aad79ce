"""Throughput of the native vector environments next to Gymnasium's ``CartPoleVectorEnv``, same process and run.

Run: ``python -m experiments.measurements.speed.vector [--sizes 1 64 256 1024 4096] [--repeats 5]
[--out results/bench]``.

For each N: env-steps per second (N × steps per second) of ``gymnasium.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point")`` at the 1 ms default control step and at a 10 ms control step (and
µs per simulated ms per environment), next to ``CartPoleVectorEnv`` at the same N; the median of ``--repeats``
timing runs, interleaved so that a busy machine slows every row alike. Episodes (10 s of road, El Centro for
the building) autoreset inside the timing, as in training. Commands alternate between v_min and v_max every 50
steps.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleVectorEnv

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def rate(venv, n_steps: int, actions) -> float:
    """Env-steps per second over n_steps vector steps."""
    t0 = time.perf_counter()
    for k in range(n_steps):
        venv.step(actions[(k // 50) % 2])
    return venv.num_envs * n_steps / (time.perf_counter() - t0)


def bench(sizes=(1, 64, 256, 1024, 4096), repeats: int = 5, seconds: float = 1.0) -> list[dict]:
    import mrd_env  # noqa: F401

    rows = []
    for N in sizes:
        cases = {
            "QuarterCarPhysical-v0, control 1 ms": (gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=N,
                                                         vectorization_mode="vector_entry_point"), 1),
            "QuarterCarPhysical-v0, control 10 ms": (gym.make_vec("mrd_env/QuarterCarPhysical-v0", num_envs=N,
                                                          vectorization_mode="vector_entry_point",
                                                          control_dt=0.01), 10),
            "ShearBuildingPhysical-v0, control 1 ms": (gym.make_vec("mrd_env/ShearBuildingPhysical-v0", num_envs=N,
                                                            vectorization_mode="vector_entry_point"), 1),
        }
        cart = CartPoleVectorEnv(num_envs=N)
        acts = {}
        for label, (venv, _) in cases.items():
            lo, hi = venv.single_action_space.low, venv.single_action_space.high
            acts[label] = (np.tile(lo, (N, 1)).astype(np.float64), np.tile(hi, (N, 1)).astype(np.float64))
            venv.reset(seed=0)
            rate(venv, 3, acts[label])  # compile / load the kernels
        cart.reset(seed=0)
        cacts = (np.zeros(N, dtype=np.int64), np.ones(N, dtype=np.int64))
        # steps per timing run: about ``seconds`` of work at the rate of a first short run
        steps = {label: max(20, int(seconds * rate(venv, 20, acts[label]) / N)) for label, (venv, _) in cases.items()}
        csteps = max(100, int(seconds * rate(cart, 100, cacts) / N))
        rates: dict[str, list] = {k: [] for k in list(cases) + ["cartpole"]}
        for _ in range(repeats):
            for label, (venv, _) in cases.items():
                rates[label].append(rate(venv, steps[label], acts[label]))
            rates["cartpole"].append(rate(cart, csteps, cacts))
        cp = float(np.median(rates["cartpole"]))
        for label, (venv, n_sub) in cases.items():
            r = float(np.median(rates[label]))
            rows.append({"N": N, "environment": label, "env_steps_per_s": r, "x_cartpole_vector": r / cp,
                         "us_per_simulated_ms_per_env": 1e6 / (r * n_sub)})
            venv.close()
        rows.append({"N": N, "environment": "CartPoleVectorEnv", "env_steps_per_s": cp, "x_cartpole_vector": 1.0,
                     "us_per_simulated_ms_per_env": float("nan")})
    return rows


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 64, 256, 1024, 4096])
    ap.add_argument("--repeats", type=int, default=5, help="timing runs per row; the median is reported")
    ap.add_argument("--seconds", type=float, default=1.0, help="length of one timing run")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    rows = bench(args.sizes, args.repeats, args.seconds)
    md, _ = write_table(rows, args.out / "vector_speed", title="Native vector environments (same run as "
                        "CartPoleVectorEnv; median of repeats)", floatfmt=".3g")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
