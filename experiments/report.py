"""Writing tables a person puts in a report: Markdown and CSV from the same rows."""
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
