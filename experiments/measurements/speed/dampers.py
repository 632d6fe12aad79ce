"""Speed of the damper stepping routine next to Gymnasium's CartPole-v1 (issue: foundation).

Run: ``python -m experiments.measurements.speed.dampers [--model spencer_dyke] [--out results/bench]``.
Reports µs per damper step for N = 1 (inside one long record, and one call per step as an environment
makes them) and damper-steps per second for a batch of N = 4096, with CartPole-v1's ``env.step`` time
measured in the same run. Input: 1.5 cm at 2.5 Hz (0.24 m/s peak) at the maximum command.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mrd_env.dampers import make_damper
from mrd_env.stepping import Driver, Processing, SystemMatrices, run

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def _inputs(N, n, dt, rng):
    t = np.arange(n + 1) * dt
    f = 2.5 * (1 + 0.2 * rng.random((N, 1)))  # slightly different records so the batch is not degenerate
    w = 2 * np.pi * f
    X = 0.015
    return np.ascontiguousarray(np.stack([X * np.sin(w * t), X * w * np.cos(w * t), -X * w * w * np.sin(w * t)],
                                         axis=2))


def bench_model(name: str, n_long: int = 20000, n_batch: int = 4096, n_batch_steps: int = 200) -> list[dict]:
    d = make_damper(name)
    dt = 1e-3
    rng = np.random.default_rng(0)
    sysm = SystemMatrices.displacement_driven()
    vmax = d.command.v_max

    def go(N, n, W):
        Y = np.tile(d.initial_state(), (N, 1))
        return run(d, sysm, Y, np.full((N, 1), vmax), np.full((N, n, 1), vmax), W, dt)

    go(1, 10, _inputs(1, 10, dt, rng))  # compile
    W = _inputs(1, n_long, dt, rng)
    t0 = time.perf_counter()
    _, _, nsub = go(1, n_long, W)
    long_us = (time.perf_counter() - t0) / n_long * 1e6
    # one compiled call per 1 ms step, as an environment makes them (the driver, one period per call)
    drv = Driver(d, sysm, 1, Processing(G=np.zeros((1, d.n_states + 1 + 3))), dt=dt, n_sub=1)
    drv.set_inputs(W, n_long)
    drv.reset(Y0=d.initial_state()[None], U0=np.full((1, 1), vmax))
    action = np.array([vmax])
    n_calls = 5000
    drv.step(action)
    t0 = time.perf_counter()
    for _ in range(n_calls):
        drv.step(action)
    call_us = (time.perf_counter() - t0) / n_calls * 1e6
    Wb = _inputs(n_batch, n_batch_steps, dt, rng)
    t0 = time.perf_counter()
    go(n_batch, n_batch_steps, Wb)
    el = time.perf_counter() - t0
    return [{"model": name, "case": "N=1, one 20 s record", "us_per_damper_step": long_us,
             "damper_steps_per_s": 1e6 / long_us, "mean_substeps": float(nsub.mean())},
            {"model": name, "case": "N=1, one compiled call per step", "us_per_damper_step": call_us,
             "damper_steps_per_s": 1e6 / call_us, "mean_substeps": float("nan")},
            {"model": name, "case": f"N={n_batch} batch", "us_per_damper_step": el / (n_batch * n_batch_steps) * 1e6,
             "damper_steps_per_s": n_batch * n_batch_steps / el, "mean_substeps": float("nan")}]


def bench_cartpole(n: int = 20000) -> dict:
    import gymnasium as gym

    env = gym.make("CartPole-v1")
    env.reset(seed=0)
    a = 0
    t0 = time.perf_counter()
    for _ in range(n):
        _, _, term, trunc, _ = env.step(a)
        a = 1 - a
        if term or trunc:
            env.reset()
    us = (time.perf_counter() - t0) / n * 1e6
    return {"model": "CartPole-v1 (gymnasium.make)", "case": "env.step", "us_per_damper_step": us,
            "damper_steps_per_s": 1e6 / us, "mean_substeps": float("nan")}


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", nargs="+", default=["spencer_dyke", "bouc_wen", "bingham"])
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    rows = [r for m in args.models for r in bench_model(m)] + [bench_cartpole()]
    md, _ = write_table(rows, args.out / "damper_speed", title="Damper stepping speed (1 kHz, 2 cores)",
                        floatfmt=".3g")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
