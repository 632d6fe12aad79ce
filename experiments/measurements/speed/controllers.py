"""µs per ``predict`` call of every controller, next to the environment step it drives (issue: controllers).

Run: ``python -m experiments.measurements.speed.controllers``. Observations are recorded from a real episode
first, so each law sees realistic signals; the table also gives ``env.step`` for scale.
"""
from __future__ import annotations

import time

import gymnasium as gym

import mrd_env  # noqa: F401  (registers the environments)
from controllers import available_controllers, make_controller

from experiments.common.plants import chosen_plants
from mrd_env.report import markdown_table
from mrd_env.stepping.first_use import set_mode


def bench(env_id: str, names, n: int = 3000) -> list[dict]:
    env = gym.make(env_id, episode_seconds=n * 1e-3 + 0.01)  # the default sensors, as the benchmark
    obs, _ = env.reset(seed=0)
    observations = []
    t0 = time.perf_counter()
    for _ in range(n):
        obs, *_ = env.step(env.action_space.high)
        observations.append(obs)
    step_us = (time.perf_counter() - t0) / n * 1e6
    rows = [{"env": env_id, "controller": "(env.step)", "us_per_call": step_us}]
    for name in names:
        ctrl = make_controller(name, env)
        ctrl.reset()
        for o in observations[:50]:
            ctrl.predict(o)
        t0 = time.perf_counter()
        for o in observations:
            ctrl.predict(o)
        rows.append({"env": env_id, "controller": name, "us_per_call": (time.perf_counter() - t0) / n * 1e6})
    env.close()
    return rows


def main() -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    plants = chosen_plants("both")  # the published benchmark's plants, with their benchmark laws
    assert {law for p in plants for law in p.benchmark_laws} <= set(available_controllers())
    rows = [row for p in plants for row in bench(p.env_id, p.benchmark_laws)]
    print(markdown_table(rows, title="Controller predict() cost (µs per call)", floatfmt=".3g"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
