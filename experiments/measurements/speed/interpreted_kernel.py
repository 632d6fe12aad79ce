"""The stepping kernel run by the Python interpreter instead of numba: is it the same bit for bit, and how slow?
(issue: speed where users wait — a first use that does not wait for the compiler.)

Run: ``python -m experiments.measurements.speed.interpreted_kernel [--model spencer_dyke] [--steps 300]``.

A damper model's generated kernel source (:func:`mrd_env.stepping.codegen.kernel_source`) is executed as plain
Python (:func:`mrd_env.stepping.first_use.interpreted_module`: ``nb.njit`` the identity, ``prange`` = ``range``),
and a QuarterCarPhysical-v0 episode with sensor noise (which
exercises the counter-based Gaussian generator's 64-bit wrap-around) is stepped once by the compiled kernel and
once by the interpreted one, same seed and same random actions. If the two agree bit for bit, an environment can
step interpreted while a background process compiles, and switch to the compiled kernel when the disk cache holds
it, without changing any result: what :mod:`mrd_env.stepping.first_use` does on a first use with an empty cache.
"""
from __future__ import annotations

import argparse
import time
import types

import numpy as np


def interpreted_kernel(model_cls) -> types.ModuleType:
    """The kernel module of ``model_cls`` as Python code (no compilation)."""
    from mrd_env.stepping.codegen import kernel_prefix, kernel_source
    from mrd_env.stepping.first_use import interpreted_module

    return interpreted_module(kernel_prefix(model_cls), kernel_source(model_cls)[0])


def episode(model: str, steps: int, interpreted: bool, seed: int = 3):
    """(observations, rewards, µs per step) of a noisy QuarterCarPhysical-v0 episode, the compiled or interpreted step."""
    import warnings

    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    from mrd_env.stepping.first_use import set_mode

    set_mode("wait")  # the compiled row is the compiled kernel, never a first use's interpreted one

    warnings.filterwarnings("ignore", category=RuntimeWarning)  # numpy's uint64 wrap-around, intended
    env = gym.make("mrd_env/QuarterCarPhysical-v0", damper=model, episode_seconds=30.0,
                   sensor_noise={"sprung_acc": 0.05, "travel": 1e-4}).unwrapped
    env.reset(seed=seed)
    if interpreted:
        env._kstep = interpreted_kernel(type(env.assembly.damper)).run_systems
    rng = np.random.default_rng(seed)
    env.step(rng.uniform(env.action_space.low, env.action_space.high))  # the first call's one-off costs, untimed
    obs, rewards = [], []
    t0 = time.perf_counter()
    for _ in range(steps):
        o, r, *_ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
        obs.append(o.copy())
        rewards.append(r)
    return np.array(obs), np.array(rewards), (time.perf_counter() - t0) / steps * 1e6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", nargs="+", default=["spencer_dyke"], help="damper models")
    ap.add_argument("--steps", type=int, default=300)
    args = ap.parse_args(argv)
    if args.steps < 1:
        ap.error("--steps must be >= 1")
    all_same = True
    for model in args.models:
        oc, rc, tc = episode(model, args.steps, False)
        oi, ri, ti = episode(model, args.steps, True)
        same = np.array_equal(oc, oi) and np.array_equal(rc, ri)
        all_same &= same
        print(f"{model:24s} {args.steps} steps of QuarterCarPhysical-v0 with sensor noise: "
              f"{'the same bit for bit' if same else 'DIFFERENT'}; compiled {tc:.1f} µs per step, "
              f"interpreted {ti:.0f} µs per step", flush=True)
    return 0 if all_same else 1


if __name__ == "__main__":
    raise SystemExit(main())
