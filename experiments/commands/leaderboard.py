"""``mrd-env leaderboard``: result files of ``mrd-env score`` on one suite merged into one table (controllers ×
scenarios: the share of the achievable gain, mean and 95 % interval over the episodes, best first) and one figure.

Every file must be of the first file's suite, version and digest — results against other references or other
episodes are refused, never merged. The files are read as data: nothing they name is imported or run.
Writes ``<out>/leaderboard.md``/``.csv`` (the table), ``leaderboard_rows.md``/``.csv`` (the numbers) and
``leaderboard.png`` as one set: the ``--out`` folder is replaced as a whole (a reader or a kill finds the previous
set or the new one), so it must be new, empty or a previous leaderboard's; a folder that holds other files is
refused. Every file is read and checked, and the folder checked, before anything is written; the bounds on result
files are :mod:`experiments.common.leaderboard`'s.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", nargs="+", type=Path, metavar="RESULT.json",
                   help="result files written by mrd-env score (all of the same suite version)")
    p.add_argument("--out", type=Path, default=Path("results/leaderboard"),
                   help="the leaderboard's folder, replaced as a whole: new, empty or a previous leaderboard's "
                        "(default: %(default)s)")


def run(args: argparse.Namespace) -> int:
    from ..common.leaderboard import check_folder, leaderboard

    check_folder(args.out)  # a folder that would lose the user's files: refused before the files are read
    board = leaderboard(args.results)  # every file read and checked before anything is written
    files = board.write(args.out)
    print(board.markdown())
    print(f"wrote {files['markdown']}, {files['csv']}, {files['rows_csv']}, {files['figure']}")
    return 0
