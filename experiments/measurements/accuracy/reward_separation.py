"""Do the rewards separate controllers? Random commands, passive-off, passive-on and the best classical law on
every held-out test scenario, at the agents' 10 ms control step: mean return and the paired difference between
neighbours in the ranking (same seeds, so road-to-road variation cancels), with 95 % intervals over seeds.

    python -m experiments.measurements.accuracy.reward_separation [--plant both] [--seeds 5] [--out results/reward_separation]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mrd_env.report import write_table

from experiments.common.evaluation import evaluate_batch, mean_ci
from experiments.common.plants import PlantProfile, chosen_plants, plant_choices, plant_name
from experiments.common.scenarios import held_out_scenarios
from mrd_env.stepping.first_use import set_mode


def separation(plant: PlantProfile, seeds: int = 5, control_dt: float = 0.01) -> list[dict]:
    """The plant's laws on its test scenarios (see the module docstring): one row per law ranked."""
    from controllers import make_controller

    rows = []
    for sc in held_out_scenarios(plant, seeds=seeds):
        ret = {}
        for name in plant.laws:
            eps = evaluate_batch(lambda v, n=name: make_controller(n, v), sc, "", control_dt=control_dt)
            ret[name] = np.array([e.episode_return for e in eps])
        best = max((n for n in ret if n not in ("random", "passive_off", "passive_on")),
                   key=lambda n: ret[n].mean())
        order = sorted(("random", "passive_off", "passive_on", best), key=lambda n: -ret[n].mean())
        for i, name in enumerate(order):
            m, lo, hi = mean_ci(ret[name])
            row = {"scenario": sc.name, "controller": name + (" (best law)" if name == best else ""),
                   "episodes": ret[name].size, "return": m, "return_lo95": lo, "return_hi95": hi}
            if i + 1 < len(order):
                d, dlo, dhi = mean_ci(ret[name] - ret[order[i + 1]])
                row.update({"minus_next": d, "minus_next_lo95": dlo, "minus_next_hi95": dhi})
            else:
                row.update({"minus_next": np.nan, "minus_next_lo95": np.nan, "minus_next_hi95": np.nan})
            rows.append(row)
    return rows


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--plant", type=plant_name, choices=plant_choices(both=True), default="both")
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--out", type=Path, default=Path("results/reward_separation"))
    args = p.parse_args(argv)
    import mrd_env  # noqa: F401

    for plant in chosen_plants(args.plant):
        rows = separation(plant, args.seeds)
        md, _ = write_table(rows, args.out / f"{plant.name}_separation", floatfmt=".4g",
                            title=f"{plant.name}: returns at 10 ms (ranked) and the paired gap to the next (95 % "
                                  "intervals)")
        print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
