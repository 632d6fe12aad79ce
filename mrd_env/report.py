"""What a person puts in a report: Markdown and CSV tables from the same rows, and PNG figures.

Figures are drawn on :class:`matplotlib.figure.Figure` objects with the Agg canvas, never through pyplot's
global state, so writing a report never changes the matplotlib backend of the user's process.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

from . import storage


def write_table(rows: list[dict], path_stem: str | Path, *, title: str = "", floatfmt: str = ".4g") -> tuple[Path, Path]:
    """Write ``rows`` (dicts with the same keys) to ``<stem>.md`` and ``<stem>.csv``; return both paths. The pair is
    written together (:func:`mrd_env.storage.write_texts`): an interruption leaves both old or both new."""
    stem = Path(path_stem)
    if not rows:
        raise ValueError("write_table needs at least one row")
    keys = list(rows[0])
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=keys, restval="")
    w.writeheader()
    w.writerows(rows)
    md_path, csv_path = stem.with_suffix(".md"), stem.with_suffix(".csv")
    storage.write_texts({md_path: markdown_table(rows, title=title, floatfmt=floatfmt), csv_path: buf.getvalue()})
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
    with storage.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    return path
