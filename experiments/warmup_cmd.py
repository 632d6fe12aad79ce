"""``mrd-env warmup``: compile every damper model's kernels into the disk cache now, once, instead of on the first
use of each model (20–25 s a model): the environments' scalar and vector steps and the rig's stepper.

Run it after installing (or before a class: the labs then start at once). The cache is
``$MRD_ENV_CACHE_DIR/kernels`` (else ``~/.cache/mrd-env/kernels``); every later process finds it. The models
compile in parallel on a local process pool (``--jobs``, default: every core; numba compiles one function at a
time, so a model's compilation cannot be split, but models can run side by side).
"""
from __future__ import annotations

import argparse
import time


def warm(model: str) -> float:
    """Compile what a first use of ``model`` compiles (a scalar and a threaded vector environment step, the rig's
    stepper); the seconds it took (a fraction of a second when the cache already holds it)."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    from mrd_env.rig import sinusoidal_test

    t0 = time.perf_counter()
    env = gym.make("mrd_env/QuarterCar-v1", damper=model, episode_seconds=0.01)
    env.reset(seed=0)
    env.step(env.action_space.low)
    venv = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=64, vectorization_mode="vector_entry_point",
                        damper=model, episode_seconds=0.01)  # 64: the threaded path
    venv.reset(seed=0)
    venv.step(venv.action_space.sample())
    venv.close()
    sinusoidal_test(model, 0.01, 2.0, [0.0], cycles=0.01)
    return time.perf_counter() - t0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--models", nargs="+", default=None, help="damper models (default: every registered model)")
    p.add_argument("--jobs", type=int, default=None,
                   help="models compiled side by side, each in its own process (default: every core)")


def run(args: argparse.Namespace) -> int:
    from mrd_env.dampers import available_dampers
    from mrd_env.executor import Task, run_tasks

    models = args.models or available_dampers()
    unknown = [m for m in models if m not in available_dampers()]
    if unknown:
        raise ValueError(f"--models: unknown damper model(s) {unknown}; available: {available_dampers()}")
    if args.jobs is not None and args.jobs < 1:
        raise ValueError(f"--jobs must be an integer >= 1, got {args.jobs}")
    t0 = time.perf_counter()
    seconds = run_tasks([Task(warm, (m,), label=m) for m in models], jobs=args.jobs, desc="warmup", retry=False)
    for m, s in zip(models, seconds):
        print(f"{m:24s} {s:6.1f} s", flush=True)
    print(f"{len(models)} model(s) ready in {time.perf_counter() - t0:.0f} s (wall; {sum(seconds):.0f} s of "
          "compilation in all)")
    return 0
