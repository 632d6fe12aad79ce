"""``mrd-env score``: controllers scored on a frozen benchmark suite (:mod:`mrd_env.suites`) against its stored
references — the share of the achievable gain (R − R_p) / (R_c − R_p) and the suite's criteria, per scenario, with
95 % intervals over the episodes (:mod:`experiments.benchmark.scoring`; nothing is solved).

``--controller`` (repeatable) takes a registered law's name, a shipped agent's name (``quarter_car_cmaes``), an agent
folder, or ``package.module:attribute``: a class
or factory taking the environment, or an object with ``predict`` (the protocol: :mod:`controllers.protocol`).
``--law-options JSON`` gives a single registered law its options (an MPC's settings: the plants' MPC rows, e.g.
``--controller mpc --law-options '{"weights": "reward", "f_max": 1e5, "force_ref": 200, "horizon": 10}' --name
"mpc+preview (reward)"`` on ``car-preview-v1``); ``--name`` names a single controller's row and result file.
**Naming a module imports it: its code runs**, as with ``python -m`` — only name code you mean to run. Agents load
without running code from their folders (one that only has SB3's pickled ``model.zip`` needs ``--trust-agent``).

Writes, per controller, ``<out>/<suite id>__<controller>.json`` (the result file: suite name, version and digest, the
controller's description, every episode's figures) and ``.md``/``.csv`` (its table); ``mrd-env leaderboard`` merges
result files of the same suite.

A suite fixes its plant: the plant options (``--storeys``, ``--damper-storeys``, ``--damper``) may only name the
suite's own plant; options that would change it are refused with the suites whose plant they describe.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..common import sweep
from ..common.plants import add_plant_options, check_suite_plant
from ..benchmark.scoring_options import add_controller_arguments, importable, out_folder


def add_arguments(p: argparse.ArgumentParser) -> None:
    from experiments.benchmark.scoring import POOL_MIN_SECONDS

    p.add_argument("--suite", required=True,
                   help="a shipped suite (name-vN, e.g. car-comfort-v1; a name without version: its latest) or a "
                        "suite file (.json)")
    add_controller_arguments(p, required=True)
    p.add_argument("--law-options", default=None, metavar="JSON",
                   help="the options of the registered law given as the one --controller, as a JSON object (e.g. an "
                        "MPC's: '{\"weights\": \"reward\", \"horizon\": 10}'); recorded in the result file")
    p.add_argument("--name", default=None,
                   help="the row's and result file's name of the one --controller (default: the law's name, with its "
                        "options; agent <name>; the import spec)")
    p.add_argument("--against", default=None, metavar="RESULT_OR_CONTROLLER",
                   help="compare each controller with this one on the same episodes (paired: the difference of their "
                        "pooled shares with its 95 %% interval, episodes won, ahead/behind/tie): a result file of the "
                        "same suite (.json), or a controller scored in this run (as --controller)")
    p.add_argument("--out", type=Path, default=Path("results/score"), metavar="FOLDER",
                   help="the folder of the result files (default results/score)")
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)
    for action in p._actions:  # score's auto is its own (experiments.benchmark.scoring.score)
        if action.dest == "backend":
            action.help = ("serial, a local process pool, or Ray (default auto: in this process, unless the first "
                           "scenario's time says the others are worth a pool's start-up: over "
                           f"{POOL_MIN_SECONDS:g} s of work)")
    add_plant_options(p)  # a suite fixes its plant: they may only name it (check_suite_plant)


def run(args: argparse.Namespace) -> int:
    from experiments.benchmark.scoring import (bounded, check_controller, check_references, controller_spec,
                                               one_torch_thread, resolve_suite, result_filename, score)

    if args.episodes is not None and args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    options = None
    if args.law_options is not None:
        try:
            options = json.loads(args.law_options)
        except (json.JSONDecodeError, RecursionError) as exc:
            why = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
            raise ValueError(f"--law-options must be a JSON object, got {bounded(args.law_options)} ({why})") \
                from None
        if not isinstance(options, dict):
            raise ValueError(f"--law-options must be a JSON object ({{...}}), got {bounded(args.law_options)}")
    for flag, given in (("--law-options", args.law_options), ("--name", args.name)):
        if given is not None and len(args.controller) != 1:
            raise ValueError(f"{flag} applies to one --controller; {len(args.controller)} were given (score them one "
                             "command each)")
    executor = sweep.options(args)
    importable(args.controller)
    suite = resolve_suite(args.suite)
    check_suite_plant(suite, args)
    check_references(suite)
    # every controller checked before any episode runs (a typo must not cost the first controller's episodes), and
    # before --out is made: a refused command writes nothing
    specs = []
    for c in args.controller:
        spec = controller_spec(c, name=args.name, options=options, trust_agent=args.trust_agent,
                               converted=args.out / "converted-agents", suite=suite)
        check_controller(spec, suite)
        if any(s.name == spec.name for s in specs):
            raise ValueError(f"--controller {bounded(c)}: {bounded(spec.name)} is given twice")
        specs.append(spec)
    reference = _against(args, suite, specs)
    out_folder(args.out, "each controller's <suite>__<controller>.json/.md/.csv are written")
    for spec in specs:
        one_torch_thread(spec)  # this process is the command's own (an SB3 policy: 10× faster on 2 cores)
    files = [args.out / result_filename(suite.id, s.name) for s in specs]
    clash = {f for f in files if files.count(f) > 1}
    if clash:
        raise ValueError(f"--controller: two controllers would write {sorted(map(str, clash))[0]}; rename one")
    results = {}
    for spec, path in zip(specs, files):
        result = score(suite, spec, episodes=args.episodes, progress=not args.no_progress,
                       command=["mrd-env", *getattr(args, "_argv", [])], **executor)
        result.write(path)
        md, csv_path = result.write_tables(path.with_suffix(""))
        results[spec.name] = result
        print(result.markdown())
        print(f"wrote {path}, {md}, {csv_path}")
    if isinstance(reference, Path):
        reference = _read_reference(reference, suite)
    elif reference is not None:  # a controller: this run's result, or scored now on the same episodes
        reference = results.get(reference.name) or score(suite, reference, episodes=args.episodes,
                                                         progress=not args.no_progress, **executor)
    for result in results.values():
        if reference is not None and result is not reference:
            print(result.paired_markdown(reference, suite))
    if len(files) > 1:
        print(f"merge them: mrd-env leaderboard {' '.join(map(str, files))} --out {args.out / 'leaderboard'}")
    return 0


def _against(args, suite, specs):
    """``--against``: None; the result file's path (checked when read); or the controller's spec, checked like a
    ``--controller``, before anything is scored or written."""
    from experiments.benchmark.scoring import check_controller, controller_spec

    if args.against is None:
        return None
    if args.against.endswith(".json"):
        path = Path(args.against)
        _read_reference(path, suite)  # refused now, not after the scoring
        return path
    spec = controller_spec(args.against, trust_agent=args.trust_agent, converted=args.out / "converted-agents",
                           suite=suite)
    check_controller(spec, suite)
    return next((s for s in specs if s.name == spec.name), spec)


def _read_reference(path: Path, suite):
    """The result file ``path`` checked against ``suite`` (its digest, episodes and shares)."""
    from experiments.benchmark.ranking import check_against_suite, read_result

    result = read_result(path)
    check_against_suite(result, suite, path)
    return result
