"""Hostile result files and the leaderboard's output (issue 48, items 6 and 10): a result file is read only as a
regular file within its bounds (size, episodes, scenarios, names), refused with one line naming the field before
anything is written; many scenarios merge in seconds (the figure draws at most MAX_PANELS panels); a name is shown
as text in Markdown and never taken for a formula in CSV; the five output files are one set, even when the writer
is killed. Result files are built here by hand as plain JSON (the format of ``SuiteResult.to_json``)."""
from __future__ import annotations

import csv
import io
import json
import os
import re
import signal
import time
from pathlib import Path

import pytest

from experiments.cli import main
from experiments.benchmark import ranking as lb
from experiments.benchmark.ranking import FILES, leaderboard, read_result
from mrd_env.report import csv_text, markdown_table
from tests.deadline import deadline


def result(name: str = "ctrl", suite: str = "tiny", scenarios=("ISO-C", "ISO-D"), seeds=(1, 2),
           shares=(-0.4, -0.3, 0.7, 0.1), criteria=("acc_weighted_rms",), units=None) -> dict:
    """A result of ``mrd-env score``: ``shares`` cycled over the episodes (scenario × seed)."""
    eps = []
    for i, (sc, seed) in enumerate((sc, seed) for sc in scenarios for seed in seeds):
        eps.append({"label": f"{sc} s{seed}", "scenario": sc, "seed": seed, "return": -1.0 - 0.01 * i,
                    "share": shares[i % len(shares)], "criteria": {k: 0.5 + 0.01 * i for k in criteria},
                    "terminated": None})
    return {"format": "mrd-env-score", "format_version": 1,
            "suite": {"id": f"{suite}-v1", "name": suite, "version": 1, "digest": "ab" * 32, "plant": "quarter_car",
                      "episodes": len(eps)},
            "controller": {"name": name, "kind": "law", "spec": name}, "criteria": list(criteria),
            "units": dict(units if units is not None else {k: "m/s²" for k in criteria}), "episodes": eps,
            "created": "2026-11-28T00:00:00+00:00", "mrd_env_version": "0", "command": ["mrd-env", "score"]}


def write(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def run_cli(argv, capsys) -> tuple[int, str]:
    code = main(["leaderboard", *map(str, argv)])
    _, err = capsys.readouterr()
    return code, err


def snapshot(folder: Path) -> dict:
    return {f.name: f.read_bytes() for f in sorted(folder.iterdir())} if folder.exists() else {}


@pytest.fixture
def board(tmp_path) -> Path:
    """A previous leaderboard, which a refused call must leave as it was."""
    out = tmp_path / "board"
    leaderboard([write(tmp_path / "good.json", result("good"))], out=out)
    return out


def assert_refused(argv, board: Path, capsys, *needles: str) -> str:
    before = snapshot(board)
    code, err = run_cli([*argv, "--out", board], capsys)
    assert code == 2 and err.startswith("mrd-env leaderboard: error: ") and err.count("\n") == 1, err
    assert len(err) < 1000, "the error line quotes an excerpt, not the whole field"
    for needle in needles:
        assert needle in err, err
    assert snapshot(board) == before, "a refused leaderboard changes nothing"
    assert [f.name for f in board.parent.iterdir() if f.name.endswith(".staging")] == []
    return err


# --------------------------------------------------------------------------------------------- 6a: size and time


@pytest.mark.hostile
def test_five_hundred_scenarios_merge_in_seconds_with_a_bounded_figure(tmp_path, monkeypatch):
    """500 scenarios took 134 s (a figure of 500 panels sharing an axis, laid out in quadratic time); the tables hold
    every scenario, the figure at most MAX_PANELS panels."""
    from experiments.common import evaluation

    names = [f"road {i}" for i in range(lb.MAX_SCENARIOS)]
    files = [write(tmp_path / f"{c}.json", result(c, scenarios=names, seeds=(1,))) for c in ("a", "b")]
    drawn = []
    save = evaluation.save_figure
    monkeypatch.setattr(evaluation, "save_figure",
                        lambda fig, path, **kw: drawn.append(sum(ax.get_visible() for ax in fig.axes))
                        or save(fig, path, **kw))
    start = time.perf_counter()
    board = leaderboard(files, out=tmp_path / "board")
    took = time.perf_counter() - start
    assert took < 30, f"{took:.1f} s for {len(names)} scenarios"
    assert drawn == [evaluation.MAX_PANELS]
    assert set(board.table[0]) >= set(names) and len(board.rows) == 2 * (len(names) + 1)
    md = (tmp_path / "board" / "leaderboard.md").read_text(encoding="utf-8")
    assert all(f"| {n} |" in md for n in names[-3:])


@pytest.mark.hostile
@pytest.mark.parametrize("what", ["scenarios", "episodes"])
def test_a_result_file_beyond_its_count_of_scenarios_or_episodes_is_refused(what, tmp_path, board, capsys):
    if what == "scenarios":
        data = result(scenarios=[f"s{i}" for i in range(lb.MAX_SCENARIOS + 1)], seeds=(1,))
        needle = f"at most {lb.MAX_SCENARIOS}"
    else:
        data = result(scenarios=["A"], seeds=(1,))
        data["suite"]["episodes"] = lb.MAX_EPISODES + 1
        needle = f"a result file at most {lb.MAX_EPISODES}"
    assert_refused([write(tmp_path / "r.json", data)], board, capsys, "r.json", needle)


@pytest.mark.hostile
def test_the_result_files_of_one_leaderboard_are_bounded_together(tmp_path, board, capsys, monkeypatch):
    files = [write(tmp_path / f"{c}.json", result(c)) for c in "abc"]
    size = files[0].stat().st_size
    monkeypatch.setattr(lb, "MAX_TOTAL_BYTES", 2 * size + 10)
    assert_refused(files, board, capsys, "c.json", "together")
    monkeypatch.setattr(lb, "MAX_RESULTS", 2)
    assert_refused(files, board, capsys, "3 result files", "at most 2")
    monkeypatch.setattr(lb, "MAX_RESULTS", 100)
    monkeypatch.setattr(lb, "MAX_TOTAL_BYTES", 10 * size)
    monkeypatch.setattr(lb, "MAX_CELLS", 5)   # 3 controllers × 2 scenarios: 6 cells
    assert_refused(files, board, capsys, "6 cells", "at most 5")


def test_the_leaderboards_shares_are_the_results_own_summary(tmp_path):
    """The leaderboard groups the episodes in one pass (linear, not scenarios × episodes): the same shares and
    intervals as the result's summary (SuiteResult.shares, of scoring.summary_rows)."""
    files = [write(tmp_path / f"{c}.json", result(c, scenarios=("A", "B", "C"), seeds=(1, 2, 3),
                                                  shares=shares)) for c, shares in
             (("a", (0.1, 0.5, -0.2, 0.9)), ("b", (0.3, 0.3, 0.3)), ("c", (0.2,)))]
    board = leaderboard(files)
    for f in files:
        r = read_result(f)
        mine = {row["scenario"]: (row["share"], row["share lo95"], row["share hi95"]) for row in board.rows
                if row["controller"] == r.name}
        assert mine == pytest.approx(r.shares(), nan_ok=True)


def test_the_size_cap_leaves_room_for_the_shipped_suites():
    """A result of the largest shipped suite (every episode, seven criteria, as ``mrd-env score`` writes it, with
    its summary) is far below the cap (car-comfort-v1's real result: 20 344 bytes)."""
    from mrd_env import suites

    largest = max(suites.suites().values(), key=lambda s: len(s.labels()))
    crit = ("acc_weighted_rms", "travel_rms", "travel_peak", "tyre_load_rms", "cost", "cost_stroke",
            "cost_tyre_lift_off")
    data = result("skyhook_continuous", scenarios=[sc.name for sc in largest.scenarios], seeds=(1000000,),
                  criteria=crit)
    data["episodes"] *= max(1, len(largest.labels()) // len(data["episodes"]))
    data["summary"] = [{"scenario": "x" * 20, **{f"{k}{b}": 0.123456789 for k in crit for b in ("", " lo95", " hi95")}}
                       for _ in range(len(largest.scenarios) + 1)]
    size = len(json.dumps(data, indent=1))
    assert 100 * size <= lb.MAX_RESULT_BYTES <= 16 * 1024 ** 2, size


# --------------------------------------------------------------------------------------------- 6b: every text bounded


def _long(field: str, n: int):
    """An edit of a result that makes ``field`` ``n`` characters long."""
    text = "x" * n

    def edit(d: dict) -> None:
        if field == "controller":
            d["controller"]["name"] = text
        elif field == "suite":
            d["suite"].update(name=text, id=f"{text}-v1")
        elif field == "scenario":
            d["episodes"][0]["scenario"] = text
        elif field == "label":
            d["episodes"][0]["label"] = text
        elif field == "criterion":
            d["criteria"][0] = text
        elif field == "unit":
            d["units"]["acc_weighted_rms"] = text
        elif field == "command":
            d["command"].append(text)
    return edit


@pytest.mark.hostile
@pytest.mark.parametrize("field, needle", [("controller", "controller's name"), ("suite", "suite's name"),
                                           ("scenario", "episode 0's scenario"), ("label", "episode 0's label"),
                                           ("criterion", "criteria[0]"), ("unit", "the unit of"),
                                           ("command", "command[2]")])
def test_an_overlong_text_is_refused_naming_its_field(field, needle, tmp_path, board, capsys):
    data = result()
    n = lb.MAX_TEXT + 1 if field == "command" else lb.MAX_NAME + 1
    _long(field, n)(data)
    err = assert_refused([write(tmp_path / "r.json", data)], board, capsys, needle, f"{n} characters")
    if field != "command":
        ok = result()
        _long(field, lb.MAX_NAME)(ok)
        if field == "criterion":
            ok["units"] = {}
        read_result(write(tmp_path / "ok.json", ok))  # the longest allowed name is read
    assert "xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx" not in err


@pytest.mark.hostile
def test_a_five_megabyte_name_is_refused_by_the_file_size_before_it_is_parsed(tmp_path, board, capsys):
    """The 5 MB controller name took 211 s and 3.1 GB, then exit 1 with the tables already replaced."""
    data = result()
    data["controller"]["name"] = "x" * (5 * 1024 ** 2)
    start = time.perf_counter()
    assert_refused([write(tmp_path / "big.json", data)], board, capsys, "big.json", f"{lb.MAX_RESULT_BYTES} bytes")
    assert time.perf_counter() - start < 5


# --------------------------------------------------------------------------------------------- 6c: regular files only


@pytest.mark.hostile
@pytest.mark.parametrize("kind", ["device", "fifo", "folder", "link to a device"])
@pytest.mark.skipif(os.name != "posix", reason="devices and FIFOs of POSIX")
def test_a_result_file_must_be_a_regular_file(kind, tmp_path, board, capsys):
    """/dev/zero was read until memory ran out; a FIFO blocked forever."""
    path = {"device": Path("/dev/zero"), "fifo": tmp_path / "pipe.json", "folder": tmp_path / "folder.json",
            "link to a device": tmp_path / "link.json"}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "link to a device":
        path.symlink_to("/dev/zero")
    with deadline(20):
        assert_refused([path], board, capsys, str(path), "not a regular file")


# --------------------------------------------------------------------------------------------- 10a: names as text


@pytest.mark.hostile
@pytest.mark.parametrize("name", ["two\nlines", "erase \x1b[2J", "\u202eevil", "\ud800", "tab\there", "bell\x07"])
def test_a_control_character_in_a_name_is_refused(name, tmp_path, board, capsys):
    assert_refused([write(tmp_path / "r.json", result(name))], board, capsys, "controller's name", "printable")


@pytest.mark.hostile
@pytest.mark.parametrize("name", ["all scenarios", "rank", "controller"])
def test_a_scenario_named_like_a_column_of_the_table_is_refused(name, tmp_path, board, capsys):
    assert_refused([write(tmp_path / "r.json", result(scenarios=(name, "B")))], board, capsys, "a column")


HOSTILE_NAMES = ["<script>alert(1)</script>", '=HYPERLINK("http://evil.example","click")', "+cmd|' /C calc'!A0",
                 "@SUM(1+1)", "-2+3+cmd", "a|b\\|c", "[click](javascript:alert(1))", "![img](http://evil.example/x)",
                 "R&D <b>bold</b>", "$\\frac{1}{", "\\"]


@pytest.mark.hostile
def test_hostile_names_are_shown_as_text_in_markdown_and_never_run_as_formulas_in_csv(tmp_path):
    """Each name a controller, a scenario holds a hostile name too: the Markdown renders to a table of the right
    shape with every name as its text (no tag, no link), the CSV cells read back as the names with a leading ' only
    where a spreadsheet would see a formula, and the numbers (negative shares too) stay numbers."""
    markdown_it = pytest.importorskip("markdown_it")
    files = [write(tmp_path / f"r{i}.json", result(n, scenarios=("<i>x</i>", "=1+1"))) for i, n in
             enumerate(HOSTILE_NAMES)]
    leaderboard(files, out=tmp_path / "board")   # the figure draws too ("$\\frac{" is not mathtext)
    folder = tmp_path / "board"
    html = markdown_it.MarkdownIt("commonmark").enable("table").render((folder / "leaderboard.md").read_text(encoding="utf-8"))
    assert "<script" not in html and "<b>" not in html and "<i>" not in html and "href" not in html \
        and "<img" not in html
    body = html.split("<tbody>")[1].split("</tbody>")[0]  # the ranked table (the paired verdicts follow it)
    rows = re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)
    assert len(rows) == len(HOSTILE_NAMES)
    import html as html_lib

    cells = [[html_lib.unescape(c) for c in re.findall(r"<td>(.*?)</td>", r, flags=re.S)] for r in rows]
    header = re.findall(r"<th>(.*?)</th>", html.split("<tbody>")[0])
    assert all(len(c) == len(header) for c in cells), "a name broke a row into more or fewer cells"
    assert sorted(c[1] for c in cells) == sorted(HOSTILE_NAMES), "every name shown as its text"
    assert [html_lib.unescape(h) for h in header[-2:]] == ["<i>x</i>", "=1+1"]

    table = list(csv.reader(io.StringIO((folder / "leaderboard.csv").read_text(encoding="utf-8"))))
    numbers = list(csv.DictReader(io.StringIO((folder / "leaderboard_rows.csv").read_text(encoding="utf-8"))))
    for text in [c for row in table for c in row] + [v for r in numbers for v in r.values()]:
        assert not text.startswith(("=", "+", "@", "\t", "\r")) or text.startswith("'"), text
        assert not text.startswith("-") or re.fullmatch(r"[-0-9.e, \[\]]+", text) or text.startswith("'"), text
    assert "'=1+1" in table[0]
    assert sorted(c.removeprefix("'") for c in (row[1] for row in table[1:])) == sorted(HOSTILE_NAMES)
    shares = [float(r["share"]) for r in numbers]   # numeric cells stay numeric
    assert min(shares) < 0 and all(r["share"] == repr(float(r["share"])) for r in numbers)


def test_every_table_goes_through_one_escape():
    """mrd_env.report: the one place every Markdown and CSV table of the project is written."""
    rows = [{"name|x": "a\nb", "value": -0.5, "cell": "-0.12 [-0.3, 0.05]", "f": "=1+2", "tab": "\t=x", "n": 3}]
    md = markdown_table(rows, title="t\r\n<b>")
    lines = md.splitlines()
    assert lines[0] == "### t\\r\\n&lt;b&gt;" and len(lines) == 5
    assert lines[2] == "| name\\|x | value | cell | f | tab | n |"
    assert lines[4] == "| a\\nb | -0.5 | -0.12 [-0.3, 0.05] | =1+2 | \\t=x | 3 |"
    back = list(csv.reader(io.StringIO(csv_text(rows))))
    assert back[1] == ["a\nb", "-0.5", "-0.12 [-0.3, 0.05]", "'=1+2", "'\t=x", "3"]


# --------------------------------------------------------------------------------------------- 10b: one set


@pytest.mark.hostile
def test_an_out_folder_with_files_of_the_users_is_refused(tmp_path, board, capsys):
    (board / "notes.txt").write_text("mine")
    assert_refused([write(tmp_path / "r.json", result())], board, capsys, "notes.txt", "not a leaderboard's")
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("mine")
    code, err = run_cli([tmp_path / "r.json", "--out", not_a_folder], capsys)
    assert code == 2 and "is a file" in err and not_a_folder.read_text() == "mine"


def _generation(folder: Path) -> set:
    """The generations (suite gen<k>) the five files of ``folder`` come from: one for a consistent set."""
    from PIL import Image

    found = set()
    for name in FILES[:4]:
        found |= set(re.findall(r"gen(\d+)", (folder / name).read_text(encoding="utf-8")))
    with Image.open(folder / FILES[4]) as im:
        found |= set(re.findall(r"gen(\d+)", im.text["Title"]))
    return found


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the kill test forks the writing process")
def test_a_killed_writer_leaves_one_consistent_set_and_the_next_write_no_leftovers(tmp_path):
    """13 of 100 kills left a new table beside an old figure. A process rewriting the leaderboard in a loop (four
    generations, each of its own suite and controller) is killed with SIGKILL at random moments: the folder holds
    the five files of one generation every time; the next write leaves no staging folder behind."""
    import numpy as np

    gens = [[write(tmp_path / f"gen{k}.json", result(f"ctrl-gen{k}", suite=f"gen{k}"))] for k in range(4)]
    out = tmp_path / "out" / "board"
    leaderboard(gens[0], out=out)
    rng = np.random.default_rng(0)
    kills, mid_write = 10, 0
    for i in range(kills):
        pid = os.fork()
        if pid == 0:  # the writer: rewrites the leaderboard until killed
            try:
                k = i
                while True:
                    k += 1
                    leaderboard(gens[k % 4], out=out)
            finally:
                os._exit(1)
        time.sleep(float(rng.uniform(0.05, 1.2)))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        assert sorted(f.name for f in out.iterdir()) == sorted(FILES), f"kill {i}"
        assert len(_generation(out)) == 1, f"kill {i}: files of two writes {_generation(out)}"
        mid_write += any(f.name.endswith(".staging") for f in out.parent.iterdir())
    leaderboard(gens[1], out=out)
    assert sorted(f.name for f in out.parent.iterdir()) == ["board"], "the next write removes what a kill left"
    assert sorted(f.name for f in out.iterdir()) == sorted(FILES) and _generation(out) == {"1"}


# --------------------------------------------------------------------------------------------- 4: a forged shipped id


@pytest.mark.hostile
def test_a_result_claiming_a_shipped_suite_with_other_references_is_refused(tmp_path, board, capsys):
    """A result file names its suite's id and digest: one that claims a shipped id (``car-comfort-v1``) with
    another digest was scored against other references — a forged suite whose shares would pass for the real
    suite's — and an unshipped version of a shipped suite's name is refused the same way."""
    from mrd_env.suites import shipped_digest

    real = shipped_digest("car-comfort-v1")
    assert real is not None
    forged = result(suite="car-comfort")
    forged["suite"]["digest"] = "ab" * 32
    assert_refused([write(tmp_path / "forged.json", forged)], board, capsys, "car-comfort-v1",
                   "a name of its own")
    newer = result(suite="car-comfort")
    newer["suite"].update(id="car-comfort-v9", version=9)
    assert_refused([write(tmp_path / "newer.json", newer)], board, capsys, "car-comfort-v9", "a name of its own")
    honest = result(suite="car-comfort")
    honest["suite"]["digest"] = real
    assert read_result(write(tmp_path / "honest.json", honest)).suite["id"] == "car-comfort-v1"
