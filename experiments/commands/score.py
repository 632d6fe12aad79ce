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
import os
import sys
from pathlib import Path

from mrd_env import storage

from ..common import sweep
from ..common.plants import add_plant_options, check_suite_plant


def _whole(option: str, low: int):
    """argparse's ``type`` of a whole-number option >= ``low``: its error names the option's range (``int()`` takes
    '²'-free Unicode digits such as '٣' and 5 000-digit numbers; the option takes ASCII digits, at most 18)."""
    def parse(text: str) -> int:
        digits = text.strip()
        if not (digits.isascii() and digits.isdigit() and len(digits) <= 18) or int(digits) < low:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {low}, got {_bounded(text)}")
        return int(digits)

    parse.__name__ = option.lstrip("-")
    return parse


def _bounded(value) -> str:
    """``repr(value)`` cut to about 120 characters (an error message's quote of what the user typed)."""
    import reprlib

    r = reprlib.Repr()
    r.maxstring = r.maxother = 120
    return r.repr(value)


def out_folder(path: Path) -> Path:
    """``--out`` made and probed (:func:`mrd_env.storage.writable_folder`), after a one-line ``ValueError`` where it,
    or a folder above it, is a file (``--out results/score.json``: the option takes a folder, not a result file)."""
    for p in (path, *path.parents):
        if p.exists() or p.is_symlink():
            if not p.is_dir():
                where = "" if p == path else f" ({p} is a file)"
                raise ValueError(f"--out {_bounded(str(path))} is not a folder{where}: --out takes the folder into which "
                                 "each controller's <suite>__<controller>.json/.md/.csv are written")
            break
    return storage.writable_folder(path)


def add_arguments(p: argparse.ArgumentParser) -> None:
    from controllers import available_controllers

    from experiments.benchmark.scoring import POOL_MIN_SECONDS, shipped_agent_names

    p.add_argument("--suite", required=True,
                   help="a shipped suite (name-vN, e.g. car-comfort-v1; a name without version: its latest) or a "
                        "suite file (.json)")
    p.add_argument("--controller", action="append", required=True, metavar="CONTROLLER",
                   help="a registered law (" + ", ".join(available_controllers()) + "), a shipped agent ("
                        + ", ".join(shipped_agent_names()) + "), an agent folder (a "
                        "plain SB3 model.zip with --trust-agent), or package.module:attribute (a class or factory "
                        "taking the environment, or an object with predict; IMPORTING IT RUNS ITS CODE: name only "
                        "code you mean to run); repeat for several")
    p.add_argument("--law-options", default=None, metavar="JSON",
                   help="the options of the registered law given as the one --controller, as a JSON object (e.g. an "
                        "MPC's: '{\"weights\": \"reward\", \"horizon\": 10}'); recorded in the result file")
    p.add_argument("--name", default=None,
                   help="the row's and result file's name of the one --controller (default: the law's name, with its "
                        "options; agent <name>; the import spec)")
    p.add_argument("--out", type=Path, default=Path("results/score"), metavar="FOLDER",
                   help="the folder of the result files (default results/score)")
    p.add_argument("--episodes", type=_whole("--episodes", 1), default=None, metavar="K",
                   help="only the first K episodes of each scenario (a smoke run: the result is marked partial)")
    p.add_argument("--trust-agent", action="store_true",
                   help="also load agents that only have SB3's model.zip, and a plain SB3 model.zip (scored in the "
                        "suite's environment, its spaces checked against it) — pickles: they can run any code; only "
                        "from a source you trust; converted once into <out>/converted-agents/")
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)
    for action in p._actions:  # score's auto is its own (experiments.benchmark.scoring.score)
        if action.dest == "backend":
            action.help = ("serial, a local process pool, or Ray (default auto: in this process, unless the first "
                           "scenario's time says the others are worth a pool's start-up: over "
                           f"{POOL_MIN_SECONDS:g} s of work)")
    add_plant_options(p)  # a suite fixes its plant: they may only name it (check_suite_plant)


def run(args: argparse.Namespace) -> int:
    from controllers.protocol import is_import_spec

    from experiments.benchmark.scoring import (check_controller, check_references, controller_spec, one_torch_thread,
                                  resolve_suite, result_filename, score)

    if args.episodes is not None and args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    options = None
    if args.law_options is not None:
        try:
            options = json.loads(args.law_options)
        except (json.JSONDecodeError, RecursionError) as exc:
            why = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
            raise ValueError(f"--law-options must be a JSON object, got {_bounded(args.law_options)} ({why})") \
                from None
        if not isinstance(options, dict):
            raise ValueError(f"--law-options must be a JSON object ({{...}}), got {_bounded(args.law_options)}")
    for flag, given in (("--law-options", args.law_options), ("--name", args.name)):
        if given is not None and len(args.controller) != 1:
            raise ValueError(f"{flag} applies to one --controller; {len(args.controller)} were given (score them one "
                             "command each)")
    executor = sweep.options(args)
    if any(is_import_spec(c) for c in args.controller) and not {"", os.getcwd()} & set(sys.path):
        # module:attribute looked up in the installed packages, then the current folder (last: it shadows nothing)
        sys.path.append(os.getcwd())
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
            raise ValueError(f"--controller {_bounded(c)}: {_bounded(spec.name)} is given twice")
        specs.append(spec)
    out_folder(args.out)
    for spec in specs:
        one_torch_thread(spec)  # this process is the command's own (an SB3 policy: 10× faster on 2 cores)
    files = [args.out / result_filename(suite.id, s.name) for s in specs]
    clash = {f for f in files if files.count(f) > 1}
    if clash:
        raise ValueError(f"--controller: two controllers would write {sorted(map(str, clash))[0]}; rename one")
    for spec, path in zip(specs, files):
        result = score(suite, spec, episodes=args.episodes, progress=not args.no_progress,
                       command=["mrd-env", *getattr(args, "_argv", [])], **executor)
        result.write(path)
        md, csv_path = result.write_tables(path.with_suffix(""))
        print(result.markdown())
        print(f"wrote {path}, {md}, {csv_path}")
    if len(files) > 1:
        print(f"merge them: mrd-env leaderboard {' '.join(map(str, files))} --out {args.out / 'leaderboard'}")
    return 0
