"""Wall time of one ``env.step`` of each plant against the reference plant's (the single-plant commands' default,
the quarter car), measured in the same run.

Run: ``python -m experiments.measurements.speed.plant_step [--plant NAME ...] [--steps 5000] [--repeats 7]
[--out results/bench]``.

Each plant's physics id with its default options (its default road or record, damper and sensors; a 60 s episode
where the plant takes ``episode_seconds``), at a 1 ms control step (one physics step per ``env.step``) and at
10 ms (ten). The rows are interleaved within each repeat and each figure is the median over the repeats; the ratio
to the reference is the median of the per-repeat ratios (a machine that slows for a while slows both sides alike).
The commands alternate between v_min and v_max every 50 steps; the kernels are compiled and warmed up first; the
load average is printed with the table.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from experiments.measurements.speed.envs import make_env, time_steps
from mrd_env import storage
from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def bench(names, steps: int = 5000, repeats: int = 7) -> tuple[list[dict], str]:
    from mrd_env.plants import plants

    specs = plants()
    reference = next(s for s in specs.values() if s.profile.train_default)
    chosen = [reference] + [specs[n] for n in names if n != reference.name]
    cases = []
    for spec in chosen:
        for control_dt in (1e-3, 1e-2):
            kw = {"control_dt": control_dt}
            try:
                env = make_env(spec.physics_id, episode_seconds=60.0, **kw)
            except (TypeError, ValueError):
                env = make_env(spec.physics_id, **kw)
            acts = (env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64))
            time_steps(env, 200, acts)  # compile and warm up
            cases.append((spec, control_dt, env, acts))
    runs: dict[tuple, list] = {}
    for _ in range(repeats):
        for spec, control_dt, env, acts in cases:
            n_sub = int(round(control_dt / 1e-3))
            runs.setdefault((spec.name, control_dt), []).append(time_steps(env, max(steps // n_sub, 300), acts))
    rows = []
    for spec, control_dt, env, _ in cases:
        us = runs[(spec.name, control_dt)]
        ref = runs[(reference.name, control_dt)]
        rows.append({"plant": spec.title, "control_dt_ms": control_dt * 1e3,
                     "dampers": int(np.prod(env.action_space.shape)), "us_per_env_step": float(np.median(us)),
                     f"x_{reference.name}": float(np.median(np.array(us) / np.array(ref)))})
        env.close()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return rows, f"load average (1, 5, 15 min) after the run: {load} on {os.cpu_count()} cores"


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plant", nargs="*", default=None, help="plants to time beside the reference (default: all)")
    ap.add_argument("--steps", type=int, default=5000, help="simulated ms per timing run")
    ap.add_argument("--repeats", type=int, default=7, help="timing runs per row; the median is reported")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    from mrd_env.plants import plants

    names = list(plants()) if args.plant is None else args.plant
    unknown = sorted(set(names) - set(plants()))
    if unknown:
        ap.error(f"--plant: unknown plant(s) {unknown}; plants: {sorted(plants())}")
    rows, load = bench(names, args.steps, args.repeats)
    md, _ = write_table(rows, args.out / "plant_step", title="One env.step per plant (gymnasium.make, same run)",
                        floatfmt=".3g")
    text = md.read_text() + f"\n{load}\n"
    storage.write_text(md, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
