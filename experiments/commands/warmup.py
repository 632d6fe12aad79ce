"""``mrd-env warmup``: compile every damper model's kernels into the disk cache now, once, instead of on the first
use of each model (15–25 s a model): the environments' scalar and vector steps and the rig's stepper
(:func:`mrd_env.warmup.warm`). Without it, a first use steps the interpreted kernel while a background process
compiles (:mod:`mrd_env.stepping.first_use`).

Run it after installing (or before a class: the labs then start at once). The cache is
``$MRD_ENV_CACHE_DIR/kernels`` (else ``~/.cache/mrd-env/kernels``; :mod:`mrd_env.caches`); every later process
finds it. The models compile in parallel on a local process pool (``--jobs``, default: every core; numba
compiles one function at a time, so a model's compilation cannot be split, but models can run side by side).
"""
from __future__ import annotations

import argparse
import time

from mrd_env.warmup import warm


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
