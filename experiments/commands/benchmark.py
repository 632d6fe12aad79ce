"""``mrd-env benchmark``: the suites' benchmark — every controller that fits a suite scored on it
(:func:`experiments.benchmark.run.run_benchmark`): the plant's laws, its MPC rows, the shipped agents trained on the
suite's environment, and any ``--controller`` of yours (what ``mrd-env score`` takes), against each suite's stored
references (nothing is solved). A controller that does not fit a suite is listed with the reason.

The suites: every shipped suite (of ``--plant``, and of the plant the plant options describe: ``--storeys 6`` keeps
the suites of the six-storey building), or those named with ``--suite`` (a shipped suite's id, or your own suite
file, e.g. one ``mrd-env suite build`` wrote).

Writes, under ``--out``: ``results/<suite id>__<controller>.json`` (one result file per controller and suite, each
as soon as it is scored), ``leaderboards/<suite id>/`` (per suite: ``leaderboard.md``/``.csv``, the ranked table,
``leaderboard_rows.md``/``.csv``, its numbers, ``leaderboard.png``, the figure, and ``leaderboard.html``, the page a
browser opens from disk) and ``benchmark.md`` (the
summary printed at the end: per suite, the best controller of each kind; ``benchmark.json``: what was scored and
what did not fit, with the reasons and wall times, as data).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..common import sweep
from ..common.plants import add_plant_options, plant_choices, plant_name
from ..benchmark.scoring_options import add_controller_arguments, check_out, importable


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", action="append", default=None, metavar="ID|FILE",
                   help="a shipped suite (name-vN, e.g. car-comfort-v1) or a suite file (.json); repeat for several "
                        "(default: every shipped suite of --plant)")
    p.add_argument("--plant", type=plant_name, choices=plant_choices(both=True), default="all",
                   help="the suites of a plant, of both published plants (building and quarter car) or of all "
                        "(default)")
    add_controller_arguments(p, required=False)
    p.add_argument("--no-shipped", action="store_true",
                   help="score only the --controller ones, not the laws, MPC rows and agents the project ships")
    p.add_argument("--only", nargs="+", default=None, metavar="NAME",
                   help="of the shipped controllers, only these (e.g. passive_off skyhook_continuous 'mpc (reward)' "
                        "quarter_car_cmaes)")
    p.add_argument("--out", type=Path, default=Path("results/benchmark"), metavar="FOLDER",
                   help="the folder of the result files, leaderboards and summary (default results/benchmark)")
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)
    add_plant_options(p)  # they choose the suites whose plant they describe (a suite fixes its plant)


def chosen_suites(args: argparse.Namespace) -> list:
    """The suites of ``--suite`` (default every shipped one), of ``--plant``, and whose plant the plant options
    describe; ``ValueError`` where none is left."""
    from experiments.benchmark.run import choose_suites
    from experiments.common.plants import chosen_plants, check_suite_plant, plant_option_values

    picked = choose_suites(args.suite, plants=None if args.plant == "all" else
                           {p.name for p in chosen_plants(args.plant)})
    if not plant_option_values(args):
        return picked
    kept, why = [], None
    for s in picked:
        try:
            check_suite_plant(s, args)
        except ValueError as exc:
            why = why or exc
            continue
        kept.append(s)
    if not kept:
        raise why
    return kept


def run(args: argparse.Namespace) -> int:
    from experiments.benchmark.run import LEADERBOARDS, RESULTS, SUMMARY, run_benchmark

    if args.no_shipped and not args.controller:
        raise ValueError("--no-shipped leaves nothing to score: add --controller")
    if args.no_shipped and args.only:
        raise ValueError("--only chooses among the shipped controllers, which --no-shipped leaves out")
    executor = sweep.options(args)
    importable(args.controller)
    suites = chosen_suites(args)
    check_out(args.out, f"the benchmark writes {RESULTS}/, {LEADERBOARDS}/ and {SUMMARY}")
    bench = run_benchmark(suites, args.controller or (), shipped=not args.no_shipped, only=args.only, out=args.out,
                          episodes=args.episodes, trust_agent=args.trust_agent, progress=not args.no_progress,
                          own_process=True, **executor)
    print(bench.markdown())
    n, boards = sum(len(e.scored) for e in bench.suites), sum(e.leaderboard is not None for e in bench.suites)
    print(f"wrote {n} result file(s) in {args.out / RESULTS}, {boards} leaderboard(s) (tables, figure and page) in "
          f"{args.out / LEADERBOARDS}, and {args.out / SUMMARY} (scored in {bench.wall_s:.0f} s)")
    return 0
