"""``mrd-env dataset``: a controller's episodes on a benchmark suite recorded as Minari datasets (offline RL), one per
scenario, ``mrd-env/<suite id>/<scenario>/<controller>-v0`` in ``--out`` (:mod:`experiments.benchmark.dataset`).

``--controller`` takes what ``mrd-env score`` takes (a registered law with ``--law-options``, a shipped agent, an
agent folder, ``package.module:attribute``: **naming a module imports it, its code runs**), one of the suite's shipped
rows by its name (``"mpc+preview (reward)"``), or ``clairvoyant``: the clairvoyant command sequences, solved again at
the suite's control step (non-causal; seconds to minutes an episode: use ``--episodes``).

Load one with ``MINARI_DATASETS_PATH=<out> python -c "import minari; minari.load_dataset('<id>')"``.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..benchmark.scoring_options import add_controller_arguments, check_out, importable


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--suite", required=True,
                   help="a shipped suite (name-vN, e.g. car-preview-v1) or a suite file (.json)")
    add_controller_arguments(p, required=True)
    for action in p._actions:
        if action.dest == "controller":
            action.help = "clairvoyant (the non-causal command sequences), one of the suite's shipped rows by its " \
                          "name (\"mpc+preview (reward)\"), or " + action.help
    p.add_argument("--law-options", default=None, metavar="JSON",
                   help="the options of the registered law given as the one --controller, as a JSON object")
    p.add_argument("--name", default=None, help="the one --controller's name (the dataset id's last part)")
    p.add_argument("--scenario", action="append", default=None, metavar="NAME",
                   help="only this scenario of the suite (repeatable; default: every scenario)")
    p.add_argument("--out", type=Path, default=Path("results/datasets"), metavar="FOLDER",
                   help="Minari's datasets folder (MINARI_DATASETS_PATH to load them; default results/datasets)")
    p.add_argument("--overwrite", action="store_true", help="replace datasets that exist")
    p.add_argument("--no-progress", action="store_true")


def run(args: argparse.Namespace) -> int:
    try:
        import h5py  # noqa: F401  (Minari's HDF5 storage)
        import minari  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"mrd-env dataset needs minari and h5py ({exc}): pip install 'mrd-env[datasets]'") from None
    from experiments.benchmark.dataset import plan, record, resolve_controller
    from experiments.benchmark.scoring import bounded, resolve_suite

    options = None
    if args.law_options is not None:
        try:
            options = json.loads(args.law_options)
        except (json.JSONDecodeError, RecursionError):
            options = None
        if not isinstance(options, dict):
            raise ValueError(f"--law-options must be a JSON object ({{...}}), got {bounded(args.law_options)}")
    for flag, given in (("--law-options", args.law_options), ("--name", args.name)):
        if given is not None and len(args.controller) != 1:
            raise ValueError(f"{flag} applies to one --controller; {len(args.controller)} were given")
    check_out(args.out, "the datasets are written")
    importable(args.controller)
    suite = resolve_suite(args.suite)
    # every controller and dataset checked before any episode runs: a refused command writes nothing
    specs = [resolve_controller(c, suite, name=args.name, options=options, trust_agent=args.trust_agent,
                                converted=args.out / "converted-agents") for c in args.controller]
    for spec in specs:
        plan(suite, spec, root=args.out, episodes=args.episodes, scenarios=args.scenario, overwrite=args.overwrite)
    command = ["mrd-env", *getattr(args, "_argv", [])]
    for spec in specs:
        record(suite, spec, root=args.out, name=args.name, options=options, episodes=args.episodes,
               scenarios=args.scenario, overwrite=args.overwrite, trust_agent=args.trust_agent, command=command,
               progress=None if args.no_progress else lambda r: print(r.line(), flush=True))
    print(f"load them: MINARI_DATASETS_PATH={args.out} python -c \"import minari; "
          f"print(minari.list_local_datasets())\"")
    return 0
