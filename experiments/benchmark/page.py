"""A leaderboard as one self-contained HTML page (``leaderboard.html``, written beside the tables by
:func:`experiments.benchmark.ranking.write_leaderboards` with ``html=True``; ``mrd-env leaderboard --html``).

The page opens from disk, with no server and no network: its style sheet, its script and its charts are inline, and
it loads nothing. It shows

- the suite's identity: name, version, digest, description, control step (s), reference procedure;
- the ranked controllers, a table sortable by any column (click its header): the pooled share over all scenarios
  with its bootstrap 95 % interval (the primary column), the mean share, each scenario's pooled share, the kind with
  the digest of what was scored, the episodes, the paired verdict against the next row; partial results apart;
- the paired verdicts (each ranked row against the next and against the best law);
- one chart per scenario and one over all scenarios (inline SVG drawn here, in Python): a dot per controller at its
  pooled share, a line for its interval, the references 0 and 1 marked;
- per controller, an expandable section: its result file's controller description and every episode (return R,
  share, R_p, R_c, the criteria with their units).

**Nothing a result file holds can run in the page.** Every text is escaped (:func:`html.escape`, attributes always
quoted); the data the script reads is JSON in a ``<script type="application/json">`` element with ``<``, ``>`` and
``&`` written as ``\\u003c``, ``\\u003e``, ``\\u0026`` (:func:`json_island`), never code. A Content-Security-Policy
allows only the page's own script and style sheet (by their SHA-256), so even a script that got in would not run.

The script also keeps the page's own health visible to a reader and to the browser test
(``tests/experiments/test_leaderboard_page.py``): every script error, unhandled rejection, ``console.error`` call
and content-security violation is written into the list ``#page-errors`` and counted in the ``data-page-errors``
attribute of ``<html>`` (absent: none). Once loaded it sets ``data-page-ready`` and, on each chart, the number of
marks the browser actually drew (``data-drawn-marks``: marks with a non-empty bounding box). A URL fragment
``#sort=ranked.4`` clicks the header of column 4 of the ranked table (``ranked.4,ranked.4``: twice, the other
direction) — a link to a sorted page, and how the headless browser clicks.
"""
from __future__ import annotations

import base64
import hashlib
import html
import json
import math
import shlex

from experiments.benchmark.aggregate import ALL
from experiments.benchmark.scoring import MEAN_SHARE

#: The charts' geometry (px): a controller's row, the plot's width, a character of the 12 px labels (a generous
#: average, so that an estimated label is never narrower than the drawn one), the widest label column.
ROW_PX, PLOT_PX, CHAR_PX, MAX_LABEL_PX = 22, 440, 7.2, 300
#: The least distance (px) between two tick labels of an axis (a label such as "−0.75" is about 32 px wide).
MIN_TICK_PX = 55
#: The chart's share axis spans at least [-0.1, 1.05] and reaches down to at most -1 (a share below is drawn as an
#: arrow at the axis' end, its number in the row's text): the PNG figure's range, so a −12 does not squash the rest.
AXIS_FLOOR, AXIS_MIN, AXIS_MAX = -1.0, -0.1, 1.05

_STYLE = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:1.5em auto;max-width:1400px;
padding:0 1em;color:#1b1b1b;background:#fff}
h1{font-size:1.6em;margin:.2em 0}h2{font-size:1.25em;margin-top:1.6em;border-bottom:1px solid #ddd}
dl.identity{display:grid;grid-template-columns:max-content 1fr;gap:.15em 1em}dl.identity dt{font-weight:600}
dl.identity dd{margin:0;overflow-wrap:anywhere}
.scroll{overflow-x:auto}
table{border-collapse:collapse;margin:.5em 0}caption{text-align:left;font-size:.9em;color:#444;padding:.3em 0;
max-width:1100px}
th,td{border:1px solid #d0d0d0;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
td.primary,th.primary{background:#eef4ff;font-weight:600}table{font-size:.93em}.ci{font-weight:400;color:#555;font-size:.92em}
th button{font:inherit;font-weight:600;background:none;border:0;padding:0;cursor:pointer;text-align:left;color:inherit}
th button::after{content:" \\2195";color:#999}th[aria-sort=ascending] button::after{content:" \\25B2";color:#000}
th[aria-sort=descending] button::after{content:" \\25BC";color:#000}
.verdict-ahead{color:#0a6b2d}.verdict-behind{color:#a11}.verdict-tie{color:#555}
figure{margin:1em 0}figcaption{font-size:.9em;color:#444}
svg.chart{max-width:100%;height:auto}svg.chart text{font:12px system-ui,sans-serif;fill:#1b1b1b}
svg.chart .axis{stroke:#555}svg.chart .grid{stroke:#e4e4e4}svg.chart .ref0{stroke:#333}
svg.chart .ref1{stroke:#333;stroke-dasharray:5 4}svg.chart .interval{stroke:#2a5db0;stroke-width:2}
svg.chart .mark{fill:#2a5db0}svg.chart .mark.partial{fill:#fff;stroke:#2a5db0;stroke-width:1.5}
svg.chart .apart{stroke:#888;stroke-dasharray:2 3}svg.chart .tick{font-size:11px}
details{margin:.3em 0;border:1px solid #ddd;padding:.3em .6em}summary{cursor:pointer;font-weight:600}
dl.controller{display:grid;grid-template-columns:max-content 1fr;gap:.1em 1em}dl.controller dd{margin:0;
overflow-wrap:anywhere;font-family:ui-monospace,monospace;font-size:.9em;white-space:pre-wrap}
#page-errors{color:#a11;font-weight:600}
"""

_SCRIPT = r"""
"use strict";
(function () {
  var pending = [];
  function report(text) {
    var list = document.getElementById("page-errors");
    if (!list) { pending.push(text); return; }
    var item = document.createElement("li");
    item.textContent = text;
    list.appendChild(item);
    list.hidden = false;
    document.documentElement.setAttribute("data-page-errors", String(list.children.length));
  }
  window.addEventListener("error", function (e) {
    report("error: " + (e.message || (e.target && e.target.tagName) || e.type));
  }, true);
  window.addEventListener("unhandledrejection", function (e) { report("unhandled rejection: " + e.reason); });
  document.addEventListener("securitypolicyviolation", function (e) {
    report("blocked by the page's content security policy: " + e.violatedDirective);
  });
  var consoleError = console.error;
  console.error = function () {
    report("console.error: " + Array.prototype.join.call(arguments, " "));
    return consoleError.apply(console, arguments);
  };

  function compare(a, b, direction) {
    var aMissing = a === null || a === undefined, bMissing = b === null || b === undefined;
    if (aMissing || bMissing) { return aMissing === bMissing ? 0 : (aMissing ? 1 : -1); }  // missing: always last
    var order = typeof a === "number" && typeof b === "number" ? a - b : String(a).localeCompare(String(b));
    return direction === "ascending" ? order : -order;
  }

  function sortTable(table, column, keys) {
    var header = table.tHead.rows[0].cells[column];
    var previous = header.getAttribute("aria-sort");
    var direction = previous ? (previous === "ascending" ? "descending" : "ascending")
                             : header.getAttribute("data-first-sort");
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th) { th.removeAttribute("aria-sort"); });
    header.setAttribute("aria-sort", direction);
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (x, y) {
      var i = Number(x.getAttribute("data-row")), j = Number(y.getAttribute("data-row"));
      return compare(keys[i][column], keys[j][column], direction) || i - j;
    });
    rows.forEach(function (row) { body.appendChild(row); });
    table.setAttribute("data-sorted-by", column + " " + direction);
  }

  document.addEventListener("DOMContentLoaded", function () {
    pending.splice(0).forEach(report);
    var data = JSON.parse(document.getElementById("leaderboard-data").textContent);
    Object.keys(data.sort_keys).forEach(function (id) {
      var table = document.getElementById(id);
      if (!table) { return; }
      Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, column) {
        var button = th.querySelector("button");
        if (button) {
          button.addEventListener("click", function () { sortTable(table, column, data.sort_keys[id]); });
        }
      });
    });
    var match = /(?:^|[#&])sort=([^&]*)/.exec(location.hash);
    if (match) {
      decodeURIComponent(match[1]).split(",").forEach(function (target) {
        var parts = target.split(".");
        var table = document.getElementById(parts[0]);
        var cell = table && data.sort_keys[parts[0]] && table.tHead.rows[0].cells[Number(parts[1])];
        var button = cell && cell.querySelector("button");
        if (button) { button.click(); } else { report("no sortable column " + target); }
      });
    }
    Array.prototype.forEach.call(document.querySelectorAll("svg.chart"), function (svg) {
      var drawn = Array.prototype.filter.call(svg.querySelectorAll(".mark"), function (mark) {
        var box = mark.getBBox();
        return box.width > 0 && box.height > 0;
      });
      svg.setAttribute("data-drawn-marks", String(drawn.length));
    });
    document.documentElement.setAttribute("data-page-ready", "1");
  });
})();
"""


def _sha256(text: str) -> str:
    return "sha256-" + base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode("ascii")


#: Only the page's own style sheet and script may apply; nothing may be loaded.
POLICY = (f"default-src 'none'; style-src '{_sha256(_STYLE)}'; script-src '{_sha256(_SCRIPT)}'; img-src 'none'; "
          "base-uri 'none'; form-action 'none'")


def _t(text) -> str:
    """``text`` escaped for an element's content or a double-quoted attribute."""
    return html.escape(str(text), quote=True)


def json_island(data) -> str:
    """``data`` as JSON that may stand inside a ``<script type="application/json">`` element: ``<``, ``>`` and ``&``
    escaped (no ``</script>`` or ``<!--`` can end or change the element), the line separators U+2028/9 too, no NaN
    (null instead)."""
    text = json.dumps(_finite(data), ensure_ascii=False, allow_nan=False, separators=(",", ":"))
    for ch, code in (("&", "\\u0026"), ("<", "\\u003c"), (">", "\\u003e"), ("\u2028", "\\u2028"),
                     ("\u2029", "\\u2029")):
        text = text.replace(ch, code)
    return text


def _finite(v):
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    return v


def _num(v: float, fmt: str = ".4g") -> str:
    return f"{v:{fmt}}".replace("-", "\u2212") if isinstance(v, (int, float)) and math.isfinite(v) else "n/a"


# ------------------------------------------------------------------------------------------------- the page


def page(board) -> str:
    """The HTML page of ``board``, a :class:`~experiments.benchmark.ranking.Leaderboard` (see the module docstring;
    this module imports nothing of :mod:`~experiments.benchmark.ranking`, which imports it to write the page)."""
    from mrd_env import __version__

    figures = {(r["controller"], r["scenario"]): r for r in board.rows}
    scenarios = list(dict.fromkeys(r["scenario"] for r in board.rows if r["scenario"] != ALL))
    ranked_keys, ranked = _ranked_table("ranked", board.title(), board.table, scenarios, figures,
                                        verdict_column=board.next_column)
    parts = [_identity(board), "<h2>Ranking</h2>",
             ranked if board.table else "<p>No complete result: nothing is ranked.</p>"]
    sort_keys = {"ranked": ranked_keys}
    if board.verdicts:
        parts += ["<h2>Paired verdicts</h2>", _verdicts(board.verdicts, board.verdicts_title())]
    if board.partial:
        partial_keys, partial = _ranked_table("partial", board.partial_title(), board.partial, scenarios, figures)
        parts += ["<h2>Partial results (not ranked)</h2>", partial]
        sort_keys["partial"] = partial_keys
    parts += ["<h2>Charts</h2>", _charts(board, scenarios, figures)]
    parts += ["<h2>Controllers and their episodes</h2>", _controllers(board)]
    title = f"{board.suite['id']} leaderboard"
    data = {"suite": _identity_fields(board), "sort_keys": sort_keys}
    return "\n".join([
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{_t(POLICY)}">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_t(title)}</title>",
        f"<style>{_STYLE}</style>",
        f"<script>{_SCRIPT}</script>",
        "</head>",
        "<body>",
        '<ol id="page-errors" hidden></ol>',
        f"<h1>{_t(title)}</h1>",
        *parts,
        f"<p><small>Written by mrd-env leaderboard (mrd-env {_t(__version__)}). Click a column's header to sort; "
        "the data: the JSON element <code>#leaderboard-data</code>.</small></p>",
        f'<script type="application/json" id="leaderboard-data">{json_island(data)}</script>',
        "</body>",
        "</html>",
        "",
    ])


def _identity_fields(board) -> dict:
    """The suite's identity: what the result files state, and what the suite the shares were checked against
    holds (its description, control step and reference procedure)."""
    s, ref = board.suite, board.against
    fields = {"name": s["name"], "version": s["version"], "id": s["id"], "digest": s["digest"],
              "episodes": s["episodes"], "plant": s.get("plant", ""), "environment": s.get("env_id", "")}
    if ref is not None:
        fields.update(plant=ref.plant, environment=ref.env_id, description=ref.description,
                      control_dt=ref.control_dt, procedure=ref.procedure.get("version"))
    else:
        fields.update(description=None, control_dt=s.get("control_dt"), procedure=None)
    fields["checked"] = board.checked
    return fields


def _identity(board) -> str:
    f = _identity_fields(board)
    unknown = ("not recorded in the suite" if f["checked"]
               else "not known (the shares were not checked against the suite)")
    items = [("suite", f["name"]), ("version", f["version"]), ("digest (SHA-256)", f["digest"]),
             ("episodes", f["episodes"]), ("plant", f["plant"] or unknown), ("environment", f["environment"] or unknown),
             ("description", f["description"] if f["description"] is not None else unknown),
             ("control step (s)", f["control_dt"] if f["control_dt"] is not None else unknown),
             ("reference procedure (version)", f["procedure"] if f["procedure"] is not None else unknown),
             ("shares", "each recomputed from its return and the suite's references" if f["checked"]
              else "as the result files state them, not checked against the suite's references")]
    return ('<dl class="identity">' + "".join(f"<dt>{_t(k)}</dt><dd>{_t(v)}</dd>" for k, v in items) + "</dl>")


def _ranked_table(table_id: str, caption: str, rows: list[dict], scenarios: list[str], figures: dict,
                  verdict_column: str | None = None) -> tuple[list[list], str]:
    """(sort keys per row and column, the table's HTML): the table rows of a leaderboard with a number to sort each
    share column by (its pooled share, or mean share) from the leaderboard's rows; ``verdict_column``: the ranked
    table's column of the verdict against the next row (a partial result has no rank and no verdict)."""
    ranked = verdict_column is not None
    columns = [("rank", "rank", "ascending")] if ranked else []
    columns += [("controller", "controller", "ascending"), ("kind", "kind (digest of what was scored)", "ascending"),
                ("episodes", "episodes", "descending"),
                (ALL, "pooled share, all scenarios", "descending"),
                (MEAN_SHARE, "mean share, all scenarios", "descending")]
    if ranked:
        columns.append((verdict_column, "paired verdict against the next", "ascending"))
    columns += [(s, f"{s}: pooled share", "descending") for s in scenarios]
    keys, body = [], []
    for i, row in enumerate(rows):
        label = row["controller"]
        # a suite of one scenario has no row over all scenarios: its scenario's row is that
        overall = figures.get((label, ALL)) or (figures.get((label, scenarios[0])) if scenarios else None)
        values, cells = [], []
        for key, _, _ in columns:
            text, cls = row.get(key, ""), ""
            if key == "rank":
                value, cls = row["rank"], "num"
            elif key == "episodes":
                value, cls = overall["episodes"] if overall else None, "num"
            elif key == ALL:
                value, cls = overall["pooled share"] if overall else None, "num primary"
            elif key == MEAN_SHARE:
                value, cls = overall["share"] if overall else None, "num"
            elif key in scenarios:
                fig = figures.get((label, key))
                value, cls = fig["pooled share"] if fig else None, "num"
            else:
                value = str(text)
                if key == verdict_column and text:
                    cls = f"verdict-{text}"
            values.append(value)
            shown = _t(text)
            if key == ALL or key == MEAN_SHARE or key in scenarios:  # the interval under the value: narrow columns
                value_text, _, interval = str(text).partition(" [")
                shown = _t(value_text) + (f'<br><span class="ci">[{_t(interval)}</span>' if interval else "")
            cells.append(f'<td class="{cls}">{shown}</td>' if cls else f"<td>{shown}</td>")
        keys.append(values)
        body.append(f'<tr data-row="{i}">' + "".join(cells) + "</tr>")
    primary = ' class="primary"'
    head = "".join(f'<th scope="col" data-first-sort="{first}"{primary if k == ALL else ""}>'
                   f'<button type="button">{_t(title)}</button></th>' for k, title, first in columns)
    return keys, (f'<div class="scroll"><table id="{table_id}" class="sortable"><caption>{_t(caption)}; each share '
                  "(dimensionless) over its [95 % interval]; click a header to sort</caption>"
                  f"<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>")


def _verdicts(verdicts: list[dict], title: str) -> str:
    keys = list(verdicts[0])
    head = "".join(f'<th scope="col">{_t(k)}</th>' for k in keys)
    body = "".join("<tr>" + "".join(f'<td class="verdict-{_t(v[k])}">{_t(v[k])}</td>' if k == "verdict"
                                    else f"<td>{_t(v[k])}</td>" for k in keys) + "</tr>" for v in verdicts)
    return (f'<div class="scroll"><table id="verdicts"><caption>{_t(title)}</caption>'
            f"<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>")


# ------------------------------------------------------------------------------------------------- the charts


def _charts(board, scenarios: list[str], figures: dict) -> str:
    apart = {r["controller"]: r["episodes"] for r in board.partial}
    order = [r["controller"] for r in board.table + board.partial]
    out = []
    for s in ([ALL] if len(scenarios) > 1 else []) + scenarios:
        entries = [(label, figures[(label, s)], label in apart) for label in order if (label, s) in figures]
        out.append(f"<figure><figcaption><strong>{_t(s)}</strong>: pooled share per controller "
                   f"({len(entries)} controllers)</figcaption>{chart(s, entries)}</figure>")
    legend = ("<p>Each chart: the pooled share of the achievable gain Σ(R − R_p) / Σ(R_c − R_p) of each controller "
              "(dot) and its bootstrap 95 % interval (line), the number on the right; 0 (solid line): the best "
              "constant command, 1 (dashed): the clairvoyant optimum; a share beyond the axis is an arrow at its end"
              + ("; hollow, below the dotted line: partial results, not ranked" if apart else "") + ".</p>")
    return legend + "\n".join(out)


def _ticks(lo: float, hi: float, width: float) -> list[float]:
    """Tick values over [lo, hi] at least :data:`MIN_TICK_PX` apart on an axis ``width`` px long."""
    for step in (0.1, 0.2, 0.25, 0.5, 1.0, 2.0):
        if step * width / (hi - lo) >= MIN_TICK_PX:
            break
    first = math.ceil(lo / step - 1e-9)
    return [round(k * step, 10) for k in range(first, int(math.floor(hi / step + 1e-9)) + 1)]


def chart(scenario: str, entries: list[tuple[str, dict, bool]]) -> str:
    """One inline SVG: a row per controller (``entries``: its label, its leaderboard row — pooled share and interval
    —, whether partial), its label on the left (shortened to the label column with an ellipsis, the whole label its
    tooltip), a mark at the pooled share and a line over the interval, the share and interval as text on the
    right; the x axis (dimensionless share) with ticks at least :data:`MIN_TICK_PX` apart. Labels, ticks and texts
    each have their own column and row, so none overlaps another."""
    finite = [x for _, r, _ in entries for x in (r["pooled share"], r["pooled share lo95"], r["pooled share hi95"])
              if math.isfinite(x)]
    lo = max(AXIS_FLOOR, min([AXIS_MIN, *finite]))
    hi = max([AXIS_MAX, *finite])
    lo, hi = math.floor(lo * 4) / 4 if lo < AXIS_MIN else lo, hi
    chars = max([len(label) + (10 if partial else 0) for label, _, partial in entries] + [10])
    label_px = min(MAX_LABEL_PX, chars * CHAR_PX + 12)
    max_chars = int((label_px - 12) / CHAR_PX)
    value_px = 29 * CHAR_PX  # "−0.123 [−0.456, −0.012]" and a margin
    top, gap = 8, ROW_PX if any(p for _, _, p in entries) else 0
    n_ranked = sum(1 for _, _, p in entries if not p)
    plot_h = len(entries) * ROW_PX + gap
    width, height = label_px + PLOT_PX + value_px, top + plot_h + 48

    def x(v: float) -> float:
        return label_px + (min(max(v, lo), hi) - lo) / (hi - lo) * PLOT_PX

    out = [f'<svg class="chart" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
           f'viewBox="0 0 {width:.0f} {height:.0f}" role="img" aria-label="{_t(scenario)}: pooled shares">']
    bottom = top + plot_h
    for t in _ticks(lo, hi, PLOT_PX):
        out.append(f'<line class="grid" x1="{x(t):.1f}" x2="{x(t):.1f}" y1="{top}" y2="{bottom}"/>'
                   f'<line class="axis" x1="{x(t):.1f}" x2="{x(t):.1f}" y1="{bottom}" y2="{bottom + 5}"/>'
                   f'<text class="tick" x="{x(t):.1f}" y="{bottom + 18}" text-anchor="middle">{_num(t, "g")}</text>')
    out.append(f'<line class="ref0" x1="{x(0):.1f}" x2="{x(0):.1f}" y1="{top}" y2="{bottom}"/>'
               f'<line class="ref1" x1="{x(1):.1f}" x2="{x(1):.1f}" y1="{top}" y2="{bottom}"/>'
               f'<line class="axis" x1="{label_px}" x2="{label_px + PLOT_PX}" y1="{bottom}" y2="{bottom}"/>'
               f'<text x="{label_px + PLOT_PX / 2:.1f}" y="{bottom + 38}" text-anchor="middle">pooled share of the '
               "achievable gain (dimensionless)</text>")
    if gap and n_ranked:
        y_apart = top + n_ranked * ROW_PX + gap / 2
        out.append(f'<line class="apart" x1="0" x2="{width:.0f}" y1="{y_apart:.1f}" y2="{y_apart:.1f}"/>')
    for i, (label, r, partial) in enumerate(entries):
        y = top + i * ROW_PX + ROW_PX / 2 + (gap if partial else 0)
        shown = label + (" (partial)" if partial else "")
        short = shown if len(shown) <= max_chars else shown[:max_chars - 1] + "…"
        out.append(f'<text x="{label_px - 8}" y="{y + 4:.1f}" text-anchor="end"><title>{_t(shown)}</title>'
                   f"{_t(short)}</text>")
        v, v_lo, v_hi = r["pooled share"], r["pooled share lo95"], r["pooled share hi95"]
        if math.isfinite(v_lo) and math.isfinite(v_hi):
            out.append(f'<line class="interval" x1="{x(v_lo):.1f}" x2="{x(v_hi):.1f}" y1="{y:.1f}" y2="{y:.1f}"/>')
        cls = "mark partial" if partial else "mark"
        if math.isfinite(v) and lo <= v <= hi:
            out.append(f'<circle class="{cls}" cx="{x(v):.1f}" cy="{y:.1f}" r="4.5"><title>{_t(label)}: '
                       f"{_num(v, '.3f')}</title></circle>")
        elif math.isfinite(v):  # beyond the axis: an arrow at its end, pointing out
            tip = x(v) + (-2 if v < lo else 2)
            back = tip + (9 if v < lo else -9)
            out.append(f'<path class="{cls}" d="M{tip:.1f},{y:.1f} L{back:.1f},{y - 5:.1f} L{back:.1f},{y + 5:.1f} Z">'
                       f"<title>{_t(label)}: {_num(v, '.3f')} (beyond the axis)</title></path>")
        interval = f" [{_num(v_lo, '.3f')}, {_num(v_hi, '.3f')}]" if math.isfinite(v_lo) else ""
        out.append(f'<text x="{label_px + PLOT_PX + 10}" y="{y + 4:.1f}">{_num(v, ".3f")}{interval}</text>')
    out.append("</svg>")
    return "".join(out)


# ------------------------------------------------------------------------------------------------- controllers


def _controllers(board) -> str:
    """Per result (ranked first, then partial), a ``<details>``: its controller description and its episodes."""
    by_label = dict(zip(board.labels, board.results))
    order = [r["controller"] for r in board.table + board.partial]
    return "\n".join(_controller(label, by_label[label]) for label in order if label in by_label)


def _description(result) -> list[tuple[str, str]]:
    items = [(str(k), v if isinstance(v, str) else json.dumps(v, ensure_ascii=False, sort_keys=True))
             for k, v in result.controller.items()]
    if result.command:
        items.append(("command", shlex.join(str(a) for a in result.command)))
    items += [("scored", result.created or "not recorded"), ("mrd-env version", result.mrd_env_version or "not "
                                                                                                        "recorded")]
    return items


def _controller(label: str, result) -> str:
    criteria = [k for k in result.criteria if any(k in e["criteria"] for e in result.episodes)]

    def unit(k: str) -> str:
        return f"{k} ({result.units[k]})" if k in result.units else k

    head = ["episode", "scenario", "seed", "return R", "share (R − R_p) / (R_c − R_p)", "R_p (best constant)",
            "R_c (clairvoyant)", *map(unit, criteria), "terminated"]
    rows = []
    for e in result.episodes:
        cells = [_t(e["label"]), _t(e["scenario"]), _t(e["seed"])]
        nums = [e["return"], e["share"], e.get("passive", math.nan), e.get("clairvoyant", math.nan),
                *(e["criteria"].get(k, math.nan) for k in criteria)]
        rows.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells)
                    + "".join(f'<td class="num">{_t(_num(v))}</td>' for v in nums)
                    + f"<td>{_t(e['terminated'] or '')}</td></tr>")
    status = "" if result.complete else f"; partial: {len(result.episodes)} of {result.suite['episodes']} episodes"
    return (f"<details><summary>{_t(label)} ({_t(result.controller['kind'])}, {len(result.episodes)} episodes"
            f"{_t(status)})</summary>"
            '<dl class="controller">' + "".join(f"<dt>{_t(k)}</dt><dd>{_t(v)}</dd>" for k, v in _description(result))
            + '</dl><div class="scroll"><table class="episodes"><caption>each episode: its return R (the reward '
            "summed over the episode, as the environment gives it), its share, the suite's references R_p and R_c "
            "(returns as R), and the criteria (units in the headers)</caption><thead><tr>"
            + "".join(f'<th scope="col">{_t(h)}</th>' for h in head)
            + "</tr></thead><tbody>" + "".join(rows) + "</tbody></table></div></details>")
