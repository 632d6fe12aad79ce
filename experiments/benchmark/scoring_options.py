"""The options of the commands that score controllers on suites (``mrd-env score``, ``mrd-env benchmark``):
``--controller``, ``--episodes``, ``--trust-agent``, ``--out``, and their checks."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from mrd_env import storage


def whole(option: str, low: int):
    """argparse's ``type`` of a whole-number option >= ``low``: its error names the option's range (``int()`` takes
    '²'-free Unicode digits such as '٣' and 5 000-digit numbers; the option takes ASCII digits, at most 18)."""
    def parse(text: str) -> int:
        from .scoring import bounded

        digits = text.strip()
        if not (digits.isascii() and digits.isdigit() and len(digits) <= 18) or int(digits) < low:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {low}, got {bounded(text)}")
        return int(digits)

    parse.__name__ = option.lstrip("-")
    return parse


def check_out(path: Path, what: str) -> None:
    """A one-line ``ValueError`` where ``--out``, or a folder above it, is a file (``--out results/score.json``: the
    option takes a folder, not a result file); ``what``: what the folder receives, for that message."""
    from .scoring import bounded

    for p in (path, *path.parents):
        if p.exists() or p.is_symlink():
            if not p.is_dir():
                where = "" if p == path else f" ({p} is a file)"
                raise ValueError(f"--out {bounded(str(path))} is not a folder{where}: --out takes the folder into "
                                 f"which {what}")
            break


def out_folder(path: Path, what: str) -> Path:
    """``--out`` checked (:func:`check_out`), made and probed (:func:`mrd_env.storage.writable_folder`)."""
    check_out(path, what)
    return storage.writable_folder(path)


def add_controller_arguments(p: argparse.ArgumentParser, *, required: bool) -> None:
    """``--controller`` (repeatable), ``--episodes K`` and ``--trust-agent``."""
    from controllers import available_controllers

    from .scoring import shipped_agent_names

    p.add_argument("--controller", action="append", required=required, metavar="CONTROLLER",
                   help="a registered law (" + ", ".join(available_controllers()) + "), a shipped agent ("
                        + ", ".join(shipped_agent_names()) + "), an agent folder (a "
                        "plain SB3 model.zip with --trust-agent), or package.module:attribute (a class or factory "
                        "taking the environment, or an object with predict; IMPORTING IT RUNS ITS CODE: name only "
                        "code you mean to run); repeat for several")
    p.add_argument("--episodes", type=whole("--episodes", 1), default=None, metavar="K",
                   help="only the first K episodes of each scenario (a smoke run: the result is marked partial)")
    p.add_argument("--trust-agent", action="store_true",
                   help="also load agents that only have SB3's model.zip, and a plain SB3 model.zip (scored in the "
                        "suite's environment, its spaces checked against it) — pickles: they can run any code; only "
                        "from a source you trust; converted once into <out>/converted-agents/")


def importable(controllers) -> None:
    """Where a controller is ``module:attribute``: the current folder on ``sys.path`` (last: it shadows nothing), so
    that a module beside the user is found as with ``python -m``."""
    from controllers.protocol import is_import_spec

    if any(is_import_spec(c) for c in controllers or ()) and not {"", os.getcwd()} & set(sys.path):
        sys.path.append(os.getcwd())
