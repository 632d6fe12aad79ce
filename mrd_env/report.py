"""What a person puts in a report: Markdown and CSV tables from the same rows, and PNG figures.

Figures are drawn on :class:`matplotlib.figure.Figure` objects with the Agg canvas, never through pyplot's
global state, so writing a report never changes the matplotlib backend of the user's process.
"""
from __future__ import annotations

import csv
from pathlib import Path


def write_table(rows: list[dict], path_stem: str | Path, *, title: str = "", floatfmt: str = ".4g") -> tuple[Path, Path]:
    """Write ``rows`` (dicts with the same keys) to ``<stem>.md`` and ``<stem>.csv``; return both paths."""
    stem = Path(path_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    if not rows:
        raise ValueError("write_table needs at least one row")
    keys = list(rows[0])
    csv_path = stem.with_suffix(".csv")
    with csv_path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, restval="")
        w.writeheader()
        w.writerows(rows)
    md_path = stem.with_suffix(".md")
    md_path.write_text(markdown_table(rows, title=title, floatfmt=floatfmt))
    return md_path, csv_path


def markdown_table(rows: list[dict], *, title: str = "", floatfmt: str = ".4g") -> str:
    keys = list(rows[0])

    def fmt(v):
        return format(v, floatfmt) if isinstance(v, float) else str(v)

    lines = [f"### {title}", ""] if title else []
    lines.append("| " + " | ".join(keys) + " |")
    lines.append("|" + "|".join("---" for _ in keys) + "|")
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def figure(nrows: int = 1, ncols: int = 1, *, figsize=(8.0, 4.5), **subplot_kw):
    """A new (Figure, axes) pair detached from pyplot (``constrained_layout``; ``subplot_kw`` as in
    ``Figure.subplots``, e.g. ``sharex=True``)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, constrained_layout=True)
    return fig, fig.subplots(nrows, ncols, **subplot_kw)


def save_figure(fig, path: str | Path, *, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG (creating the folder) and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
