"""``mrd-env yardstick``: solve (or load from the cache) the yardstick of every held-out test episode, evaluate every
controller on the same episodes and write the shares of the achievable gain (:mod:`experiments.benchmark.yardstick`
computes them). The yardstick table gives per episode R_p, R_c, the active bound R_b and the passivity-aware bound
R_d, each with its bracket."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..common.plants import (add_plant_options, chosen_plants, plant_choices, plant_name, shipped_agents_of,
                             with_plant_options)
from ..common.scenarios import held_out_scenarios
from experiments.benchmark.yardstick import check_plant, write_report, yardsticks

def add_arguments(p: argparse.ArgumentParser) -> None:
    from ..common import sweep

    p.add_argument("--plant", type=plant_name, choices=plant_choices(both=True), default="both",
                   help="a plant with a yardstick, or both (building and quarter car)")
    p.add_argument("--seeds", type=int, default=3, help="episodes per random test scenario (default 3)")
    p.add_argument("--quick", action="store_true", help="short scenarios (a smoke run)")
    p.add_argument("--no-bound", action="store_true",
                   help="skip the bounds (the active-actuator bound and the passivity-aware bound beside it)")
    p.add_argument("--no-cache", action="store_true", help="solve again even where a cached result exists")
    p.add_argument("--out", type=Path, default=Path("results/yardstick"))
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)
    add_plant_options(p)


def run(args: argparse.Namespace) -> int:
    from ..common import sweep
    from ..common.comparison import evaluate

    if args.seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {args.seeds}")
    plants = with_plant_options([p for p in chosen_plants(args.plant) if args.plant != "all" or p.warm_laws], args)
    for plant in plants:
        check_plant(plant)
    executor = sweep.options(args)
    args.out.mkdir(parents=True, exist_ok=True)
    for plant in plants:
        scen = held_out_scenarios(plant, seeds=args.seeds, quick=args.quick)
        agents = shipped_agents_of(plant)
        t0 = time.perf_counter()
        ys = yardsticks(plant, scen, agents=agents, bound=not args.no_bound, cache=not args.no_cache,
                        progress=not args.no_progress, **executor)
        print(f"{plant.name}: {len(ys)} yardsticks in {time.perf_counter() - t0:.0f} s")
        # every controller on the same episodes: the laws at the agents' step and at 1 ms, MPC, the agents
        res = evaluate(plant, agents, seeds=args.seeds, progress=not args.no_progress, quick=args.quick,
                       **executor)
        print(write_report(plant, res, ys, args.out, len(ys)))
        print(f"wrote {args.out}/{plant.name}_yardstick.md/.csv, {plant.name}_shares.md/.csv/.png")
    return 0
