"""What every lab shares: where its figures go, how they are saved, and the instructor's checks.

A lab runs as a Jupyter notebook (through jupytext) and as a plain script (``python experiments/labs/lab1_rig.py``).
Figures go to ``$MRD_LAB_OUT/<lab>/`` (default: ``results/labs/<lab>/`` of the working directory, never the
installed package) and, in a notebook, are
shown below the cell; :meth:`Lab.finish` prints the checks and fails — a non-zero exit code in a script, an
``AssertionError`` in a notebook — if any of them failed.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

OUT_ENV = "MRD_LAB_OUT"
DEFAULT_OUT = Path("results") / "labs"  # relative to where the lab runs (a repository's results/ is not in git)
FULL_ENV = "MRD_LAB_FULL"  # "1": the long versions of the runs a lab shortens for CI


def full_length() -> bool:
    """True when ``$MRD_LAB_FULL`` is "1": labs then run their long versions (longer fits, longer training)."""
    return os.environ.get(FULL_ENV, "") == "1"


def in_notebook() -> bool:
    """True inside IPython/Jupyter (a lab run as a notebook), False in a plain script."""
    ipython = sys.modules.get("IPython")
    return ipython is not None and getattr(ipython, "get_ipython", lambda: None)() is not None


class Lab:
    """One lab's output folder, its figures and its instructor's checks."""

    def __init__(self, name: str):
        self.name = name
        self.out = Path(os.environ.get(OUT_ENV) or DEFAULT_OUT) / name
        self.out.mkdir(parents=True, exist_ok=True)
        self.figures: list[Path] = []
        self.checks: list[tuple[str, bool, str]] = []
        self._t0 = time.perf_counter()

    def save(self, fig, filename: str, dpi: int = 90) -> None:
        """Write a matplotlib Figure as ``<out>/<filename>`` (PNG; shown below the cell in a notebook)."""
        from mrd_env.report import save_figure

        path = save_figure(fig, self.out / filename, dpi=dpi)
        self.figures.append(path)
        if in_notebook():
            from IPython.display import Image, display

            display(Image(filename=str(path)))

    def add(self, path) -> None:
        """Count a figure another function wrote (e.g. a learning curve) among the lab's figures."""
        path = Path(path)
        if not path.exists():
            raise ValueError(f"figure {path} does not exist")
        self.figures.append(path)

    def check(self, what: str, passed, detail: str = "") -> bool:
        """Record one instructor's check: ``what`` is the physics expected, ``detail`` the numbers seen."""
        ok = bool(passed)
        self.checks.append((what, ok, detail))
        print(f"[{'PASS' if ok else 'FAIL'}] {what}" + (f" — {detail}" if detail else ""))
        return ok

    def user_file(self, path: str, setting: str) -> str:
        """``path``, a file the student named (in ``setting``), checked before the lab uses it: a missing or
        unreadable file ends a script with one line on stderr and exit code 2, and raises in a notebook."""
        if path and not (os.path.isfile(path) and os.access(path, os.R_OK)):
            msg = f"{self.name}: {setting}={path}: no such readable file"
            if in_notebook():
                raise FileNotFoundError(msg)
            print(msg, file=sys.stderr)
            sys.exit(2)
        return path

    def finish(self) -> None:
        """Summarise; fail if any check failed (exit code 1 in a script, AssertionError in a notebook)."""
        failed = [c for c in self.checks if not c[1]]
        print(f"{self.name}: {len(self.checks) - len(failed)}/{len(self.checks)} checks passed, "
              f"{len(self.figures)} figures in {self.out}, {time.perf_counter() - self._t0:.1f} s")
        if failed:
            msg = f"{self.name}: {len(failed)} instructor check(s) failed: " + "; ".join(c[0] for c in failed)
            if in_notebook():
                raise AssertionError(msg)
            sys.exit(msg)
