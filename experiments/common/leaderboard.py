"""Reading result files of ``mrd-env score`` and merging them into a leaderboard (``mrd-env leaderboard``).

:func:`read_result` reads one result file as plain data — nothing it names is imported or run — and checks it field
by field. :func:`leaderboard` refuses a file of another suite, version or digest than the first file's (their shares
are against other references, or other episodes) and merges the rest into one table (controllers × scenarios, the
share with its interval) and one figure.
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from mrd_env import storage

from .evaluation import grouped_bars
from .scoring import ALL, FORMAT, FORMAT_VERSION, KINDS, SuiteResult, _cell, _csv, summary_rows


# ---------------------------------------------------------------------------------------------- reading results


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a number in strict JSON")


def _is_number(v, optional: bool = True) -> bool:
    if v is None:
        return optional
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def read_result(path: str | Path) -> SuiteResult:
    """The result in the file ``path``, read as plain data (nothing it names is imported or run) and checked field by
    field; ``ValueError`` (one line, naming the file) for another format or a malformed file."""
    path = Path(path)
    where = f"result file {path}"
    try:
        data = json.loads(path.read_text(encoding="utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
        raise ValueError(f"{where}: not a JSON result of mrd-env score ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where}: not a result of mrd-env score (its format must be {FORMAT!r})")
    if data.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{where}: result format version {data.get('format_version')!r}, this mrd-env reads "
                         f"{FORMAT_VERSION}")

    def bad(what: str):
        return ValueError(f"{where}: {what}")

    s = data.get("suite")
    if not isinstance(s, dict) or not isinstance(s.get("name"), str) or not isinstance(s.get("version"), int) \
            or isinstance(s.get("version"), bool) or not isinstance(s.get("digest"), str) \
            or not re.fullmatch(r"[0-9a-f]{64}", s["digest"]) or s.get("id") != f"{s['name']}-v{s['version']}" \
            or not isinstance(s.get("episodes"), int) or s["episodes"] < 1:
        raise bad("its suite must give name, version, id (name-vN), digest (SHA-256) and episodes")
    c = data.get("controller")
    if not isinstance(c, dict) or not isinstance(c.get("name"), str) or not c["name"].strip() \
            or c.get("kind") not in KINDS:
        raise bad(f"its controller must give a name and a kind ({', '.join(KINDS)})")
    criteria = data.get("criteria")
    if not isinstance(criteria, list) or not all(isinstance(k, str) for k in criteria):
        raise bad("its criteria must be a list of names")
    units = data.get("units", {})
    if not isinstance(units, dict) or not all(isinstance(u, str) for u in units.values()):
        raise bad("its units must map criteria to unit names")
    eps = data.get("episodes")
    if not isinstance(eps, list) or not eps:
        raise bad("it holds no episodes")
    for i, e in enumerate(eps):
        if not isinstance(e, dict) or not isinstance(e.get("label"), str) or not isinstance(e.get("scenario"), str) \
                or not isinstance(e.get("seed"), int) or not _is_number(e.get("return"), optional=False) \
                or not _is_number(e.get("share")) or not isinstance(e.get("criteria"), dict) \
                or not all(_is_number(v) for v in e["criteria"].values()) \
                or not (e.get("terminated") is None or isinstance(e["terminated"], str)):
            raise bad(f"episode {i} must give label, scenario, seed, return, share, criteria (numbers or null) and "
                      "terminated (null or a reason)")
    labels = [e["label"] for e in eps]
    if len(set(labels)) != len(labels):
        raise bad("an episode appears twice")
    if len(eps) > s["episodes"]:
        raise bad(f"it holds {len(eps)} episodes, its suite has {s['episodes']}")
    eps = [{**e, "share": math.nan if e["share"] is None else e["share"],
            "criteria": {k: math.nan if v is None else v for k, v in e["criteria"].items()}} for e in eps]
    return SuiteResult(suite=s, controller=c, episodes=eps, criteria=criteria, units=units,
                       created=str(data.get("created", "")), mrd_env_version=str(data.get("mrd_env_version", "")),
                       command=data.get("command") if isinstance(data.get("command"), list) else None)


def _suite_key(r: SuiteResult) -> tuple:
    return r.suite["name"], r.suite["version"], r.suite["digest"]


@dataclass
class Leaderboard:
    """Results of one suite merged (:func:`leaderboard`): ``rows`` (per controller and scenario: episodes, share and
    its interval), ``table`` (one row per controller, best first by the share over all scenarios: one column per
    scenario, the share and its interval as text)."""

    suite: dict
    results: list[SuiteResult]
    rows: list[dict]
    table: list[dict]

    def title(self) -> str:
        return (f"{self.suite['id']}: share of the achievable gain (R − R_p) / (R_c − R_p) per controller and "
                "scenario (mean [95 % interval over episodes]; 0: the best constant command, 1: the clairvoyant "
                "optimum)")

    def markdown(self) -> str:
        from mrd_env.report import markdown_table

        rows = [{k: (str(v).replace("|", "\\|") if isinstance(v, str) else v) for k, v in r.items()}
                for r in self.table]
        return markdown_table(rows, title=self.title())

    def write(self, out: str | Path) -> dict[str, Path]:
        """``<out>/leaderboard.md`` and ``.csv`` (the table), ``leaderboard_rows.md``/``.csv`` (the numbers) and
        ``leaderboard.png`` (one panel per scenario, a bar per controller with its interval)."""
        from mrd_env.report import write_table

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        md, csv_path = out / "leaderboard.md", out / "leaderboard.csv"
        storage.write_texts({md: self.markdown(), csv_path: _csv(self.table)})
        rows_md, rows_csv = write_table(self.rows, out / "leaderboard_rows", floatfmt=".4g",
                                        title=self.title().replace("mean [95 % interval over episodes]",
                                                                   "mean, 95 % interval over episodes"))
        png = grouped_bars(self.rows, "share", "share lo95", "share hi95", out / "leaderboard.png",
                           xlabel="share of the achievable gain (dimensionless)", refs=(0.0, 1.0), xlim=(-1.0, 1.05),
                           title=f"{self.suite['id']}: share of the achievable gain, (R − R_p) / (R_c − R_p); 0: best "
                                 "constant command, dashed 1: clairvoyant optimum")
        return {"markdown": md, "csv": csv_path, "rows_markdown": rows_md, "rows_csv": rows_csv,
                "figure": png}


def leaderboard(paths, out: str | Path | None = None) -> Leaderboard:
    """Merge the result files ``paths`` (of :meth:`SuiteResult.write`) into one :class:`Leaderboard`, written to
    ``out`` when given. Every file must be of the first file's suite, version and digest: ``ValueError`` (one line)
    for one that is not, or that is not a result."""
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("leaderboard needs at least one result file")
    results = [read_result(p) for p in paths]
    first = results[0]
    for p, r in zip(paths[1:], results[1:]):
        if _suite_key(r) != _suite_key(first):
            raise ValueError(f"result file {p} was scored on suite {r.suite['id']} (digest {r.suite['digest'][:12]}), "
                             f"{paths[0]} on {first.suite['id']} (digest {first.suite['digest'][:12]}): results of "
                             "another suite, version or reference values are not merged")
    names = [r.name for r in results]
    labels = [n if names.count(n) == 1 else f"{n} ({p.stem})" for n, p in zip(names, paths)]
    scen = list(dict.fromkeys(e["scenario"] for r in results for e in r.episodes))
    summaries = [{x["scenario"]: x for x in summary_rows(r.episodes, [])} for r in results]
    # best first by the share over all scenarios (ties: in the order given; no number: last)
    order = sorted(range(len(results)), key=lambda i: -summaries[i][ALL]["share"]
                   if math.isfinite(summaries[i][ALL]["share"]) else math.inf)
    rows, table = [], []
    for i in order:
        r, summ, label = results[i], summaries[i], labels[i]
        kind = r.controller["kind"]
        table.append({"rank": len(table) + 1, "controller": label, "kind": kind,
                      "episodes": f"{len(r.episodes)}/{r.suite['episodes']}", ALL: _cell(*_share(summ[ALL])),
                      **{s: _cell(*_share(summ[s])) if s in summ else "" for s in scen}})
        for s in [*scen, ALL] if len(scen) > 1 else scen:
            if s in summ:
                rows.append({"scenario": s, "controller": label, "kind": kind, "episodes": summ[s]["episodes"],
                             "share": summ[s]["share"], "share lo95": summ[s]["share lo95"],
                             "share hi95": summ[s]["share hi95"]})
    board = Leaderboard(first.suite, results, rows, table)
    if out is not None:
        board.write(out)
    return board


def _share(row: dict) -> tuple[float, float, float]:
    return row["share"], row["share lo95"], row["share hi95"]
