"""What a person puts in a report: Markdown and CSV tables from the same rows, and PNG figures.

Every table of the project goes through :func:`markdown_table` and :func:`csv_text`, which make any text safe to
show, whoever wrote it (a controller's name in a result file from another lab):

- Markdown: ``|`` and ``\\`` are backslash-escaped (a cell stays one cell), ``<``, ``>`` and ``&`` become HTML
  entities (a renderer shows ``<script>`` as text, never runs it), ``](`` and ``][`` are escaped (no link), and a
  control character (a newline, an ANSI escape, a bidirectional override) is written as its escape, e.g. ``\\n``
  or ``\\x1b`` (the row stays one line; a terminal that prints the table receives no control sequence).
- CSV: a text cell that a spreadsheet would take for a formula (one starting with ``=``, ``+``, ``-``, ``@``, a tab
  or a carriage return) gets a leading ``'`` (OWASP's rule against formula injection); numbers stay numbers, and so
  does text made only of digits, ``.``, ``,``, ``e``, signs, brackets and spaces (``-0.5``, ``-0.12 [-0.3, 0.05]``):
  with no letter, parenthesis, ``|`` or ``!`` it can call no function and reach no other program.

Figures are drawn on :class:`matplotlib.figure.Figure` objects with the Agg canvas, never through pyplot's
global state, so writing a report never changes the matplotlib backend of the user's process.
"""
from __future__ import annotations

import csv
import io
import re
import unicodedata
from pathlib import Path

from . import storage

#: The first characters that make a spreadsheet read a CSV cell as a formula (OWASP, "CSV injection").
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: Text that is numbers and intervals of numbers only: no function call, cell reference or DDE can be written with
#: these characters, so it is left as it is in a CSV (``-0.5``, ``-0.12 [-0.3, 0.05]``).
_NUMERIC_TEXT = re.compile(r"[0-9.,eE+\-\[\] ]*")
#: Invisible characters that reorder the text around them (a table would show other text than it holds).
BIDI_CONTROLS = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}
_ESCAPES = {"<": "&lt;", ">": "&gt;", "&": "&amp;", "|": "\\|", "\\": "\\\\"}


def is_control(ch: str) -> bool:
    """Whether ``ch`` is a control character that has no place in a name shown in a table: C0/C1 controls (newline,
    tab, ANSI escape), line and paragraph separators, lone surrogates and bidirectional controls."""
    return unicodedata.category(ch) in ("Cc", "Cs", "Zl", "Zp") or ch in BIDI_CONTROLS


def _visible(ch: str) -> str:
    """A control character as text: its escape (``\\n``, ``\\x1b``, ``\\u202e``)."""
    if ch in _NAMED:
        return _NAMED[ch]
    return f"\\x{ord(ch):02x}" if ord(ch) < 0x100 else f"\\u{ord(ch):04x}"


def markdown_text(text: str) -> str:
    """``text`` as it must be written in a Markdown table cell or heading to be shown as itself (see the module
    docstring)."""
    out = []
    for ch in str(text):
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif is_control(ch):
            out.append(_visible(ch))
        else:
            out.append(ch)
    # no link or image: "[text](url)" and "[text][ref]" lose their meaning with the bracket escaped
    return "".join(out).replace("](", "\\](").replace("][", "\\][")


def csv_cell(value):
    """``value`` as a CSV cell that no spreadsheet runs: numbers as they are, text starting with a formula character
    prefixed with ``'`` unless it is numbers only (see the module docstring)."""
    if not isinstance(value, str):
        return value
    if value.startswith(FORMULA_STARTS) and not _NUMERIC_TEXT.fullmatch(value):
        return "'" + value
    return value


def csv_text(rows: list[dict]) -> str:
    """``rows`` (dicts with the keys of the first) as CSV text, every cell and header through :func:`csv_cell`."""
    if not rows:
        raise ValueError("a table needs at least one row")
    keys = list(rows[0])
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow([csv_cell(str(k)) for k in keys])
    w.writerows([csv_cell(r.get(k, "")) for k in keys] for r in rows)
    return buf.getvalue()


def write_table(rows: list[dict], path_stem: str | Path, *, title: str = "", floatfmt: str = ".4g") -> tuple[Path, Path]:
    """Write ``rows`` (dicts with the same keys) to ``<stem>.md`` and ``<stem>.csv``; return both paths. The pair is
    written together (:func:`mrd_env.storage.write_texts`): an interruption leaves both old or both new."""
    stem = Path(path_stem)
    if not rows:
        raise ValueError("write_table needs at least one row")
    md_path, csv_path = stem.with_suffix(".md"), stem.with_suffix(".csv")
    storage.write_texts({md_path: markdown_table(rows, title=title, floatfmt=floatfmt), csv_path: csv_text(rows)})
    return md_path, csv_path


def markdown_table(rows: list[dict], *, title: str = "", floatfmt: str = ".4g") -> str:
    """``rows`` (dicts with the keys of the first) as a Markdown table under a ``### title``; every header, cell and
    the title through :func:`markdown_text`, so that any text is shown as itself."""
    if not rows:
        raise ValueError("a table needs at least one row")
    keys = list(rows[0])

    def fmt(v):
        return format(v, floatfmt) if isinstance(v, float) else markdown_text(v)

    lines = [f"### {markdown_text(title)}", ""] if title else []
    lines.append("| " + " | ".join(markdown_text(k) for k in keys) + " |")
    lines.append("|" + "|".join("---" for _ in keys) + "|")
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def figure(nrows: int = 1, ncols: int = 1, *, figsize=(8.0, 4.5), **subplot_kw):
    """A new (Figure, axes) pair detached from pyplot (``constrained_layout``; ``subplot_kw`` as in
    ``Figure.subplots``, e.g. ``sharex=True``)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, constrained_layout=True)
    return fig, fig.subplots(nrows, ncols, **subplot_kw)


def save_figure(fig, path: str | Path, *, dpi: int = 110, metadata: dict | None = None) -> Path:
    """Write ``fig`` as a PNG (creating the folder) and return the path; ``metadata``: text entries of the file
    (``{"Title": ...}``, PNG text chunks), e.g. what the figure shows, readable without drawing it."""
    path = Path(path)
    with storage.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png", metadata=metadata)
    return path
