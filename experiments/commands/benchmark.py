"""``mrd-env benchmark``: a controller × scenario matrix on the same environments, one evaluation loop.

Writes ``<out>/<plant>_benchmark.md`` and ``.csv`` (per scenario and controller, the mean over the scenario's
seeds, then the worst case over the scenarios; headers with units), ``<plant>_benchmark_episodes.csv`` (every
episode), time histories of the key response (the car's sprung acceleration, the drift of the damper's storey)
for passive-off, passive-on and the best controllers by return, one plot per scenario, bar charts of the
normalised metrics (ratios only), and damper force–velocity loops.

Quarter car: Wk-weighted RMS sprung acceleration, RMS and peak suspension travel, RMS dynamic tyre load,
each also normalised by the passive-off damper. Building: peak and RMS interstorey drift, peak absolute
acceleration, peak base shear, peak damper force; J1–J6 normalised by the uncontrolled building.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mrd_env import storage
from mrd_env.report import markdown_table, write_table

from ..benchmark import yardstick
from ..common import sweep
from ..common.evaluation import Episode, applicable_laws, check_laws, controller_episodes
from ..common.plants import (PlantProfile, add_plant_options, check_agent_plant, chosen_plants, plant_choices,
                             plant_name, with_plant_options)
from ..common.scenarios import base_scenario, held_out_scenarios


def run_benchmark(plant: PlantProfile, controllers=None, scenarios=None, *, damper: str = "spencer_dyke",
                  out: Path | None = None, progress: bool = True, quick: bool = False,
                  reference_passive: bool = True, agents=(), backend: str = "serial", jobs: int | None = None,
                  address: str | None = None) -> list[Episode]:
    """Every controller (by default the plant's, :attr:`~experiments.common.plants.PlantProfile.benchmark_laws`) on
    every scenario (all seeds of a scenario in one vector environment), one task each on the chosen backend
    (:mod:`mrd_env.executor`; the episodes are the same on all of them); where the plant has one, also its
    conventional passive reference as a baseline (:attr:`~experiments.common.plants.PlantProfile.passive_reference`:
    the car with the MR damper replaced by the preset's reference dashpot, e.g. 1500 N·s/m for set A)."""
    from mrd_env.executor import Task, run_tasks

    controllers = [*(controllers or plant.benchmark_laws), *(Path(a) for a in agents)]
    scenarios = scenarios or held_out_scenarios(plant, quick=quick)
    reference = plant.passive_reference if reference_passive else None

    def rows(sc) -> list[tuple]:
        """(controller, its task's keywords, label) of every row of scenario ``sc``."""
        out = [(c, {"damper": damper}, str(c)) for c in controllers]
        if reference is not None:  # the passive-off command on the reference damper, under the reference's name
            name, options = reference(sc.options)
            out.append((("passive_off", {}), {"damper": damper, **options, "name": name}, name))
        return out

    per_scenario = [rows(sc) for sc in scenarios]
    tasks = [Task(controller_episodes, (c, sc, plant.response(sc.options)), kw, label=f"{sc.name} / {label}")
             for sc, mine in zip(scenarios, per_scenario) for c, kw, label in mine]
    results = iter(run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress,
                             desc=f"benchmark {plant.name}"))
    by_scenario: dict[str, list[Episode]] = {}
    for sc, mine in zip(scenarios, per_scenario):
        eps = [next(results) for _ in mine]
        # rows: per seed, every controller (the table's order)
        for k in range(len(sc.seeds)):
            by_scenario.setdefault(sc.label(sc.seeds[k]), []).extend(e[k] for e in eps)
    episodes = [e for group in by_scenario.values() for e in group]
    if out is not None:
        write_reports(plant, episodes, Path(out), plant.response(scenarios[0].options))
    return episodes


def _header(k: str, units: dict) -> str:
    """A column's header: its name, with its unit where it has one (:attr:`PlantProfile.metric_units`)."""
    return f"{k} ({units[k]})" if k in units else k


def _rows(plant: PlantProfile, episodes: list[Episode]) -> list[dict]:
    """One row per episode (scenario label, controller): the return and the metrics, the car's also over
    passive-off on the same episode."""
    keys = plant.benchmark_metrics
    rows = []
    for ep in episodes:
        row = {"scenario": ep.scenario, "controller": ep.controller, "return": float(ep.episode_return)}
        for k in keys:
            row[k] = float(ep.metrics.get(k, float("nan")))
        if plant.normalise_by_passive_off:  # normalise by passive-off on the same episode
            ref = next((e for e in episodes if e.scenario == ep.scenario and e.controller == "passive_off"), None)
            for k in keys:
                if ref is not None and ref.metrics.get(k):
                    row[f"{k}/off"] = row[k] / ref.metrics[k]
        row["terminated"] = ep.metrics.get("terminated", "")
        rows.append(row)
    return rows


def scenario_means(rows: list[dict], scenario_of) -> list[dict]:
    """Per scenario and controller, the mean of every numeric column over the scenario's seeds (``episodes``:
    how many)."""
    out = []
    keys = list(dict.fromkeys((scenario_of(r["scenario"]), r["controller"]) for r in rows))
    for scen, ctrl in keys:
        mine = [r for r in rows if scenario_of(r["scenario"]) == scen and r["controller"] == ctrl]
        row = {"scenario": scen, "controller": ctrl, "episodes": len(mine)}
        for k, v in mine[0].items():
            if isinstance(v, float):
                row[k] = float(np.nanmean([m[k] for m in mine]))
        row["terminated"] = sum(1 for m in mine if m.get("terminated"))
        out.append(row)
    return out


def worst_case(rows: list[dict]) -> list[dict]:
    """Per controller, the worst of every numeric column over the scenarios (benchmark convention): the maximum of
    the metrics (smaller is better), the minimum of the return."""
    out = []
    for ctrl in dict.fromkeys(r["controller"] for r in rows):
        mine = [r for r in rows if r["controller"] == ctrl]
        row = {"scenario": "worst over scenarios", "controller": ctrl}
        for k, v in mine[0].items():
            if isinstance(v, float):
                row[k] = float((np.nanmin if k == "return" else np.nanmax)([m[k] for m in mine]))
        out.append(row)
    return out


def _with_units(rows: list[dict], units: dict) -> list[dict]:
    return [{_header(k, units): v for k, v in r.items()} for r in rows]


#: At most this many controllers in a history or loop figure: passive-off, passive-on and the best by return.
HISTORY_LINES = 4


def history_selection(eps: list[Episode]) -> list[Episode]:
    """The controllers a readable history shows: passive-off and passive-on (the bounds of any fixed setting),
    then the best others by return, one per law (a law with an inverse, ``clipped_optimal+model``, draws on top
    of the law itself)."""
    fixed = [e for e in eps if e.controller in ("passive_off", "passive_on")]
    chosen, laws = [], set()
    for e in sorted((e for e in eps if e not in fixed), key=lambda e: -e.episode_return):
        law = e.controller.split("+")[0]
        if law not in laws and len(fixed) + len(chosen) < HISTORY_LINES:
            chosen.append(e)
            laws.add(law)
    return fixed + chosen


def write_reports(plant: PlantProfile, episodes: list[Episode], out: Path, response: str = "") -> dict:
    """The benchmark's tables (headers with the plant's units), histories, loops and bar chart, in ``out``."""
    from mrd_env.report import figure, save_figure

    name, units = plant.name, plant.metric_units
    out.mkdir(parents=True, exist_ok=True)
    rows = _rows(plant, episodes)
    means = scenario_means(rows, base_scenario)
    worst = worst_case(means)
    md, csv_path = write_table(_with_units(means + worst, units), out / f"{name}_benchmark", floatfmt=".4g",
                               title=f"{name}: controller × scenario (mean over each scenario's seeds; metrics "
                                     "in SI, /off: over passive-off on the same episode)")
    write_table(_with_units(rows, units), out / f"{name}_benchmark_episodes", floatfmt=".4g",
                title=f"{name}: every episode (scenario and seed) and controller")
    storage.write_text(out / f"{name}_benchmark_worst.md",
                       markdown_table(_with_units(worst, units), floatfmt=".4g",
                                      title=f"{name}: worst case over scenarios"))
    figs = []
    ylabel, scale = plant.response_axis(response)
    for sc in dict.fromkeys(e.scenario for e in episodes):
        eps = history_selection([e for e in episodes if e.scenario == sc and e.t.size])  # a scenario's first seed
        if not eps:
            continue
        fig, (a1, a2) = figure(2, 1, figsize=(10, 6), sharex=True)
        for e in eps:
            a1.plot(e.t, e.response * scale, lw=0.8, label=e.controller)
            a2.plot(e.t, e.force / 1e3, lw=0.8, label=e.controller)
        a1.set_ylabel(ylabel)
        a2.set_ylabel("damper force (kN)")
        a2.set_xlabel("time (s)")
        a1.legend(fontsize=8, ncol=4)
        a1.set_title(f"{sc}: passive settings and the best controllers by return")
        for a in (a1, a2):
            a.grid(alpha=0.3)
        figs.append(save_figure(fig, out / f"{name}_history_{_slug(sc)}.png"))
        fig, ax = figure(figsize=(6, 4.5))
        for e in eps:
            ax.plot(e.velocity, e.force / 1e3, lw=0.6, label=e.controller)
        ax.set_xlabel("damper velocity (m/s)")
        ax.set_ylabel("damper force (kN)")
        ax.set_title(f"force–velocity: {sc}")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        figs.append(save_figure(fig, out / f"{name}_loops_{_slug(sc)}.png"))
    # one quantity on the axis: every bar is a ratio (car: over passive-off; building: over the uncontrolled)
    keys = list(plant.bar_metrics)
    fig, ax = figure(figsize=(10, 4.5))
    ctrls = [r["controller"] for r in worst]
    width = 0.8 / max(len(keys), 1)
    for i, k in enumerate(keys):
        ax.bar(np.arange(len(ctrls)) + i * width, [r.get(k, np.nan) for r in worst], width, label=k)
    ax.set_xticks(np.arange(len(ctrls)) + 0.4 - width / 2, ctrls, rotation=20, fontsize=8)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel(plant.bar_ylabel)
    ax.set_title(f"{name}: worst case over the test scenarios (smaller is better)")
    ax.legend(fontsize=8, ncol=plant.bar_legend_columns)
    figs.append(save_figure(fig, out / f"{name}_bars.png"))
    return {"markdown": md, "csv": csv_path, "figures": figs}


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in s).strip("_").lower()


# ---------------------------------------------------------------------------- CLI


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", type=plant_name, choices=plant_choices(both=True), default="both",
                   help="a plant, both (building and quarter car) or all")
    p.add_argument("--controllers", nargs="+", default=None, help="controller names (default: all that apply)")
    p.add_argument("--damper", default="spencer_dyke", help="damper model name")
    p.add_argument("--quick", action="store_true", help="short scenarios (a smoke run)")
    p.add_argument("--seeds", type=int, default=3, help="random scenarios per kind (roads, Kanai–Tajimi)")
    p.add_argument("--out", type=Path, default=Path("results/benchmark"))
    p.add_argument("--agent", type=Path, nargs="*", default=[],
                   help="saved agents (a folder, .zip or .json written by mrd-env train) to score too")
    p.add_argument("--trust-agent", action="store_true",
                   help="also load agents that only have SB3's model.zip (pickles: they can run any code; only from a "
                        "source you trust; converted once into <out>/converted-agents/)")
    p.add_argument("--no-progress", action="store_true")
    yardstick.add_mode_argument(p)
    sweep.add_arguments(p)
    add_plant_options(p)


def scenario_rows(scenarios) -> list[dict]:
    """The settings of every scenario (environment, options, seed), printed and written with the tables."""
    return [{"scenario": sc.name, "environment": sc.env_id, "seeds": ", ".join(map(str, sc.seeds)),
             "options": ", ".join(f"{k}={v}" for k, v in sc.options.items()) or "defaults"} for sc in scenarios]


def agent_metadata(path: str | Path) -> dict:
    """The metadata of a saved agent (its folder or a file in it); ``ValueError`` for a missing or bad agent."""
    from controllers.agents import agent_files

    return agent_files(path)[1]


def run(args: argparse.Namespace) -> int:
    from controllers.agents import recorded_plant

    plants = with_plant_options(chosen_plants(args.plant), args)
    agents = {path: recorded_plant(agent_metadata(path)) for path in args.agent}  # ValueError for a bad path
    for path, trained_on in agents.items():
        if trained_on not in [p.name for p in plants]:
            raise ValueError(f"agent {path} was trained on the {trained_on} plant; add --plant {trained_on} (or both)")
        check_agent_plant(next(p for p in plants if p.name == trained_on), str(path),
                          agent_metadata(path).get("env_kwargs") or {})
    if args.seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {args.seeds}")
    if agents:  # an SB3 zip only with --trust-agent, converted here once: the workers never unpickle
        from controllers.agents import code_free_agent

        storage.writable_folder(args.out)
        agents = {code_free_agent(p, args.out / "converted-agents", trust=args.trust_agent): pl
                  for p, pl in agents.items()}
    # names checked before any episode runs: a typo must not cost a progress bar and a built environment
    from mrd_env.dampers import damper_class

    damper_class(args.damper)
    check_laws("--controllers", args.controllers, plants, damper=args.damper)
    storage.writable_folder(args.out)
    executor = sweep.options(args)
    for plant in plants:
        laws = args.controllers
        if laws is None:  # the default set: rows the damper cannot serve are left out with a note
            laws, skipped = applicable_laws(plant, plant.benchmark_laws, damper=args.damper)
            for law, why in skipped.items():
                print(f"note: {law} left out of the {plant.title} benchmark: {why}", file=sys.stderr)
        scen = held_out_scenarios(plant, seeds=args.seeds, quick=args.quick)
        eps = run_benchmark(plant, laws, scen, damper=args.damper, out=args.out,
                            progress=not args.no_progress,
                            agents=[p for p, pl in agents.items() if pl == plant.name], **executor)
        name = plant.name
        settings = markdown_table(scenario_rows(scen), title=f"{name}: scenario settings")
        storage.write_text(args.out / f"{name}_scenarios.md", settings)
        print(settings)
        print((args.out / f"{name}_benchmark_worst.md").read_text())
        by_controller: dict[str, list[Episode]] = {}
        for e in eps:
            by_controller.setdefault(e.controller, []).append(e)
        text = yardstick.report(plant, by_controller, scen, args.out, args.yardstick, damper=args.damper,
                                progress=not args.no_progress, **executor)
        if text:
            print(text)
        print(f"wrote {args.out}/{name}_benchmark.md/.csv, {name}_scenarios.md and figures ({len(eps)} episodes)")
    return 0
