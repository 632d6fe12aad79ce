"""Why Stable-Baselines3 called directly is slow (issue 49, item 1): PPO steps/s under settings that isolate the cause,
in one run (a script, not a test).

    python -m experiments.measurements.speed.sb3_direct [--timesteps 4096] [--repeats 3] [--variants ...] [--cold]
                                                   [--out results/bench/sb3_direct]

Each run is a fresh Python process (torch's threads, OpenMP's and numba's are set once per process) that trains
``PPO("MlpPolicy", gym.make(ENV), n_steps=1024, seed=0, device="cpu")`` for ``timesteps`` steps, SB3's defaults
otherwise (batch 64, 10 epochs), as the issue's user did. The figure is steps per second of ``model.learn``
(imports and process start excluded), split into the rollouts (environment and policy inference) and the updates
(gradient steps). The variants:

- ``default``: torch's default intra-op threads (every core), the kernel cache warm;
- ``torch1``: ``torch.set_num_threads(1)`` first (the fix);
- ``omp_passive``: default threads, ``OMP_WAIT_POLICY=PASSIVE`` (idle OpenMP threads sleep rather than spin);
- ``mkl1``: default torch threads, ``MKL_NUM_THREADS=1`` (MKL's matrix products on one thread);
- ``numba1``: default torch threads, ``NUMBA_NUM_THREADS=1`` (numba's threading layer out of the way);
- ``wait``: default threads, ``MRD_ENV_FIRST_USE=wait`` (no background compiler can run);
- ``pendulum``, ``pendulum_torch1``: Gymnasium's ``Pendulum-v1`` (no mrd_env, no numba) with and without the fix;
- with ``--cold``: ``cold``, ``cold_torch1``: an empty kernel cache (``MRD_ENV_CACHE_DIR`` a new folder), so the
  kernel runs interpreted while the background compiler compiles it (first use; not the steady state).

The variants alternate, ``repeats`` times each; the median steps/s is reported with its ratio to ``default`` and the
load average before and after.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ENV_ID = "mrd_env/QuarterCar-v1"

CHILD = """
import json, sys, time, os
import torch
if {one}:
    torch.set_num_threads(1)
import gymnasium as gym
import mrd_env  # noqa: F401
from stable_baselines3 import PPO
env = gym.make({env_id!r})
model = PPO("MlpPolicy", env, n_steps={n_steps}, seed=0, device="cpu", verbose=0)
spent = {{"rollouts": 0.0, "updates": 0.0}}
def timed(f, key):
    def g(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            spent[key] += time.perf_counter() - t
    return g
model.collect_rollouts = timed(model.collect_rollouts, "rollouts")
model.train = timed(model.train, "updates")
t0 = time.perf_counter()
model.learn(total_timesteps={timesteps})
wall = time.perf_counter() - t0
print(json.dumps({{"steps": int(model.num_timesteps), "wall": wall, "threads": torch.get_num_threads(), **spent}}))
"""

#: name: (environment, torch.set_num_threads(1), extra environment variables)
VARIANTS = {
    "default": (ENV_ID, False, {}),
    "torch1": (ENV_ID, True, {}),
    "omp_passive": (ENV_ID, False, {"OMP_WAIT_POLICY": "PASSIVE"}),
    "mkl1": (ENV_ID, False, {"MKL_NUM_THREADS": "1"}),
    "numba1": (ENV_ID, False, {"NUMBA_NUM_THREADS": "1"}),
    "wait": (ENV_ID, False, {"MRD_ENV_FIRST_USE": "wait"}),
    "pendulum": ("Pendulum-v1", False, {}),
    "pendulum_torch1": ("Pendulum-v1", True, {}),
}
COLD = {"cold": (ENV_ID, False, {}), "cold_torch1": (ENV_ID, True, {})}


def one_run(name: str, spec, timesteps: int, n_steps: int) -> dict:
    env_id, one, extra = spec
    env = {k: v for k, v in os.environ.items()
           if k not in ("OMP_WAIT_POLICY", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS", "MRD_ENV_FIRST_USE")}
    env.update(extra)
    env["PYTHONWARNINGS"] = "ignore"  # the library's torch-threads warning is not what is timed
    code = CHILD.format(one=one, env_id=env_id, n_steps=n_steps, timesteps=int(timesteps))
    with tempfile.TemporaryDirectory(prefix="mrd-env-cold-") as cold:
        if name.startswith("cold"):
            env["MRD_ENV_CACHE_DIR"] = cold
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=1800)
    if out.returncode:
        raise RuntimeError(f"{name}: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--timesteps", type=int, default=4096, help="steps per run (default 4096)")
    ap.add_argument("--n-steps", type=int, default=1024, help="PPO's rollout length (default 1024)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS) + list(COLD))
    ap.add_argument("--cold", action="store_true", help="add the empty-kernel-cache variants")
    ap.add_argument("--out", default=None, help="write <out>.md and <out>.csv")
    args = ap.parse_args(argv)
    if args.timesteps < args.n_steps or args.n_steps < 64:
        ap.error(f"--timesteps ({args.timesteps}) must be at least --n-steps ({args.n_steps}), itself at least 64")
    specs = {**VARIANTS, **COLD}
    names = list(dict.fromkeys(args.variants + (list(COLD) if args.cold else [])))
    if "default" not in names:
        names.insert(0, "default")
    load0 = os.getloadavg()
    runs: dict[str, list[dict]] = {n: [] for n in names}
    for _ in range(args.repeats):
        for name in names:
            r = one_run(name, specs[name], args.timesteps, args.n_steps)
            runs[name].append(r)
            print(f"{name} ({r['threads']} torch threads): {r['steps'] / r['wall']:.0f} steps/s, rollouts "
                  f"{r['rollouts']:.2f} s, updates {r['updates']:.2f} s (load {os.getloadavg()[0]:.2f})", flush=True)
    load1 = os.getloadavg()
    med = {n: statistics.median(r["steps"] / r["wall"] for r in rs) for n, rs in runs.items()}
    rows = [{"variant": n, "environment": specs[n][0], "torch threads": rs[0]["threads"],
             "settings": " ".join(f"{k}={v}" for k, v in specs[n][2].items()) or "-",
             "steps/s (median)": med[n], "steps/s (each run)": " ".join(f"{r['steps'] / r['wall']:.0f}" for r in rs),
             "rollouts s (median)": statistics.median(r["rollouts"] for r in rs),
             "updates s (median)": statistics.median(r["updates"] for r in rs),
             "ratio to default": med[n] / med["default"]} for n, rs in runs.items()]
    from mrd_env.report import markdown_table, write_table

    title = (f"SB3 PPO('MlpPolicy', gym.make(ENV), n_steps={args.n_steps}), {args.timesteps} steps per run, "
             f"{args.repeats} runs each, {os.cpu_count()} cores, load average {load0[0]:.2f} → {load1[0]:.2f}")
    print(markdown_table(rows, title=title))
    if args.out:
        for path in write_table(rows, args.out, title=title):
            print("wrote", path)


if __name__ == "__main__":
    main()
