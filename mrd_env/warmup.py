"""Compile a damper model's kernels into the disk cache: what a first use of the model compiles (a scalar
environment step and the rig's stepper, then a threaded vector environment step), leaving the kernel's ready
markers (:mod:`mrd_env.stepping.first_use`: one after the serial entry points, one at the end).

``mrd-env warmup`` runs it for every model; :mod:`mrd_env.stepping.first_use` runs
``python -m mrd_env.warmup <model>`` in the background while a first use steps the interpreted kernel.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


def warm(model: str) -> float:
    """Compile what a first use of ``model`` compiles and mark its kernel ready; the seconds it took (a fraction
    of a second when the cache already holds it)."""
    import gymnasium as gym

    from . import envs  # noqa: F401  (registers the environments)
    from .dampers import damper_class
    from .rig import sinusoidal_test
    from .stepping import first_use
    from .stepping.codegen import kernel_module, kernel_path

    t0 = time.perf_counter()
    cls = damper_class(model)
    kernel_module(cls, compiled=True)  # the module itself, whatever MRD_ENV_FIRST_USE says
    env = gym.make("mrd_env/QuarterCar-v1", damper=model, episode_seconds=0.01)
    env.reset(seed=0)
    env.step(env.action_space.low)
    sinusoidal_test(model, 0.01, 2.0, [0.0], cycles=0.01)
    first_use.mark_ready(kernel_path(cls), "serial")  # a first use's scalar steps switch now, before the threads
    venv = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=64, vectorization_mode="vector_entry_point",
                        damper=model, episode_seconds=0.01)  # 64: the threaded path
    venv.reset(seed=0)
    venv.step(venv.action_space.sample())
    venv.close()
    first_use.mark_ready(kernel_path(cls))
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("model", help="damper model")
    ap.add_argument("--lock", type=Path, default=None, help="lock file to remove when done (first use)")
    args = ap.parse_args(argv)
    try:
        print(f"{args.model}: compiled in {warm(args.model):.1f} s", flush=True)
    finally:
        if args.lock is not None:
            args.lock.unlink(missing_ok=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
