"""How fast, how much memory, how accurate: scripts, not tests, run as
``python -m experiments.measurements.<speed|memory|accuracy>.<name>``. Speed figures are ratios to a reference
measured in the same run, medians of repeats, with the machine's load printed beside them."""
from __future__ import annotations

import os
import sys
from typing import Callable


def load_average() -> list[float]:
    """The machine's 1, 5 and 15 min load averages, rounded: printed beside every speed figure."""
    return [round(x, 2) for x in os.getloadavg()]


def refusing(name: str, run: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    """``run(argv)``; a refused option (``ValueError``, raised before anything is measured) is one line on stderr
    naming the script ``name``, exit 2."""
    try:
        return run(argv)
    except ValueError as e:
        print(f"{name}: {e}", file=sys.stderr)
        return 2
