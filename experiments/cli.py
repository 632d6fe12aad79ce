"""``mrd-env``: one entry point, one sub-command per job.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args) -> int``;
the modules are imported only when their command runs, so ``mrd-env --help`` stays fast.
"""
from __future__ import annotations

import argparse
import importlib
import sys

COMMANDS = {
    "rig": ("experiments.rig_report", "virtual damper test rig: loops (PNG), records (CSV), peak/energy table"),
    "benchmark": ("experiments.benchmark", "controller × scenario benchmark: Markdown/CSV tables and figures"),
    "train": ("experiments.train", "train a Stable-Baselines3 agent on an environment and save it"),
    "identify": ("experiments.identify_cmd",
                 "fit a damper model to a measured record: errors table, figure, JSON preset"),
    "compare-models": ("experiments.compare_models_cmd",
                       "fit several damper models to a record and compare them on the held-back part"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mrd-env", description="MR-damper environments, models and experiments")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module)
        importlib.import_module(module).add_arguments(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(importlib.import_module(args._module).run(args) or 0)
    except ValueError as exc:  # bad user input: a clear message, no traceback
        print(f"mrd-env {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
