"""Reading result files of ``mrd-env score`` and merging them into a leaderboard (``mrd-env leaderboard``).

:func:`read_result` reads one result file as plain data — nothing it names is imported or run — and checks it field
by field, within bounds (a result file comes from anywhere; none may stall or exhaust the reader):

- the file: a regular file (never a FIFO or a device) of at most :data:`MAX_RESULT_BYTES`, and the files of one
  leaderboard :data:`MAX_TOTAL_BYTES` together, at most :data:`MAX_RESULTS` of them;
- at most :data:`MAX_EPISODES` episodes and :data:`MAX_SCENARIOS` scenarios per file, and :data:`MAX_CELLS`
  cells (controllers × scenarios) per leaderboard;
- every name shown in a table (the controller's, the suite's, a scenario, an episode label, a criterion, a unit):
  one printable line of at most :data:`MAX_NAME` characters; any other text at most :data:`MAX_TEXT` characters.

A file beyond a bound is refused with one line naming the file and the field, before anything is written.

:func:`leaderboards` groups result files by suite (its id) and makes one :class:`Leaderboard` per suite, each written
to ``<out>/<suite id>/`` (what ``mrd-env leaderboard`` runs); :func:`leaderboard` merges the files of one suite and
refuses a file of another suite, version or digest than the first file's. Both refuse files of one id with
different digests (their shares are against other references), a file given twice and two files of the same result
(the same controller description and the same return in every episode: :func:`_check_distinct`), and check every
result against its suite (:func:`check_against_suite`): its episodes are the suite's and every share is the one its
return gives with the suite's stored references, (R − R_p) / (R_c − R_p) — the file holds the return, the suite the
references, so a share edited by hand is refused naming the file and the episode. The suite is the shipped one of
the result's id (whose digest :func:`read_result` checked), or one given (``--suite``); :func:`leaderboards` refuses
a result of any other suite, :func:`leaderboard` merges it unchecked and its tables say so. Complete results are
ranked, best first by the pooled share over all scenarios (:mod:`experiments.benchmark.aggregate`: each episode
weighed by its range R_c − R_p; the mean of the episodes' shares is shown beside it), and each is compared with the
next and with the best law on the same episodes (:func:`paired_verdicts`); a partial one (``score --episodes``) is shown apart, never ranked: its own section of the
Markdown, below the ranked rows of the CSV with no rank, below a dotted line in the figure, each marked
"partial: n of N episodes".

:meth:`Leaderboard.write` writes its five files as one set: into a staging folder beside ``out``, swapped in whole
(:func:`mrd_env.storage.replace_folder`), so that a reader or a kill at any moment finds the previous set or the new
one. :func:`write_leaderboards` does so for each suite's folder, leaving other suites' folders as they are; with
``html`` each set also holds the suite's page, ``leaderboard.html`` (:mod:`experiments.benchmark.page`).
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from mrd_env import storage
from mrd_env.suites import MAX_EPISODES, MAX_SCENARIOS, MAX_VERSION, check_shipped_id
from mrd_env.suites import NAME as SUITE_NAME

from experiments.benchmark.aggregate import paired_comparison, pooled_shares
from experiments.common.evaluation import grouped_bars, mean_ci
from experiments.benchmark.scoring import (ALL, FORMAT, KINDS, MEAN_SHARE, PAIRED_HEADING, READ_VERSIONS, SuiteResult,
                                           interval_cell)

#: The largest result file read: 4 MiB, 206 times the result of the largest shipped suite (car-comfort-v1, 31
#: episodes: 20 344 bytes), room for about 6 000 episodes of seven criteria.
MAX_RESULT_BYTES = 4 * 1024 ** 2
#: The most bytes of all the result files of one leaderboard together (the memory it takes is a few times this).
MAX_TOTAL_BYTES = 32 * 1024 ** 2
#: The most result files (controllers) of one leaderboard.
MAX_RESULTS = 100
#: The most cells (controllers × scenarios) of one leaderboard's table: each is an interval to compute.
MAX_CELLS = 5_000
#: The longest name shown in a table (a suite's scenario name may have 200 characters, its label 12 more).
MAX_NAME = 256
#: The longest other text of a result file (an argument of its command, a path).
MAX_TEXT = 4096
#: The leaderboard table's column of each ranked row's paired verdict against the next one.
NEXT = "against the next"
#: The leaderboard table's own columns: no scenario may be named so.
RESERVED = ("rank", "controller", "kind", "episodes", ALL, MEAN_SHARE, NEXT)
#: The files a leaderboard folder holds: the table (Markdown, CSV), its numbers (Markdown, CSV) and the figure.
FILES = ("leaderboard.md", "leaderboard.csv", "leaderboard_rows.md", "leaderboard_rows.csv", "leaderboard.png")
#: The leaderboard's HTML page (:mod:`experiments.benchmark.page`), beside :data:`FILES` where asked for (``html``).
PAGE = "leaderboard.html"


# ---------------------------------------------------------------------------------------------- reading results


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a number in strict JSON")


def _is_number(v, optional: bool = True) -> bool:
    if v is None:
        return optional
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _shown(text: str, n: int = 40) -> str:
    """A short excerpt of ``text`` for an error line (a 5 MB name must not become a 5 MB message)."""
    return repr(text[:n]) + (f"… ({len(text)} characters)" if len(text) > n else "")


def _check_texts(data, bad) -> None:
    """``bad(...)`` for a text of the file longer than :data:`MAX_TEXT` (every string and key, however nested)."""
    stack = [(data, "")]
    while stack:
        v, at = stack.pop()
        if isinstance(v, dict):
            for k, x in v.items():
                if len(k) > MAX_TEXT:
                    raise bad(f"a key in {at or 'the file'} has {len(k)} characters, at most {MAX_TEXT}")
                stack.append((x, f"{at}.{k}" if at else k))
        elif isinstance(v, list):
            stack.extend((x, f"{at}[{i}]") for i, x in enumerate(v))
        elif isinstance(v, str) and len(v) > MAX_TEXT:
            raise bad(f"{at} has {len(v)} characters, at most {MAX_TEXT}")


def _check_name(value, field: str, bad) -> None:
    """``bad(...)`` unless ``value`` is one printable line of 1 to :data:`MAX_NAME` characters (it is shown in the
    tables: a newline would break a row, a control character reach the terminal that prints them)."""
    if not isinstance(value, str) or not value.strip():
        raise bad(f"{field} must be a non-empty text")
    if len(value) > MAX_NAME:
        raise bad(f"{field} has {len(value)} characters, at most {MAX_NAME}: {_shown(value)}")
    if not value.isprintable():
        raise bad(f"{field} must be printable text on one line (no control character), got {_shown(value)}")


def read_result(path: str | Path, limit: int = MAX_RESULT_BYTES) -> SuiteResult:
    """The result in the file ``path``, read as plain data (nothing it names is imported or run) and checked field by
    field within the module's bounds; ``limit``: the most bytes read (at most :data:`MAX_RESULT_BYTES`).
    ``ValueError`` (one line, naming the file and the field) for another format, a malformed file or one beyond a
    bound."""
    path = Path(path)
    where = f"result file {path}"
    raw = storage.read_limited(path, min(limit, MAX_RESULT_BYTES), what="result file")
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
        raise ValueError(f"{where}: not a JSON result of mrd-env score ({str(exc)[:200]})") from None
    except RecursionError:
        raise ValueError(f"{where}: not a result of mrd-env score (nested too deep)") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where}: not a result of mrd-env score (its format must be {FORMAT!r})")
    version = data.get("format_version")
    if isinstance(version, bool) or version not in READ_VERSIONS:
        raise ValueError(f"{where}: result format version {str(version)[:20]}, this mrd-env reads "
                         f"{', '.join(map(str, READ_VERSIONS))}")

    def bad(what: str):
        return ValueError(f"{where}: {what}")

    _check_texts(data, bad)
    s = data.get("suite")
    if not isinstance(s, dict) or not isinstance(s.get("name"), str) or not isinstance(s.get("version"), int) \
            or isinstance(s.get("version"), bool) or not isinstance(s.get("digest"), str) \
            or not re.fullmatch(r"[0-9a-f]{64}", s["digest"]) or s.get("id") != f"{s['name']}-v{s['version']}" \
            or not isinstance(s.get("episodes"), int) or s["episodes"] < 1:
        raise bad("its suite must give name, version, id (name-vN), digest (SHA-256) and episodes")
    _check_name(s["name"], "its suite's name", bad)
    if not 1 <= s["version"] <= MAX_VERSION:
        raise bad(f"its suite's version must be a whole number in [1, {MAX_VERSION}]")
    if s["episodes"] > MAX_EPISODES:
        raise bad(f"its suite has {s['episodes']} episodes, a result file at most {MAX_EPISODES}")
    check_shipped_id(s["id"], s["digest"], where=where)  # a shipped id means the shipped references
    c = data.get("controller")
    if not isinstance(c, dict) or not isinstance(c.get("name"), str) or not c["name"].strip() \
            or c.get("kind") not in KINDS:
        raise bad(f"its controller must give a name and a kind ({', '.join(KINDS)})")
    _check_name(c["name"], "its controller's name", bad)
    criteria = data.get("criteria")
    if not isinstance(criteria, list) or not all(isinstance(k, str) for k in criteria):
        raise bad("its criteria must be a list of names")
    for i, k in enumerate(criteria):
        _check_name(k, f"criteria[{i}]", bad)
    units = data.get("units", {})
    if not isinstance(units, dict) or not all(isinstance(u, str) for u in units.values()):
        raise bad("its units must map criteria to unit names")
    for k, u in units.items():
        _check_name(k, "a criterion of its units", bad)
        _check_name(u, f"the unit of {_shown(k)}", bad)
    eps = data.get("episodes")
    if not isinstance(eps, list) or not eps:
        raise bad("it holds no episodes")
    if len(eps) > s["episodes"]:
        raise bad(f"it holds {len(eps)} episodes, its suite has {s['episodes']}")
    for i, e in enumerate(eps):
        if not isinstance(e, dict) or not isinstance(e.get("label"), str) or not isinstance(e.get("scenario"), str) \
                or not isinstance(e.get("seed"), int) or not _is_number(e.get("return"), optional=False) \
                or not _is_number(e.get("share")) or not isinstance(e.get("criteria"), dict) \
                or not all(_is_number(v) for v in e["criteria"].values()) \
                or not (e.get("terminated") is None or isinstance(e["terminated"], str)):
            raise bad(f"episode {i} must give label, scenario, seed, return, share, criteria (numbers or null) and "
                      "terminated (null or a reason)")
        if (version >= 2 or "passive" in e or "clairvoyant" in e) and not (
                _is_number(e.get("passive"), optional=False) and _is_number(e.get("clairvoyant"), optional=False)):
            raise bad(f"episode {i} must give its references passive (R_p) and clairvoyant (R_c), numbers "
                      "(format version 2)")
        _check_name(e["label"], f"episode {i}'s label", bad)
        _check_name(e["scenario"], f"episode {i}'s scenario", bad)
        if e["scenario"] in RESERVED:
            raise bad(f"episode {i}'s scenario is named {e['scenario']!r}, a column of the leaderboard's table")
        for k in e["criteria"]:
            _check_name(k, f"a criterion of episode {i}", bad)
    labels = [e["label"] for e in eps]
    if len(set(labels)) != len(labels):
        raise bad("an episode appears twice")
    n_scenarios = len({e["scenario"] for e in eps})
    if n_scenarios > MAX_SCENARIOS:
        raise bad(f"it holds {n_scenarios} scenarios, at most {MAX_SCENARIOS}")
    eps = [{**e, "share": math.nan if e["share"] is None else e["share"],
            "criteria": {k: math.nan if v is None else v for k, v in e["criteria"].items()}} for e in eps]
    return SuiteResult(suite=s, controller=c, episodes=eps, criteria=criteria, units=units,
                       created=str(data.get("created", "")), mrd_env_version=str(data.get("mrd_env_version", "")),
                       command=data.get("command") if isinstance(data.get("command"), list) else None)


def _suite_key(r: SuiteResult) -> tuple:
    return r.suite["name"], r.suite["version"], r.suite["digest"]


def _partial_note(r: SuiteResult) -> str:
    return f"partial: {len(r.episodes)} of {r.suite['episodes']} episodes"


@dataclass
class Leaderboard:
    """Results of one suite merged (:func:`leaderboard`): ``rows`` (per controller and scenario: episodes, the pooled
    share and the mean share with their intervals, and whether the result is complete), ``table`` (one row per
    complete result, best first by the pooled share over all scenarios: that share, the mean share over all scenarios,
    the paired verdict against the next row, and one column per scenario's pooled share, each share with its interval
    as text), ``partial`` (the same for each partial result, never ranked), ``verdicts`` (:func:`paired_verdicts`).
    ``checked``: whether every share was recomputed from its return and the suite's references; ``against``: the
    suite (:class:`mrd_env.suites.Suite`) they were checked against, or None; ``labels``: each result's row label, in
    the order of ``results``."""

    suite: dict
    results: list[SuiteResult]
    rows: list[dict]
    table: list[dict]
    partial: list[dict] = field(default_factory=list)
    checked: bool = True
    #: each ranked row against the next and against the best law (:func:`paired_verdicts`)
    verdicts: list[dict] = field(default_factory=list)
    against: object = None
    labels: list[str] = field(default_factory=list)
    #: the table's column of the paired verdict against the next row
    next_column: ClassVar[str] = NEXT

    def verdicts_title(self) -> str:
        """The heading of the paired verdicts' table."""
        return VERDICTS_TITLE

    def title(self) -> str:
        unchecked = "" if self.checked else ("; shares and references as the result files state them, not checked "
                                             "against the suite's (give the suite to check them)")
        return (f"{self.suite['id']}: pooled share of the achievable gain Σ(R − R_p) / Σ(R_c − R_p) per controller "
                f"and scenario [bootstrap 95 % interval]; {MEAN_SHARE}: the mean of the episodes' shares "
                "(R − R_p) / (R_c − R_p) over all scenarios [95 % interval over episodes]; 0: the best constant "
                "command, 1: the clairvoyant optimum; ranked by the pooled share over all scenarios, "
                f"{NEXT}: the paired verdict (below); complete results only{unchecked}")

    def partial_title(self) -> str:
        return (f"{self.suite['id']}: partial results, not ranked (each share over the episodes it scored only, "
                "[95 % interval])")

    def markdown(self) -> str:
        from mrd_env.report import markdown_table, markdown_text

        # every cell made safe to show there
        if self.table:
            text = markdown_table(self.table, title=self.title())
        else:
            text = f"### {markdown_text(self.title())}\n\nno complete result: nothing is ranked\n"
        if self.verdicts:
            text += "\n" + markdown_table(self.verdicts, title=VERDICTS_TITLE)
        if self.partial:
            text += "\n" + markdown_table([{k: v for k, v in r.items() if k not in ("rank", NEXT)}
                                           for r in self.partial],
                                          title=self.partial_title())
        return text

    def write(self, out: str | Path, html: bool = False) -> dict[str, Path]:
        """``<out>/leaderboard.md`` and ``.csv`` (the table), ``leaderboard_rows.md``/``.csv`` (the numbers) and
        ``leaderboard.png`` (a panel per scenario, a bar per controller with its interval; the PNG's ``Title`` text
        entry names the suite), and with ``html`` the page ``leaderboard.html`` (:mod:`experiments.benchmark.page`),
        as one set: ``out`` becomes a folder of these files only (see :func:`check_folder`). Written into a staging folder beside ``out`` and swapped in whole, so that a reader
        or a kill at any moment finds the previous set or the new one; staging folders of an earlier writer that
        was killed are removed first. ``ValueError`` before anything is written for an ``out`` that holds other
        files."""
        out = Path(out).resolve()  # the swap replaces the folder itself (never a link to it) and needs its name
        storage.recover_folder(out)
        check_folder(out)
        _remove_stale_staging(out)
        made = [q for q in [out.parent, *out.parent.parents] if not q.exists()]
        try:
            staged = _staging_folder(out)
        except OSError as exc:
            _remove_empty(made)
            raise OSError(exc.errno, f"leaderboard folder {out} cannot be written ({exc.strerror or exc})") from None
        try:
            self._write_files(staged, html)
            storage.replace_folder(staged, out)
        except BaseException:
            shutil.rmtree(staged, ignore_errors=True)
            _remove_empty(made)
            raise
        return {"markdown": out / FILES[0], "csv": out / FILES[1], "rows_markdown": out / FILES[2],
                "rows_csv": out / FILES[3], "figure": out / FILES[4], **({"page": out / PAGE} if html else {})}

    def _write_files(self, folder: Path, html: bool = False) -> None:
        """The five files (and the page) into ``folder`` (a staging folder nobody reads: plain writes, fsync'd by the
        swap)."""
        from mrd_env.report import csv_text, markdown_table

        rows_title = (f"{self.suite['id']}: pooled share of the achievable gain Σ(R − R_p) / Σ(R_c − R_p) and its "
                      "bootstrap 95 % interval; share: the mean of the episodes' shares (R − R_p) / (R_c − R_p) and "
                      "its 95 % interval over episodes; per controller and scenario; partial results marked"
                      + ("" if self.checked else "; not checked against the suite's references"))
        texts = {FILES[0]: self.markdown(), FILES[1]: csv_text(self.table + self.partial),
                 FILES[2]: markdown_table(self.rows, title=rows_title, floatfmt=".4g"),
                 FILES[3]: csv_text(self.rows)}
        if html:
            from experiments.benchmark.page import page

            texts[PAGE] = page(self)
        for name, text in texts.items():
            (folder / name).write_bytes(text.encode("utf-8"))
        apart = {r["controller"]: r["episodes"] for r in self.partial}
        grouped_bars(self.rows, "pooled share", "pooled share lo95", "pooled share hi95", folder / FILES[4],
                     xlabel="pooled share of the achievable gain (dimensionless)", refs=(0.0, 1.0), xlim=(-1.0, 1.05),
                     title=f"{self.suite['id']}: pooled share of the achievable gain, Σ(R − R_p) / Σ(R_c − R_p); 0: "
                           "best constant command, dashed 1: clairvoyant optimum"
                           + ("; below the dotted line: partial results, not ranked" if apart and self.table else ""),
                     metadata={"Title": self.title(), "Software": "mrd-env leaderboard"}, apart=apart)


def check_folder(out: str | Path) -> None:
    """``ValueError`` (one line) unless ``out`` can become a leaderboard folder: absent, or a folder that holds
    nothing but a leaderboard's files (:data:`FILES`, :data:`PAGE`, and hidden temporaries of them left by an earlier version
    killed while writing). The folder is replaced as a whole, so a file of the user's there would be lost: refused
    rather than deleted."""
    out = Path(out)
    if not out.exists():
        return
    if not out.is_dir():
        raise ValueError(f"leaderboard folder {out} is a file, not a folder: refused")
    others = sorted(f.name for f in out.iterdir()
                    if f.name not in (*FILES, PAGE) and not (f.name.startswith(".leaderboard") and f.is_file()))
    if others:
        raise ValueError(f"leaderboard folder {out} holds {len(others)} file(s) that are not a leaderboard's "
                         f"(e.g. {_shown(others[0])}): refused, since the folder is replaced as a whole by the new "
                         f"leaderboard; choose a new or empty folder, or one that holds only {', '.join(FILES)}")


def _staging_folder(out: Path) -> Path:
    """A new empty folder beside ``out`` named ``.<out name>.<process id>.<random>.staging`` (the process id tells
    a later writer whether its writer is still alive), with the mode of the user's other folders."""
    out.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{out.name}.{os.getpid()}.", suffix=".staging", dir=out.parent))
    os.chmod(staged, 0o777 & ~storage.current_umask())
    return staged


def _remove_stale_staging(out: Path) -> None:
    """Remove the staging folders beside ``out`` whose writer is no longer running (killed mid-write). Only where
    the process can be asked whether it runs without being signalled (POSIX)."""
    if os.name != "posix" or not out.parent.is_dir():
        return
    pattern = re.compile(rf"\.{re.escape(out.name)}\.(\d+)\.[^/]*\.staging")
    for f in out.parent.iterdir():
        m = pattern.fullmatch(f.name)
        if m is None or not f.is_dir() or f.is_symlink():
            continue
        pid = int(m.group(1))
        try:
            os.kill(pid, 0)  # signal 0: only asks whether the process exists
            continue
        except ProcessLookupError:
            shutil.rmtree(f, ignore_errors=True)
        except (PermissionError, OverflowError):  # another user's process (alive), or no process id
            continue


def _remove_empty(folders: list[Path]) -> None:
    """The folders a refused or failed write made, removed again (deepest first) where still empty."""
    for q in folders:
        try:
            q.rmdir()
        except OSError:
            pass


def _read_all(paths) -> tuple[list[Path], list[SuiteResult]]:
    """Every result file of ``paths`` read (:func:`read_result`), within the bounds of one call together
    (:data:`MAX_RESULTS`, :data:`MAX_TOTAL_BYTES`)."""
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("leaderboard needs at least one result file")
    if len(paths) > MAX_RESULTS:
        raise ValueError(f"leaderboard of {len(paths)} result files: at most {MAX_RESULTS} are merged")
    results, left = [], MAX_TOTAL_BYTES
    for p in paths:
        size = _size(p)
        if size > left and size <= MAX_RESULT_BYTES:
            raise ValueError(f"result file {p}: the result files hold more than {MAX_TOTAL_BYTES} bytes together, "
                             "the most one leaderboard reads: refused")
        results.append(read_result(p, limit=MAX_RESULT_BYTES if size > MAX_RESULT_BYTES else left))
        left -= size
    return paths, results


def _check_distinct(paths: list[Path], results: list[SuiteResult]) -> None:
    """``ValueError`` (one line) for a file given twice, or two files of the same result: the same suite, the same
    controller description (every field: name, kind, what was given, its options, an agent's or a source file's
    digest) and the same return for every episode — the same controller scored again, whenever, is one result, and
    would be two rows of it. Two controllers that return the same (two names of one law) are two results."""
    seen_paths, seen = {}, {}
    for p, r in zip(paths, results):
        where = p.resolve()
        if where in seen_paths:
            raise ValueError(f"result file {p} is given twice (also as {seen_paths[where]}): each result counts once")
        seen_paths[where] = p
        key = (_suite_key(r), json.dumps(r.controller, sort_keys=True),
               tuple((e["label"], e["return"]) for e in r.episodes))
        if key in seen:
            raise ValueError(f"result file {p} holds the same result as {seen[key]} (the same controller and the same "
                             "return in every episode): each result counts once, give one of them")
        seen[key] = p


#: How far a result's share may differ from the one recomputed from its return, relative (and 1e-12 absolute, for a
#: share of about 0): the recomputation is the scorer's own arithmetic on the same numbers, so only an edit differs.
SHARE_TOLERANCE = 1e-9


def check_against_suite(result: SuiteResult, suite, path) -> None:
    """``ValueError`` (one line naming the file ``path`` and the episode) unless ``result`` was scored on ``suite``
    (a :class:`mrd_env.suites.Suite`): its digest, its count of episodes, each episode's label, scenario and seed
    one of the suite's, and each share the one its return gives with the suite's references,
    (R − R_p) / (R_c − R_p) (within :data:`SHARE_TOLERANCE`), as are the references a result of format 2 stores. The
    file holds the return and the suite holds the references: a share or reference edited by hand is refused. Every
    episode of ``result`` then holds the suite's references (``passive``, ``clairvoyant``: a result of format 1 has
    none of its own), from which its pooled shares are computed."""
    where = f"result file {path}"
    if result.suite["digest"] != suite.digest:
        raise ValueError(f"{where}: scored on suite {result.suite['id']} of digest {result.suite['digest'][:12]}, "
                         f"not on the suite given ({suite.id}, digest {suite.digest[:12]}): other references")
    episodes = {sc.label(seed): (sc.name, int(seed)) for sc, seed in suite.episodes()}
    if result.suite["episodes"] != len(episodes):
        raise ValueError(f"{where}: its suite has {result.suite['episodes']} episodes, suite {suite.id} has "
                         f"{len(episodes)}")
    for e in result.episodes:
        label = e["label"]
        if label not in episodes:
            raise ValueError(f"{where}: its episode {_shown(label)} is not an episode of suite {suite.id}")
        if (e["scenario"], e["seed"]) != episodes[label]:
            raise ValueError(f"{where}: its episode {_shown(label)} gives scenario {_shown(e['scenario'])} and seed "
                             f"{e['seed']}, suite {suite.id} {episodes[label][0]!r} and seed {episodes[label][1]}")
        ref = suite.references.get(label)
        if ref is None:
            raise ValueError(f"{where}: suite {suite.id} has no reference for episode {_shown(label)}")
        want, got = ref.share(e["return"]), e["share"]
        same = (math.isnan(want) and math.isnan(got)) or \
            math.isclose(got, want, rel_tol=SHARE_TOLERANCE, abs_tol=1e-12)
        if not same:
            raise ValueError(f"{where}: episode {_shown(label)}: its share {got!r} is not the one its return "
                             f"{e['return']!r} gives with suite {suite.id}'s references, (R − R_p) / (R_c − R_p) = "
                             f"{want!r} (R_p {ref.passive!r}, R_c {ref.clairvoyant!r}): edited by hand, or scored "
                             "against other references: refused")
        for key, stored in (("passive", ref.passive), ("clairvoyant", ref.clairvoyant)):
            if key in e and not math.isclose(e[key], stored, rel_tol=SHARE_TOLERANCE, abs_tol=1e-12):
                raise ValueError(f"{where}: episode {_shown(label)}: its reference {key} {e[key]!r} is not suite "
                                 f"{suite.id}'s ({stored!r}): edited by hand, or scored against other references: "
                                 "refused")
    for e in result.episodes:
        ref = suite.references[e["label"]]
        e["passive"], e["clairvoyant"] = ref.passive, ref.clairvoyant


def _shipped_suite(suite_id: str):
    """The shipped suite ``suite_id``, or None (a result of it has its digest: :func:`read_result`)."""
    from mrd_env import suites

    return suites.suite(suite_id) if suites.shipped_digest(suite_id) is not None else None


def _given_suites(given) -> dict:
    """{id: Suite} of the suites ``given`` (each a Suite, a shipped suite's name or a suite file's path)."""
    from experiments.benchmark.scoring import resolve_suite

    out = {}
    for g in given or ():
        s = resolve_suite(g)
        if s.id in out:
            raise ValueError(f"suite {s.id} is given twice: give each suite once")
        out[s.id] = s
    return out


def _not_merged(p, r: SuiteResult, p0, r0: SuiteResult) -> ValueError:
    return ValueError(f"result file {p} was scored on suite {r.suite['id']} (digest {r.suite['digest'][:12]}), {p0} "
                      f"on {r0.suite['id']} (digest {r0.suite['digest'][:12]}): results of another suite, version or "
                      "reference values are not merged")


def leaderboard(paths, out: str | Path | None = None, *, suite=None) -> Leaderboard:
    """Merge the result files ``paths`` (of :meth:`SuiteResult.write`) into one :class:`Leaderboard`, written to
    ``out`` when given (the five files in ``out`` itself). Every file must be of the first file's suite, version and
    digest, and no two of the same result (:func:`_check_distinct`). Every share is checked against its return and
    the suite's references (:func:`check_against_suite`): a shipped suite's, or ``suite`` (a Suite, or its name or
    file); a result of another suite without ``suite`` is merged unchecked, and its tables say so (``mrd-env
    leaderboard`` and :func:`leaderboards` refuse it). ``ValueError`` (one line) otherwise."""
    paths, results = _read_all(paths)
    first = results[0]
    for p, r in zip(paths[1:], results[1:]):
        if _suite_key(r) != _suite_key(first):
            raise _not_merged(p, r, paths[0], first)
    _check_distinct(paths, results)
    _check_cells(results)
    ref = _shipped_suite(first.suite["id"])
    if suite is not None:
        given = _given_suites([suite])
        if first.suite["id"] not in given:
            raise ValueError(f"result file {paths[0]} was scored on suite {first.suite['id']}, not on the suite given "
                             f"({next(iter(given))})")
        ref = given[first.suite["id"]]
    if ref is not None:
        for p, r in zip(paths, results):
            check_against_suite(r, ref, p)
    board = _board(paths, results, checked=ref is not None, against=ref)
    if out is not None:
        board.write(out)
    return board


def leaderboards(paths, out: str | Path | None = None, *, suites=(), html: bool = False) -> dict[str, Leaderboard]:
    """The result files ``paths`` grouped by suite: {suite id: :class:`Leaderboard`}, in the order the suites first
    appear, written to ``<out>/<suite id>/`` when ``out`` is given (:func:`write_leaderboards`; ``html``: with the
    page). Every share is
    checked against its return and its suite's references (:func:`check_against_suite`): a shipped suite's, or one
    of ``suites`` (Suites, or their names or files); a result of any other suite is refused, as are files of one id
    with different digests, a result given twice and a suite given for no result. Everything is read and checked
    before anything is written: ``ValueError`` (one line) otherwise."""
    if out is not None:
        check_out_folder(out)
    paths, results = _read_all(paths)
    groups: dict[str, list[int]] = {}
    for i, r in enumerate(results):
        groups.setdefault(r.suite["id"], []).append(i)
    for members in groups.values():
        i0 = members[0]
        for i in members[1:]:
            if _suite_key(results[i]) != _suite_key(results[i0]):
                raise _not_merged(paths[i], results[i], paths[i0], results[i0])
    _check_distinct(paths, results)
    for members in groups.values():
        _check_cells([results[i] for i in members])
    given = _given_suites(suites)
    unused = [sid for sid in given if sid not in groups]
    if unused:
        raise ValueError(f"suite {unused[0]} is given (--suite), but no result file was scored on it: no result to "
                         "check against it")
    refs = {}
    for sid, members in groups.items():
        ref = refs[sid] = given.get(sid) or _shipped_suite(sid)
        if ref is None:
            raise ValueError(f"result file {paths[members[0]]} was scored on suite {sid}, which is not shipped: its "
                             "shares are checked against its references, so give its suite file (mrd-env leaderboard "
                             "--suite FILE.json; suites= from Python)")
        for i in members:
            check_against_suite(results[i], ref, paths[i])
    boards = {sid: _board([paths[i] for i in m], [results[i] for i in m], against=refs[sid])
              for sid, m in groups.items()}
    if out is not None:
        write_leaderboards(boards, out, html=html)
    return boards


def write_leaderboards(boards: dict[str, Leaderboard], out: str | Path,
                       html: bool = False) -> dict[str, dict[str, Path]]:
    """Each leaderboard into ``<out>/<suite id>/`` (:meth:`Leaderboard.write`: its five files, and with ``html`` its
    page, one set, swapped in whole); the folders of other suites in ``out`` are left as they are, and the five files of a leaderboard of the
    earlier layout (in ``out`` itself) removed once every suite's folder is written. ``ValueError`` before anything
    is written for an ``out`` that holds anything else (:func:`check_out_folder`). {suite id: the files written}."""
    out = Path(out)
    check_out_folder(out)
    for sid in boards:
        if not re.fullmatch(rf"{SUITE_NAME.pattern}-v[0-9]+", sid):  # a folder name: a suite's id only
            raise ValueError(f"suite id {_shown(sid)} cannot name a folder")
        check_folder(out / sid)
    written = {sid: board.write(out / sid, html=html) for sid, board in boards.items()}
    for f in out.iterdir():  # the earlier layout's set, now replaced by the suites' folders
        if f.is_file() and not f.is_symlink() and (f.name in FILES or f.name.startswith(".leaderboard")):
            f.unlink()
    return written


def check_out_folder(out: str | Path) -> None:
    """``ValueError`` (one line) unless ``out`` can hold the leaderboards of :func:`leaderboards`: absent, or a
    folder that holds only leaderboard folders (each of :data:`FILES` only, see :func:`check_folder`), the staging
    and set-aside folders of their writes, and the five files of a leaderboard of the earlier layout."""
    out = Path(out)
    if not out.exists():
        return
    if not out.is_dir():
        raise ValueError(f"leaderboard folder {out} is a file, not a folder: refused")
    others = []
    for f in sorted(out.iterdir()):
        if f.is_symlink():
            others.append(f.name)
        elif f.is_file():
            if f.name not in FILES and not f.name.startswith(".leaderboard"):
                others.append(f.name)
        elif f.is_dir():
            if not (f.name.startswith(".") and f.name.endswith(".staging")) and not f.name.endswith(storage.ASIDE):
                check_folder(f)
        else:
            others.append(f.name)
    if others:
        raise ValueError(f"leaderboard folder {out} holds {len(others)} file(s) that are not a leaderboard's "
                         f"(e.g. {_shown(others[0])}): refused, since it holds one leaderboard folder per suite, "
                         "each replaced as a whole; choose a new or empty folder, or one that holds only leaderboard "
                         "folders")


def _check_cells(results: list[SuiteResult]) -> None:
    scen = list(dict.fromkeys(e["scenario"] for r in results for e in r.episodes))
    if len(scen) > MAX_SCENARIOS:
        raise ValueError(f"the result files name {len(scen)} scenarios together, at most {MAX_SCENARIOS} (the "
                         "results of one suite name its scenarios)")
    if len(scen) * len(results) > MAX_CELLS:
        raise ValueError(f"{len(results)} result files on {len(scen)} scenarios: {len(scen) * len(results)} cells of "
                         f"the table, at most {MAX_CELLS} (e.g. {MAX_CELLS // 100} controllers on 100 scenarios)")


def _board(paths: list[Path], results: list[SuiteResult], checked: bool = True, against=None) -> Leaderboard:
    """The :class:`Leaderboard` of the checked ``results`` of one suite: the complete ones ranked, best first by the
    pooled share over all scenarios (ties: in the order given; results without one — references neither checked
    nor stored, format 1 merged unchecked — after those with one, by their mean share), the partial ones apart in
    the order given (a share over 4 of 31 episodes is not comparable with one over all 31). ``against``: the suite
    they were checked against."""
    names = [r.name for r in results]
    labels = [n if names.count(n) == 1 else f"{n} ({p.stem})" for n, p in zip(names, paths)]
    labels = [x if labels.count(x) == 1 else f"{x} ({i + 1})" for i, x in enumerate(labels)]
    scen = list(dict.fromkeys(e["scenario"] for r in results for e in r.episodes))
    summaries = [_share_summary(r.episodes) for r in results]
    complete = [i for i, r in enumerate(results) if r.complete]
    order = sorted(complete, key=lambda i: _rank_key(summaries[i][ALL]))
    ranked = [(labels[i], results[i]) for i in order]
    verdicts = paired_verdicts(ranked)
    against_next = {v["controller"]: v["verdict"] for v in verdicts if "next" in v["which"]}
    rows, table, partial = [], [], []
    for i in order + [i for i in range(len(results)) if i not in complete]:
        r, summ, label = results[i], summaries[i], labels[i]
        kind = _kind(r.controller)
        status = "complete" if r.complete else _partial_note(r)
        n = r.suite["episodes"]
        row = {"rank": len(table) + 1 if r.complete else "", "controller": label, "kind": kind,
               "episodes": f"{len(r.episodes)}/{n}" if r.complete else status,
               ALL: interval_cell(*_pooled(summ[ALL])), MEAN_SHARE: interval_cell(*_share(summ[ALL])),
               NEXT: against_next.get(label, ""),
               **{s: interval_cell(*_pooled(summ[s])) if s in summ else "" for s in scen}}
        (table if r.complete else partial).append(row)
        for s in [*scen, ALL] if len(scen) > 1 else scen:
            if s in summ:
                rows.append({"scenario": s, "controller": label, "kind": kind, "result": status,
                             "episodes": summ[s]["episodes"], **{k: summ[s][k] for k in _FIGURES}})
    return Leaderboard(results[0].suite, results, rows, table, partial, checked, verdicts, against, labels)


def _rank_key(summary: dict) -> tuple:
    """Best first: by the pooled share; a result without one after, by its mean share; one with neither last."""
    pooled, mean = summary["pooled share"], summary["share"]
    if math.isfinite(pooled):
        return 0, -pooled
    return (1, -mean) if math.isfinite(mean) else (2, 0.0)


#: The heading of the paired verdicts' table.
VERDICTS_TITLE = ("paired verdicts: each ranked controller against the next and against the best law (the best-ranked "
                  f"row of kind law), {PAIRED_HEADING}")


def paired_verdicts(ranked: list[tuple[str, SuiteResult]]) -> list[dict]:
    """Each ranked result (best first) against the next one and against the best law (the first result of kind
    ``law``), on the episodes both scored, over all scenarios (:func:`~experiments.benchmark.aggregate.
    paired_comparison`): the difference of their pooled shares with its paired bootstrap 95 % interval, the episodes
    won, and the verdict — ``ahead``/``behind`` where the interval excludes 0, ``tie`` where it holds 0, ``n/a``
    without an interval. ``which``: ``next``, ``best law``, or ``next, best law`` (one row where the next is the best
    law). Unpaired
    intervals of two rows often overlap where the paired one separates them."""
    best_law = next((name for name, r in ranked if r.controller.get("kind") == "law"), None)
    results = dict(ranked)
    out = []
    for i, (name, r) in enumerate(ranked):
        nxt = ranked[i + 1][0] if i + 1 < len(ranked) else None
        others = {}
        if nxt is not None:
            others[nxt] = "next"
        if best_law is not None and best_law != name:
            others[best_law] = "next, best law" if best_law == nxt else "best law"
        for other, role in others.items():
            c = paired_comparison(r, results[other])[-1]  # the row over all scenarios
            out.append({"controller": name, "against": other, "which": role,
                        "pooled share difference": interval_cell(c["difference"], c["lo95"], c["hi95"]),
                        "episodes won": f"{c['won']}/{c['episodes']}", "verdict": c["verdict"]})
    return out


def _kind(controller: dict) -> str:
    """The row's kind and, where the result records one, the digest of what was scored (an agent's files, a Python
    controller's source): ``agent ae0ee6c317fd``. Two rows of one name are told apart by it."""
    digest = controller.get("agent_digest") or controller.get("source_sha256")
    if isinstance(digest, str) and re.fullmatch(r"[0-9a-f]{12,64}", digest):
        return f"{controller['kind']} {digest[:12]}"
    return controller["kind"]


#: The figures of a leaderboard's rows, per controller and scenario: the pooled share and the mean share, each with
#: its interval.
_FIGURES = ("pooled share", "pooled share lo95", "pooled share hi95", "share", "share lo95", "share hi95")


def _share_summary(episodes: list[dict]) -> dict[str, dict]:
    """{scenario (and ``all scenarios``): episodes, pooled share (and lo95, hi95), share (the mean, lo95, hi95)}: the
    share rows of :func:`summary_rows` (the same :func:`pooled_shares` and :func:`mean_ci`), the episodes grouped
    in one pass (linear in the episodes)."""
    by_scenario: dict[str, list[float]] = {}
    for e in episodes:
        by_scenario.setdefault(e["scenario"], []).append(e["share"])
    by_scenario[ALL] = [e["share"] for e in episodes]
    pooled = pooled_shares(episodes)
    out = {}
    for s, shares in by_scenario.items():
        m, lo, hi = mean_ci(shares)
        p = pooled[s]
        out[s] = {"scenario": s, "episodes": len(shares), "pooled share": p.value, "pooled share lo95": p.lo,
                  "pooled share hi95": p.hi, "share": m, "share lo95": lo, "share hi95": hi}
    return out


def _size(path: Path) -> int:
    """The size of ``path`` in bytes, 0 where it cannot be told (:func:`read_result` then says why)."""
    try:
        return path.stat().st_size
    except OSError:
        return 0


def _share(row: dict) -> tuple[float, float, float]:
    return row["share"], row["share lo95"], row["share hi95"]


def _pooled(row: dict) -> tuple[float, float, float]:
    return row["pooled share"], row["pooled share lo95"], row["pooled share hi95"]
