"""``mrd-env``: one entry point, one sub-command per job.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args) -> int``. Only the
module of the command being run is imported (``mrd-env --help`` imports none of them).

Errors: anything the user can get wrong — a bad option, a missing or unreadable file, a bad record, a
simulation that diverges on the user's parameters, a missing optional dependency — ends the command with one
line on stderr and exit code 2, never a traceback, also where it happens in a sweep's worker. An unexpected
exception (a bug) prints one line and exits with 1; ``--traceback`` shows the whole traceback instead.

Stopping: SIGTERM (what SLURM, ``docker stop`` and ``timeout`` send) is handled as Ctrl-C: the long commands save
what is done (``train``: the agent so far, loadable; ``tune``: the finished trials, in the study's journal;
``suite build``: every solved episode, kept for the next run; ``benchmark``: every finished result file), then the command
exits with 143 (130 for Ctrl-C). On a process pool the workers are stopped too: each task is interrupted where it
is (and saves as above), and a worker still running after :data:`mrd_env.executor.STOP_GRACE` s is killed.

An error line is cut at :data:`MAX_ERROR_LINE` characters (a message quoting a huge value says how many were cut).
"""
from __future__ import annotations

import argparse
import importlib
import re
import signal
import sys

COMMANDS = {
    "rig": ("experiments.commands.rig", "virtual damper test rig: loops (PNG), records (CSV), peak/energy table"),
    "benchmark": ("experiments.commands.benchmark",
                  "the benchmark: every controller that fits (laws, MPC, shipped agents, yours) scored on the "
                  "suites, one result file each, one leaderboard (tables, figure, page) per suite"),
    "suite": ("experiments.commands.suite",
              "your own benchmark suite: build one from a small JSON definition (references, digest, procedure, "
              "cost) on a process pool or Ray, resumable; show one"),
    "train": ("experiments.commands.train",
              "train agents (Stable-Baselines3, RL Zoo conventions): curves, best agent, checkpoints"),
    "warmup": ("experiments.commands.warmup", "compile every damper model's kernels into the disk cache now (once)"),
    "tune": ("experiments.commands.tune", "hyperparameter search for train (Optuna; pool or Ray workers)"),
    "identify": ("experiments.commands.identify",
                 "fit a damper model to a measured record: errors table, figure, JSON preset"),
    "compare-models": ("experiments.commands.compare_models",
                       "fit several damper models to a record and compare them on the held-back part"),
    "inverse": ("experiments.commands.inverse",
                "inverse models: force-tracking tables and figures (achievable forces, a measured record); train one"),
    "score": ("experiments.commands.score",
              "score controllers (laws, agents, your module:attribute) on a benchmark suite: shares of the achievable "
              "gain and criteria with 95-percent intervals, one result file each; --against: paired verdicts"),
    "leaderboard": ("experiments.commands.leaderboard",
                    "merge result files of mrd-env score on one suite version into one ranked table with paired "
                    "verdicts and one figure (--html: a page)"),
    "dataset": ("experiments.commands.dataset", "a controller's suite episodes as Minari datasets (offline RL)"),
}


#: Commands folded into ``benchmark`` and ``suite`` (issue 50), each with what replaces it. They answer with one line
#: and exit code 2 instead of running: the project had made no release, and an alias would have kept alive a second
#: benchmark on other episodes with other references, the confusion their removal ends.
REMOVED = {
    "evaluate": "agents and laws side by side are now scored on the suites: mrd-env benchmark --controller AGENT "
                "(or mrd-env score --suite ID --controller AGENT)",
    "yardstick": "the clairvoyant optimum and the active bound are each suite's stored references: mrd-env benchmark "
                 "scores every controller against them; mrd-env suite build SPEC computes them for your own episodes",
}


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is, so that every ``except KeyboardInterrupt`` that saves runs."""


def _on_sigterm(signum, frame):
    raise Terminated()


class UserError(Exception):
    """A problem with what the user asked for, reported as one line (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse with its errors on one line (argparse prints the usage line too, and exits itself)."""

    def error(self, message: str):
        raise UserError(message)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; only ``command``'s module is imported to add its options (none for ``mrd-env --help``)."""
    parser = _Parser(prog="mrd-env", description="MR-damper environments, models and experiments")
    parser.add_argument("--traceback", action="store_true", help="show the full traceback of an internal error")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module)
        if name == command:
            importlib.import_module(module).add_arguments(p)
    return parser


def _command_of(argv: list[str]) -> str | None:
    return next((a for a in argv if not a.startswith("-")), None)


def _user_errors() -> tuple[type[BaseException], ...]:
    from mrd_env.errors import SimulationDivergedError

    # OSError: missing, unreadable or unwritable files; ImportError: an optional dependency not installed
    return ValueError, OSError, SimulationDivergedError, ImportError


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_of(argv)
    prog = f"mrd-env {command}" if command in COMMANDS else "mrd-env"
    if command in REMOVED:
        return _fail(f"mrd-env {command}", f"mrd-env {command} was folded into the suites' benchmark: "
                                          f"{REMOVED[command]}", 2)
    previous = _handle_sigterm()
    try:
        args = build_parser(command if command in COMMANDS else None).parse_args(argv)
        args._argv = argv  # the command line, for the records that say how to reproduce a run
        return int(importlib.import_module(args._module).run(args) or 0)
    except SystemExit as exc:  # --help, or a sub-command that exits by itself
        code = exc.code
        if code is None or isinstance(code, int):
            return int(code or 0)
        return _fail(prog, str(code), 2)  # a message (sys.exit("...")), or whatever else it was given
    except KeyboardInterrupt as exc:
        print(f"{prog}: {'terminated' if isinstance(exc, Terminated) else 'interrupted'}", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    except UserError as exc:
        return _fail(prog, f"{exc} (see {prog} --help)", 2)
    except _user_errors() as exc:
        return _fail(prog, _message(exc), 2)
    except Exception as exc:  # a bug: one line unless asked for the traceback
        from mrd_env.executor import TaskFailed

        if isinstance(exc, TaskFailed) and isinstance(exc.error, _user_errors()):  # the user's problem, in a worker
            return _fail(prog, f"{exc.task.label or exc.task.describe()}: {_message(exc.error)}", 2)
        if "--traceback" in argv:
            raise
        return _fail(prog, f"internal error: {type(exc).__name__}: {one_line(exc, MAX_ERROR_LINE // 2)} (rerun with "
                           "--traceback for details)", 1)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _handle_sigterm():
    """Route SIGTERM to :class:`Terminated` for this command (main thread only); the previous handler, to restore."""
    try:
        return signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread (main() called from a thread): leave signals alone
        return None


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.filename is not None:
        return f"{exc.filename}: {exc.strerror or exc}"
    if isinstance(exc, ModuleNotFoundError) and exc.name:
        extras = extras_of(exc.name)
        if extras:
            return (f"{exc} (it comes with the extra {' or '.join(f'[{e}]' for e in extras)}: "
                    f"pip install 'mrd-env[{extras[0]}]')")
    return str(exc)


#: Import names whose distribution is named otherwise (the rest: the import name with '_' as '-').
_DISTRIBUTIONS = {"yaml": "pyyaml", "sklearn": "scikit-learn"}


def extras_of(module: str) -> list[str]:
    """The extras of mrd-env (pyproject.toml's optional dependencies, read from the installed package's metadata:
    one home for the fact) that install the top-level module ``module``; the narrowest first, ``test`` last."""
    import importlib.metadata as md

    top = module.split(".")[0]
    want = re.sub(r"[-_.]+", "-", _DISTRIBUTIONS.get(top, top)).lower()
    try:
        requires = md.requires("mrd-env") or []
    except md.PackageNotFoundError:
        return []
    found = []
    for req in requires:
        m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)[^;]*;.*extra\s*==\s*[\"']([^\"']+)[\"']", req)
        if m and re.sub(r"[-_.]+", "-", m.group(1)).lower() == want and m.group(2) not in found:
            found.append(m.group(2))
    return sorted(found, key=lambda e: (e in ("test", "docs"), e))


#: The longest error line printed (characters): a message quoting a huge value (an option, a file's field) is cut.
MAX_ERROR_LINE = 2000


def one_line(message, limit: int = MAX_ERROR_LINE) -> str:
    """``message`` on one line (runs of white space as one space), cut to ``limit`` characters with a note of how
    many were cut: one error line must stay readable whatever value it quotes."""
    text = re.sub(r"\s+", " ", str(message)).strip()
    if len(text) <= limit:
        return text
    cut = len(text) - limit
    return f"{text[:limit]}… ({cut} characters cut)"


def _fail(prog: str, message: str, code: int) -> int:
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
