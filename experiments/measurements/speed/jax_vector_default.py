"""The JAX vector environment's default scheme against its two schemes and the native vector environment (issue 49,
item 8: what a user who picks ``backend="jax"`` gets).

Env-steps/s of whole ``VectorEnv.step`` calls (actions in, NumPy arrays and infos out), interleaved in one process:
``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")`` (native, its thread tuner on), the
same with ``backend="jax"`` and no ``scheme`` (the default, its scheme named in the output), and with
``scheme="exact"`` and ``scheme="differentiable"``; uniform random actions every step (the exact scheme's adaptive
work is largest on command transients), median of ``--repeats`` runs of about ``--window`` s each after a warm-up
that compiles. The 1-minute load average is recorded before and after; the figures are ratios to the native
environment of the same run.

Run: ``python -m experiments.measurements.speed.jax_vector_default [--id mrd_env/QuarterCar-v1] [--n 256]
[--repeats 3] [--window 1.5] [--out results/bench_jax_vector_default.json]`` (CPU; needs ``mrd-env[jax]``).
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from experiments.measurements.speed.jax_quarter_car import load_average


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--id", default="mrd_env/QuarterCar-v1", help="the environment id")
    ap.add_argument("--n", type=int, default=256, help="environments in the batch")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per figure; the median is reported")
    ap.add_argument("--window", type=float, default=1.5, help="seconds of one timed run")
    ap.add_argument("--out", type=Path, default=Path("results/bench_jax_vector_default.json"))
    args = ap.parse_args(argv)
    if args.n < 1 or args.repeats < 1 or args.window <= 0:
        ap.error("--n and --repeats must be >= 1, --window > 0")
    import gymnasium as gym
    import jax

    import mrd_env  # noqa: F401  (registers the environments)
    from mrd_env.report import markdown_table
    from mrd_env.stepping.first_use import set_mode
    from mrd_env.storage import writable_folder, write_json

    set_mode("wait")  # the compiled numba kernel, never the interpreted one of a first use
    writable_folder(args.out.parent)
    N = args.n
    make = lambda **kw: gym.make_vec(args.id, num_envs=N, vectorization_mode="vector_entry_point", **kw)  # noqa: E731
    envs = {"native": make(), "jax default": make(backend="jax"), "jax exact": make(backend="jax", scheme="exact"),
            "jax differentiable": make(backend="jax", scheme="differentiable")}
    default_scheme = envs["jax default"].params.scheme
    rng = np.random.default_rng(N)
    space = envs["native"].action_space
    pool = [rng.uniform(space.low, space.high, space.shape) for _ in range(32)]
    for env in envs.values():
        env.reset(seed=0)

    def run(env, n):
        t0 = time.perf_counter()
        for k in range(n):
            env.step(pool[k % len(pool)])
        return N * n / (time.perf_counter() - t0)

    load0 = load_average()
    # a warm-up (the compiles) and a first run that sizes each timed run to about `window` seconds
    counts = {}
    for label, env in envs.items():
        run(env, 2)
        counts[label] = max(2, int(args.window * run(env, 2) / N))
    rates: dict[str, list] = {k: [] for k in envs}
    for _ in range(args.repeats):
        for label, env in envs.items():
            rates[label].append(run(env, counts[label]))
    load1 = load_average()
    threads = envs["native"].unwrapped.core.driver.threads
    for env in envs.values():
        env.close()
    ref = float(np.median(rates["native"]))
    rows = [{"environment": label + (f" ({default_scheme})" if label == "jax default" else ""),
             "env-steps/s": float(np.median(r)), "x native": float(np.median(r)) / ref, "runs": [round(x) for x in r],
             "steps per run": counts[label]} for label, r in rates.items()]
    out = {"id": args.id, "N": N, "repeats": args.repeats, "window_s": args.window, "default_scheme": default_scheme,
           "native_threads": threads, "load_before": load0, "load_after": load1, "jax": jax.__version__,
           "device": str(jax.devices()[0]), "cpus": os.cpu_count(), "machine": platform.platform(), "rows": rows}
    out["markdown"] = markdown_table([{k: v for k, v in r.items() if k != "runs"} for r in rows],
                                     title=f"{args.id}, N = {N}: env-steps/s, median of {args.repeats} (load "
                                           f"{load0} / {load1})", floatfmt=".3g")
    write_json(args.out, out, indent=1)
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
