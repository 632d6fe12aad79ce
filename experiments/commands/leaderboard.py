"""``mrd-env leaderboard``: result files of ``mrd-env score`` merged into one leaderboard per suite (controllers ×
scenarios: the share of the achievable gain, mean and 95 % interval over the episodes, best first) and one figure.

The files are grouped by suite (its id); files of one id with different digests (other references) are refused,
never merged. Every share is recomputed from its episode's return and the suite's stored references — a shipped
suite's, or a suite file given with ``--suite`` (a result of a suite that is neither is refused) — and a file whose
share differs (edited by hand), whose episodes are not the suite's, given twice, or holding the same result as
another (the same controller description and the same returns) is refused. Complete results are ranked; a partial
one (``score --episodes``) is shown apart, marked "partial: n of N episodes", never ranked. The files are read as
data: nothing they name is imported or run.

Writes, per suite, ``<out>/<suite id>/leaderboard.md``/``.csv`` (the table), ``leaderboard_rows.md``/``.csv`` (the
numbers) and ``leaderboard.png`` — and with ``--html`` the page ``leaderboard.html`` (:mod:`experiments.benchmark.page`: one
self-contained file, the sortable table, the paired verdicts, a chart per scenario, each controller's episodes) —
as one set: each suite's folder is replaced as a whole (a reader or a kill finds the
previous set or the new one); the folders of suites not given are left as they are. ``--out`` must be new, empty or
hold only such folders (or a leaderboard of the earlier layout, whose five files the suites' folders replace); a
folder that holds other files is refused. Every file is read and checked, and the folders checked, before anything
is written; the bounds on result files are :mod:`experiments.benchmark.ranking`'s.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", nargs="+", type=Path, metavar="RESULT.json",
                   help="result files written by mrd-env score (of one or more suites: one leaderboard per suite)")
    p.add_argument("--suite", action="append", default=[], metavar="SUITE",
                   help="the suite file (.json) of a suite of your own that results were scored on, to check their "
                        "shares against its references (shipped suites need none; repeat for several)")
    p.add_argument("--out", type=Path, default=Path("results/leaderboard"),
                   help="the folder of the leaderboards, one folder per suite (<out>/<suite id>/), each replaced as a "
                        "whole: new, empty or holding only leaderboard folders (default: %(default)s)")
    p.add_argument("--html", action="store_true",
                   help="also write each suite's page, <out>/<suite id>/leaderboard.html: one self-contained file "
                        "(no server, no network) with the sortable table, the paired verdicts, a chart per scenario "
                        "and each controller's episodes")


def run(args: argparse.Namespace) -> int:
    from experiments.benchmark.ranking import check_out_folder, leaderboards, write_leaderboards

    check_out_folder(args.out)  # a folder that would lose the user's files: refused before the files are read
    suites = [Path(s) if s.endswith(".json") or Path(s).is_file() else s for s in args.suite]
    boards = leaderboards(args.results, suites=suites)  # every file read and checked before anything is written
    written = write_leaderboards(boards, args.out, html=args.html)
    for sid, board in boards.items():
        print(board.markdown())
        files = written[sid]
        print(f"wrote {', '.join(str(f) for f in files.values())}")
    return 0
