"""The leaderboard's HTML page (issue 53, item 1), written by ``mrd-env leaderboard --html`` and loaded in a real
browser: headless Chromium from the distribution's packages renders it without an error (the page writes every
script error, ``console.error`` and content-security violation into its DOM, and the browser's log must hold no
console message), clicking a column's header reorders the rows, every chart is drawn (its marks have a size), and
controller names and descriptions written to inject script appear as text, with no script of theirs run. A
screenshot is kept under the test's folder and copied to ``results/ci/leaderboard-page.png`` (the CI artefact).

Result files of the shipped suite car-comfort-v1 are built from its stored references (no episode is run): each
episode's return is R_p + f (R_c − R_p), its share f, with f per scenario and controller (so that sorting by a
scenario gives another order than the rank) and a little per episode (so that the intervals have a width)."""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

from experiments.cli import main
from experiments.benchmark.aggregate import ALL
from experiments.benchmark.page import POLICY, json_island
from experiments.benchmark.ranking import FILES, PAGE, leaderboards
from mrd_env.suites import Suite, suite

CAR = "car-comfort-v1"
ARTEFACT = Path(__file__).resolve().parents[2] / "results" / "ci" / "leaderboard-page.png"
#: Names and descriptions written to break out of an element, an attribute or the JSON island; each payload that
#: ran would mark the page (``data-pwned``, its title), and a script that got in would violate the page's policy.
HOSTILE_NAMES = ("</script><script>alert(1)</script>",
                 "\"><img src=x onerror=\"document.documentElement.setAttribute('data-pwned','1')\">",
                 "' onmouseover='document.title=\"PWNED\"' x='")
HOSTILE_DESCRIPTION = ("<!--<script>document.title='PWNED'</script>--> ]]><svg onload=alert(1)> \u2028 "
                       "</textarea><style>body{display:none}</style> &lt;b&gt;")
#: (controller, kind, {scenario index: fraction of the achievable gain}, partial): the agent is best over all, but
#: behind skyhook on ISO-A; the hostile ones in between.
CONTROLLERS = (("agent-x", "agent", (0.45, 0.40, 0.10, 0.30), False),
               ("skyhook", "law", (0.20, 0.25, 0.35, 0.10), False),
               (HOSTILE_NAMES[0], "law", (0.10, 0.05, 0.05, -0.5), False),
               (HOSTILE_NAMES[1], "python", (-0.20, -0.10, 0.15, 0.0), False),
               (HOSTILE_NAMES[2], "law", (-2.5, -1.8, -3.0, -4.0), False),
               ("partial-law", "law", (0.30, 0.30, 0.30, 0.30), True))


def result_of(s: Suite, name: str, kind: str, fractions: tuple, partial: bool) -> dict:
    """A result of ``mrd-env score`` on ``s`` (format 2): each episode at its scenario's fraction of the achievable
    gain, ± up to 0.06 per episode; ``partial``: the first episode of each scenario only."""
    eps = []
    for sc, f in zip(s.scenarios, fractions):
        for k, seed in enumerate(sc.seeds[:1] if partial else sc.seeds):
            label = sc.label(seed)
            ref = s.reference(label)
            ret = ref.passive + (f + 0.03 * ((7 * k) % 5 - 2)) * (ref.clairvoyant - ref.passive)
            eps.append({"label": label, "scenario": sc.name, "seed": seed, "return": ret, "share": ref.share(ret),
                        "passive": ref.passive, "clairvoyant": ref.clairvoyant,
                        "criteria": {"acc_weighted_rms": 0.5 + 0.01 * k}, "terminated": None})
    controller = {"name": name, "kind": kind, "spec": name, "description": HOSTILE_DESCRIPTION}
    if kind == "agent":
        controller["agent_digest"] = "ae0ee6c317fd" + "0" * 52
    return {"format": "mrd-env-score", "format_version": 2,
            "suite": {"id": s.id, "name": s.name, "version": s.version, "digest": s.digest, "plant": s.plant,
                      "env_id": s.env_id, "control_dt": s.control_dt, "episodes": len(s.labels())},
            "controller": controller, "criteria": ["acc_weighted_rms"], "units": {"acc_weighted_rms": "m/s²"},
            "episodes": eps, "created": "2026-12-01T00:00:00+00:00", "mrd_env_version": "0",
            "command": ["mrd-env", "score", name]}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> dict:
    """The page written by ``mrd-env leaderboard --html`` from the result files, and the leaderboard it shows."""
    folder = tmp_path_factory.mktemp("page")
    s = suite(CAR)
    paths = []
    for i, (name, kind, fractions, partial) in enumerate(CONTROLLERS):
        paths.append(folder / f"result{i}.json")
        paths[-1].write_text(json.dumps(result_of(s, name, kind, fractions, partial)), encoding="utf-8")
    assert main(["leaderboard", *map(str, paths), "--out", str(folder / "board"), "--html"]) == 0
    board = leaderboards(paths)[CAR]
    return {"folder": folder, "page": folder / "board" / CAR / PAGE, "board": board, "suite": s}


# ------------------------------------------------------------------------------------------- the page as a file


class Element:
    def __init__(self, tag: str, attrs: dict, parent):
        self.tag, self.attrs, self.parent, self.children = tag, attrs, parent, []

    def text(self) -> str:
        return "".join(c if isinstance(c, str) else c.text() for c in self.children)

    def iter(self, tag: str | None = None, cls: str | None = None):
        for c in self.children:
            if isinstance(c, Element):
                if (tag is None or c.tag == tag) and (cls is None or cls in c.attrs.get("class", "").split()):
                    yield c
                yield from c.iter(tag, cls)

    def find(self, tag: str | None = None, cls: str | None = None, **attrs):
        return next((e for e in self.iter(tag, cls) if all(e.attrs.get(k) == v for k, v in attrs.items())), None)


class Tree(HTMLParser):
    """A page parsed into :class:`Element`\\ s (the standard library's parser: entities decoded in text)."""

    VOID = {"meta", "br", "img", "input", "hr", "link", "wbr", "col", "source", "area", "base"}

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.root = self.at = Element("#document", {}, None)
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        e = Element(tag, {k: v or "" for k, v in attrs}, self.at)
        self.at.children.append(e)
        if tag not in self.VOID:
            self.at = e

    def handle_startendtag(self, tag, attrs):
        self.at.children.append(Element(tag, {k: v or "" for k, v in attrs}, self.at))

    def handle_endtag(self, tag):
        e = self.at
        while e is not None and e.tag != tag:
            e = e.parent
        if e is not None and e.parent is not None:
            self.at = e.parent

    def handle_data(self, data):
        self.at.children.append(data)


def ranked_rows(doc: Element) -> list[str]:
    """The controllers of the ranked table, top to bottom."""
    return [list(tr.iter("td"))[1].text() for tr in doc.find("table", id="ranked").find("tbody").iter("tr")]


def column_of(doc: Element, header: str) -> int:
    heads = [th.text() for th in doc.find("table", id="ranked").find("thead").iter("th")]
    return heads.index(header)


def test_the_page_is_one_self_contained_file_that_shows_every_part(written):
    """Beside the five files; loads nothing (no src, no href, no url(), a policy that allows only its own script and
    style sheet); the suite's identity, every controller's description, episodes and row, a chart per scenario."""
    text = written["page"].read_text(encoding="utf-8")
    assert sorted(f.name for f in written["page"].parent.iterdir()) == sorted([*FILES, PAGE])
    doc = Tree(text).root
    assert not any("src" in e.attrs or "href" in e.attrs for e in doc.iter()), "the page loads nothing"
    assert "url(" not in text and "@import" not in text
    assert doc.find("meta", **{"http-equiv": "Content-Security-Policy"}).attrs["content"] == POLICY
    s, board = written["suite"], written["board"]
    identity = doc.find("dl", "identity").text()
    for fact in (s.name, s.digest, s.description, str(s.control_dt), str(s.procedure["version"])):
        assert fact in identity
    assert len(board.table) == 5 and len(board.partial) == 1
    assert ranked_rows(doc) == [r["controller"] for r in board.table]
    details = list(doc.iter("details"))
    assert len(details) == len(CONTROLLERS)
    for d in details:
        assert HOSTILE_DESCRIPTION in d.find("dl", "controller").text()  # the description, shown as text
        episodes = len(list(d.find("table", "episodes").find("tbody").iter("tr")))
        assert episodes in (len(s.labels()), len(s.scenarios))
    charts = list(doc.iter("svg", "chart"))
    assert len(charts) == len(s.scenarios) + 1  # one over all scenarios, one per scenario
    assert all(len(list(c.iter(cls="mark"))) == len(CONTROLLERS) for c in charts)


def test_nothing_in_a_result_file_becomes_markup_or_code(written):
    """The page's only elements are its own: two scripts (its code and the JSON data), no element or attribute a
    name or description brought; the JSON island gives the names back exactly."""
    text = written["page"].read_text(encoding="utf-8")
    doc = Tree(text).root
    scripts = list(doc.iter("script"))
    assert [sc.attrs.get("type") for sc in scripts] == [None, "application/json"]
    assert not any(e.tag in ("img", "svg") and ("onerror" in e.attrs or "onload" in e.attrs) for e in doc.iter())
    assert not any(k.startswith("on") for e in doc.iter() for k in e.attrs)
    assert len(list(doc.iter("style"))) == 1 and "<!--" not in text
    island = scripts[1].text()
    assert "<" not in island and ">" not in island and "&" not in island
    data = json.loads(island)
    assert [row[1] for row in data["sort_keys"]["ranked"]] == [r["controller"] for r in written["board"].table]
    assert json.loads(json_island({"x": ["</script>", math.nan, "\u2028"]})) == {"x": ["</script>", None, "\u2028"]}


# ------------------------------------------------------------------------------------------- in a browser


def chromium() -> str | None:
    return next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)


def browse(page: Path, tmp: Path, fragment: str, screenshot: Path | None = None) -> tuple[Element, str]:
    """The DOM of ``page#fragment`` after its scripts ran in headless Chromium, and the browser's log."""
    args = [chromium(), "--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run", "--disable-extensions",
            f"--user-data-dir={tmp / 'profile'}", "--enable-logging=stderr", "--v=0", "--window-size=1280,2000",
            "--dump-dom"]
    if screenshot is not None:
        args.append(f"--screenshot={screenshot}")
    done = subprocess.run([*args, f"{page.as_uri()}#{fragment}"], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "DBUS_SESSION_BUS_ADDRESS": "disabled:"})
    assert done.returncode == 0, done.stderr[-2000:]
    return Tree(done.stdout).root, done.stderr


@pytest.mark.skipif(chromium() is None, reason="no chromium, chromium-browser or google-chrome binary on PATH: the "
                                               "page's browser test needs one (Debian: apt-get install chromium)")
def test_the_page_in_a_browser(written, tmp_path):
    """Loaded from disk with a fragment that clicks the header of ISO-A's column: no error, the rows in ISO-A's
    order (best first; clicked again: worst first), every chart's marks drawn, the hostile names as text."""
    board, page = written["board"], written["page"]
    static = Tree(page.read_text(encoding="utf-8")).root
    scenario = written["suite"].scenarios[2].name
    column = column_of(static, f"{scenario}: pooled share")
    figures = {(r["controller"], r["scenario"]): r["pooled share"] for r in board.rows}
    by_scenario = sorted((r["controller"] for r in board.table), key=lambda c: -figures[(c, scenario)])
    assert by_scenario != ranked_rows(static), "the test needs a column whose order is not the rank's"

    shot = tmp_path / "leaderboard-page.png"
    doc, log = browse(page, tmp_path, f"sort=ranked.{column}", screenshot=shot)
    html_el = doc.find("html")
    assert html_el.attrs.get("data-page-ready") == "1", "the page's script did not finish"
    assert "data-page-errors" not in html_el.attrs, doc.find("ol", id="page-errors").text()
    assert "CONSOLE" not in log, [line for line in log.splitlines() if "CONSOLE" in line]
    assert "data-pwned" not in html_el.attrs and doc.find("title").text() == f"{CAR} leaderboard"
    ranked = doc.find("table", id="ranked")
    assert ranked.attrs["data-sorted-by"] == f"{column} descending"
    assert ranked_rows(doc) == by_scenario
    charts = list(doc.iter("svg", "chart"))
    assert len(charts) == len(written["suite"].scenarios) + 1
    for c in charts:
        scen = ALL if c.attrs["aria-label"].startswith(ALL) else c.attrs["aria-label"].split(": ")[0]
        expected = sum(1 for (_, s), v in figures.items() if s == scen and math.isfinite(v))
        assert c.attrs["data-drawn-marks"] == str(expected) == str(len(CONTROLLERS)), c.attrs["aria-label"]
    cells = [td.text() for td in ranked.iter("td")]
    for name in HOSTILE_NAMES:
        assert name in cells
    assert [sc.attrs.get("type") for sc in doc.iter("script")] == [None, "application/json"]
    assert shot.stat().st_size > 10_000
    ARTEFACT.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(shot, ARTEFACT)

    again, _ = browse(page, tmp_path, f"sort=ranked.{column},ranked.{column}")
    assert again.find("table", id="ranked").attrs["data-sorted-by"] == f"{column} ascending"
    assert ranked_rows(again) == by_scenario[::-1]
