"""``mrd-env evaluate``: agents and classical laws side by side on the held-out test scenarios.

Every controller sees the same sensors at the same control step: the agents' (their observation options,
:data:`controllers.agents.OBSERVATION_OPTIONS`), which are the plant's measured set by default; the laws run
there too, and once more at 1 ms (their own best rate) as extra rows. For each controller and scenario: the
environment's return and the field's metrics (quarter car: Wk-weighted r.m.s. acceleration, travel, tyre load;
building: J1–J6), mean and 95 % interval over seeds and episodes (for agents, over their training seeds too);
then the mean over all test scenarios. Writes ``<out>/<plant>_evaluation.md``/``.csv`` and
``<out>/<plant>_evaluation.png`` (returns with their intervals), and ``<out>/<plant>_paired.md``/``.csv``: each
agent minus the best law at each control step on the same episodes (:func:`paired`). By default the agents shipped with the project
(``controllers/agents/``) are evaluated. Agents load without running code from their folders; one that only has
SB3's ``model.zip`` (pickles) is refused unless ``--trust-agent`` is given (docs/security.md).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mrd_env.report import write_table

from ..benchmark import yardstick
from ..common import sweep
from ..common.comparison import comparison_damper, evaluate
from ..common.evaluation import Episode, check_laws, episode_means, grouped_bars, mean_ci
from ..common.plants import (PlantProfile, add_plant_options, check_agent_plant, chosen_plants, plant_choices,
                             plant_name, shipped_agents_of, with_plant_options)
from ..common.scenarios import base_scenario, held_out_scenarios


def summarise(plant: PlantProfile, results: dict[str, list[Episode]]) -> list[dict]:
    """Rows: per scenario and controller, mean and 95 % interval over the episodes of the return and the mean of
    the plant's metrics (:attr:`~experiments.common.plants.PlantProfile.evaluation_metrics`; an agent trained on
    several seeds with its seeds' mean on each episode); then the mean over the test scenarios (``all test
    scenarios``)."""
    rows = []
    scen = list(dict.fromkeys(base_scenario(e.scenario) for eps in results.values() for e in eps))
    for s in scen + ["all test scenarios"]:
        for ctrl, eps in results.items():
            mine = [e for e in eps if s == "all test scenarios" or base_scenario(e.scenario) == s]
            if not mine:
                continue
            returns = list(episode_means(mine).values())
            m, lo, hi = mean_ci(returns, upper=0.0)
            row = {"scenario": s, "controller": ctrl, "episodes": len(returns), "return": m, "return_lo95": lo,
                   "return_hi95": hi}
            for k in plant.evaluation_metrics:
                row[k] = float(np.mean(list(episode_means(mine, lambda e, k=k: e.metrics.get(k, np.nan)).values())))
            row["terminated"] = sum(1 for e in mine if "terminated" in e.metrics)
            rows.append(row)
    return rows


def paired(results: dict[str, list[Episode]]) -> list[dict]:
    """Each agent against the best law (by mean return over the test scenarios; random commands excluded) at each
    control step, episode by episode — the same roads or ground motions, so their variation cancels: the mean
    difference of return (positive: the agent is better) and its 95 % interval, per scenario and over all. An
    agent trained on several seeds counts with its mean over the seeds on each episode."""
    agents = [c for c in results if c.startswith("agent ")]
    # the best law on equal information: random commands and the preview rows (which see the road ahead) excluded
    laws = [c for c in results if not c.startswith(("agent ", "random ")) and "preview" not in c]
    rows = []
    for a in agents:
        mine = episode_means(results[a])
        for rate in dict.fromkeys(c.split(" @ ")[-1] for c in laws):
            at_rate = [c for c in laws if c.endswith(f"@ {rate}")]
            best = max(at_rate, key=lambda c: np.mean([e.episode_return for e in results[c]]))
            law = episode_means(results[best])
            labels = [k for k in mine if k in law]
            scen = list(dict.fromkeys(base_scenario(k) for k in labels))
            for s in scen + ["all test scenarios"]:
                diff = [mine[k] - law[k] for k in labels if s == "all test scenarios" or base_scenario(k) == s]
                m, lo, hi = mean_ci(diff)
                rows.append({"comparison": f"{a} − {best}", "scenario": s, "episodes": len(diff),
                             "difference": m, "difference_lo95": lo, "difference_hi95": hi})
    return rows


def plot(plant: PlantProfile, rows: list[dict], path: Path) -> Path:
    """Mean return with its 95 % interval per controller, one group per scenario."""
    return grouped_bars(rows, "return", "return_lo95", "return_hi95", path,
                        xlabel="episode return (dimensionless)",
                        title=f"{plant.name}: agents and classical laws on the held-out test scenarios")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", type=plant_name, choices=plant_choices(both=True), default="both",
                   help="a plant, both (building and quarter car) or all")
    p.add_argument("--agents", type=Path, nargs="*", default=None,
                   help="agent folders (or files in them) written by mrd-env train (default: the shipped agents)")
    p.add_argument("--laws", nargs="*", default=None, help="classical laws (default: all that apply)")
    p.add_argument("--seeds", type=int, default=3, help="episodes per random test scenario (default 3)")
    p.add_argument("--control-dt", type=float, default=None,
                   help="control step of the comparison (default: the agents'; 1 ms without agents)")
    p.add_argument("--no-1ms", action="store_true", help="do not add the laws at their own 1 ms rate")
    p.add_argument("--no-mpc", action="store_true", help="leave out model predictive control (and its preview row)")
    p.add_argument("--damper", default=None,
                   help="damper model name or preset file (fitted.json) of every row (default: the agents' own, "
                        "else the plant's)")
    p.add_argument("--trust-agent", action="store_true",
                   help="also load agents that only have SB3's model.zip: pickled Python objects, which can run any "
                        "code; only for agents from a source you trust (each is converted once into "
                        "<out>/converted-agents/ and evaluated from there)")
    p.add_argument("--quick", action="store_true", help="short scenarios (a smoke run)")
    p.add_argument("--out", type=Path, default=Path("results/evaluate"))
    p.add_argument("--no-progress", action="store_true")
    yardstick.add_mode_argument(p)
    sweep.add_arguments(p)
    add_plant_options(p)


def run(args: argparse.Namespace) -> int:
    from controllers.agents import agent_files, code_free_agent, recorded_plant

    if args.seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {args.seeds}")
    plants = with_plant_options(chosen_plants(args.plant), args)
    check_laws("--laws", args.laws, plants)
    executor = sweep.options(args)
    if args.damper is not None:
        from mrd_env.dampers import damper_class
        damper_class(args.damper)  # ValueError naming the models, or the preset file's problem
    args.out.mkdir(parents=True, exist_ok=True)
    if args.control_dt is not None:  # checked by the environment itself, before any episode runs
        import gymnasium as gym

        import mrd_env  # noqa: F401
        for p in plants:
            gym.make(p.env_id, control_dt=args.control_dt).close()
    chosen = {p.name: [] for p in plants}
    if args.agents is None:
        for p in plants:
            chosen[p.name] = shipped_agents_of(p)  # those trained on the plant as chosen
    else:
        for a in args.agents:
            trained_on = recorded_plant(agent_files(a)[1])  # ValueError for a bad path
            if trained_on not in chosen:
                raise ValueError(f"agent {a} was trained on the {trained_on} plant; add --plant {trained_on}")
            chosen[trained_on].append(a)
    # an SB3 zip is loaded only if trusted, once, here: the rows load its code-free copy
    chosen = {name: [code_free_agent(a, args.out / "converted-agents", trust=args.trust_agent) for a in agents]
              for name, agents in chosen.items()}
    for plant in plants:
        name, agents = plant.name, chosen[plant.name]
        for a in agents:
            check_agent_plant(plant, str(a), agent_files(a)[1].get("env_kwargs") or {})
        res = evaluate(plant, agents, args.laws, seeds=args.seeds, control_dt=args.control_dt, damper=args.damper,
                       laws_at_1ms=not args.no_1ms, mpc=not args.no_mpc, progress=not args.no_progress,
                       quick=args.quick, **executor)
        rows = summarise(plant, res)
        md, csv_path = write_table(rows, args.out / f"{name}_evaluation", floatfmt=".4g",
                                   title=f"{name}: return and metrics on the held-out test scenarios (mean, 95 % "
                                         "interval)")
        fig = plot(plant, [r for r in rows if r["scenario"] != "all test scenarios"],
                   args.out / f"{name}_evaluation.png")
        print(md.read_text())
        print(f"wrote {md}, {csv_path}, {fig}")
        pairs = paired(res)
        if pairs:
            md, _ = write_table(pairs, args.out / f"{name}_paired", floatfmt=".4g",
                                title=f"{name}: agent minus the best law at each control step, on the same episodes "
                                      "(mean, 95 % interval; positive: the agent is better)")
            print(md.read_text())
        damper = comparison_damper(args.damper, [agent_files(a)[1].get("env_kwargs") or {} for a in agents])
        text = yardstick.report(plant, res, held_out_scenarios(plant, seeds=args.seeds, quick=args.quick), args.out,
                                args.yardstick, damper=damper, progress=not args.no_progress, **executor)
        if text:
            print(text)
    return 0
