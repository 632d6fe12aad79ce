"""The leaderboard as a new user meets it (issue 49, items 3, 4 and 9): a duplicate result refused; a partial
result shown apart, never ranked (Markdown, CSV, figure); every share recomputed from its return and the suite's
references (a shipped suite's, or the one given with ``--suite``), a hand-edited share refused naming the file and
the episode; results of several suites written as one leaderboard per suite folder; a figure whose labels and titles
never overlap, whatever the number of controllers and panels; every file written named.

Result files of a shipped suite are built here from its stored references (no episode is run): each episode's
return is R_p + f (R_c − R_p), its share f."""
from __future__ import annotations

import csv
import io
import itertools
import json
import warnings
from pathlib import Path

import pytest

from experiments.cli import main
from experiments.common import evaluation
from experiments.benchmark.ranking import FILES, leaderboard, leaderboards, read_result
from mrd_env.suites import Reference, Suite, SuiteScenario, suite, write_suite

CAR, BUILDING = "car-comfort-v1", "building-six-storey-v1"


def result_of(s: Suite, name: str, fraction: float = 0.3, episodes: int | None = None, **controller) -> dict:
    """A result of ``mrd-env score`` on the suite ``s``: every episode at ``fraction`` of its achievable gain (the
    first ``episodes`` of each scenario where given, as ``score --episodes`` writes a partial result)."""
    eps = []
    for sc in s.scenarios:
        for seed in sc.seeds[:episodes]:
            label = sc.label(seed)
            ref = s.reference(label)
            ret = ref.passive + fraction * (ref.clairvoyant - ref.passive)
            eps.append({"label": label, "scenario": sc.name, "seed": seed, "return": ret, "share": ref.share(ret),
                        "criteria": {"acc_weighted_rms": 0.5}, "terminated": None})
    return {"format": "mrd-env-score", "format_version": 1,
            "suite": {"id": s.id, "name": s.name, "version": s.version, "digest": s.digest, "plant": s.plant,
                      "episodes": len(s.labels())},
            "controller": {"name": name, "kind": "law", "spec": name, **controller}, "criteria": ["acc_weighted_rms"],
            "units": {"acc_weighted_rms": "m/s²"}, "episodes": eps, "created": "2026-12-01T00:00:00+00:00",
            "mrd_env_version": "0", "command": ["mrd-env", "score"]}


def write(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def run_cli(argv, capsys) -> tuple[int, str, str]:
    code = main(["leaderboard", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def refused(argv, capsys, *needles: str) -> str:
    """The command refuses ``argv`` with one line naming every needle, and writes nothing."""
    out = Path(argv[argv.index("--out") + 1])
    existed = out.exists()
    code, _, err = run_cli(argv, capsys)
    assert code == 2 and err.startswith("mrd-env leaderboard: error: ") and err.count("\n") == 1, err
    for needle in needles:
        assert needle in err, err
    assert existed or not out.exists(), "a refused leaderboard writes nothing"
    return err


@pytest.fixture(scope="module")
def car() -> Suite:
    return suite(CAR)


@pytest.fixture
def user_suite(tmp_path, car) -> tuple[Suite, Path]:
    """A suite of the user's (not shipped): two scenarios of the car suite's references, written to a file."""
    from mrd_env.suites import read_suite

    scen = (SuiteScenario("ISO-C", {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}}, (1, 2)),
            SuiteScenario("ISO-D", {"road": "iso8608", "road_params": {"road_class": "D", "speed": 20.0}}, (3,)))
    refs = {"ISO-C s1": Reference(-0.20, 0.0, -0.12), "ISO-C s2": Reference(-0.19, 0.0, -0.16),
            "ISO-D": Reference(-0.50, 1.0, -0.30)}
    mine = Suite(name="my-car", version=1, plant="quarter_car", env_id="mrd_env/QuarterCarPhysical-v0",
                 description="a suite of my own", options={"episode_seconds": 0.2}, control_dt=0.01, scenarios=scen,
                 criteria=("acc_weighted_rms",), references=refs)
    path = write_suite(mine, tmp_path / "my-car-v1.json")
    return read_suite(path), path


# --------------------------------------------------------------------------------------------- 3a: duplicates


def test_the_same_file_twice_is_refused(tmp_path, car, capsys):
    """It made two rows of one result."""
    a = write(tmp_path / "a.json", result_of(car, "skyhook"))
    refused([a, a, "--out", tmp_path / "board"], capsys, "a.json", "twice")
    refused([a, tmp_path / "." / "a.json", "--out", tmp_path / "board"], capsys, "twice")
    with pytest.raises(ValueError, match="twice"):
        leaderboard([a, a])


def test_the_same_result_in_two_files_is_refused_and_another_controller_with_the_same_returns_is_not(tmp_path, car,
                                                                                                   capsys):
    """The same result: the same controller description (name, kind, what was given, its options and digests) and
    the same return for every episode, whenever it was scored. Two controllers that return the same (MPC of horizon
    1 and clipped-optimal, tests/experiments/test_score.py) are two results."""
    a = write(tmp_path / "a.json", result_of(car, "skyhook"))
    again = result_of(car, "skyhook")
    again["created"] = "2027-01-01T00:00:00+00:00"
    b = write(tmp_path / "b.json", again)
    err = refused([a, b, "--out", tmp_path / "board"], capsys, "b.json", "a.json", "the same result")
    assert "same controller" in err and "same return" in err
    other = write(tmp_path / "c.json", result_of(car, "skyhook", options={"gain": 2}))
    twin = write(tmp_path / "d.json", result_of(car, "mpc h1"))
    board = leaderboard([a, other, twin])
    assert len(board.table) == 3


# --------------------------------------------------------------------------------------------- 3b: partial results


def test_a_partial_result_is_shown_apart_and_never_ranked(tmp_path, car, capsys):
    """4 of 31 episodes ranked among complete results: now ranked are the complete ones only; the partial one is
    in its own section of the Markdown, below the ranked rows of the CSV without a rank, and below a line in the
    figure, each marked "partial: n of N episodes"."""
    n = len(car.labels())
    partial = write(tmp_path / "partial.json", result_of(car, "best but partial", 0.9, episodes=1))
    k = len(read_result(partial).episodes)
    files = [partial, write(tmp_path / "a.json", result_of(car, "a", 0.3)),
             write(tmp_path / "b.json", result_of(car, "b", 0.5))]
    drawn = []
    save = evaluation.save_figure
    evaluation_save = pytest.MonkeyPatch()
    evaluation_save.setattr(evaluation, "save_figure", lambda fig, path, **kw: drawn.append(fig) or save(fig, path,
                                                                                                         **kw))
    try:
        code, out, err = run_cli([*files, "--out", tmp_path / "board"], capsys)
    finally:
        evaluation_save.undo()
    assert code == 0, err
    folder = tmp_path / "board" / CAR
    md = (folder / "leaderboard.md").read_text(encoding="utf-8")
    ranked, _, apart = md.partition("partial results, not ranked")
    assert "| 1 | b |" in ranked and "| 2 | a |" in ranked and "best but partial" not in ranked
    assert f"| best but partial | law | partial: {k} of {n} episodes |" in apart and "| 3 |" not in md
    assert md in out
    table = list(csv.DictReader(io.StringIO((folder / "leaderboard.csv").read_text(encoding="utf-8"))))
    assert [(r["rank"], r["controller"]) for r in table] == [("1", "b"), ("2", "a"), ("", "best but partial")]
    assert table[2]["episodes"] == f"partial: {k} of {n} episodes" and table[0]["episodes"] == f"{n}/{n}"
    numbers = list(csv.DictReader(io.StringIO((folder / "leaderboard_rows.csv").read_text(encoding="utf-8"))))
    assert {r["result"] for r in numbers if r["controller"] == "best but partial"} == {f"partial: {k} of {n} episodes"}
    assert {r["result"] for r in numbers if r["controller"] != "best but partial"} == {"complete"}
    (fig,) = drawn
    height = {t.get_text(): t.get_position()[1] for t in fig.axes[0].get_yticklabels()}
    assert height["b"] > height["a"] > height[f"best but partial · partial: {k} of {n} episodes"], height
    assert any(line.get_linestyle() == ":" for line in fig.axes[0].get_lines()), "a line sets the partial one apart"
    # the Python API says so too
    board = leaderboard(files)
    assert [r["controller"] for r in board.table] == ["b", "a"] and [r["controller"] for r in board.partial] == \
        ["best but partial"]


# --------------------------------------------------------------------------------------------- 3c: shares checked


def _edit_share(data: dict, i: int, share: float) -> dict:
    data["episodes"][i]["share"] = share
    return data


def test_a_share_edited_by_hand_is_refused_naming_the_file_and_the_episode(tmp_path, car, capsys):
    """The file holds the return and the suite the references: the share is recomputed, (R − R_p) / (R_c − R_p),
    for every episode. An edit beyond 1e-9 (relative) is refused; a last-digit difference is not."""
    good = result_of(car, "skyhook", 0.3)
    label = good["episodes"][5]["label"]
    share = good["episodes"][5]["share"]
    forged = write(tmp_path / "forged.json", _edit_share(json.loads(json.dumps(good)), 5, 0.95))
    err = refused([forged, "--out", tmp_path / "board"], capsys, "forged.json", label, "share", "0.95")
    assert "(R − R_p) / (R_c − R_p)" in err
    with pytest.raises(ValueError, match="forged.json"):
        leaderboard([forged])
    barely = write(tmp_path / "barely.json", _edit_share(json.loads(json.dumps(good)), 5, share * (1 + 2e-9)))
    refused([barely, "--out", tmp_path / "board"], capsys, label)
    rounding = write(tmp_path / "ok.json", _edit_share(json.loads(json.dumps(good)), 5, share * (1 + 1e-12)))
    assert run_cli([rounding, "--out", tmp_path / "board"], capsys)[0] == 0


def test_a_result_whose_episodes_are_not_the_suites_is_refused(tmp_path, car, capsys):
    data = result_of(car, "skyhook")
    data["episodes"][0]["label"] = "ISO-Z s1"
    refused([write(tmp_path / "label.json", data), "--out", tmp_path / "board"], capsys, "label.json", "ISO-Z s1",
            "not an episode of")
    data = result_of(car, "skyhook")
    data["episodes"][0]["seed"] += 1
    refused([write(tmp_path / "seed.json", data), "--out", tmp_path / "board"], capsys, "seed.json", "seed")
    data = result_of(car, "skyhook")
    data["suite"]["episodes"] += 1
    refused([write(tmp_path / "count.json", data), "--out", tmp_path / "board"], capsys, "count.json", "episodes")


def test_a_users_suite_needs_its_suite_file_and_is_checked_against_it(tmp_path, user_suite, capsys):
    """Without --suite a result of a suite that is not shipped cannot be checked: refused, saying to pass it."""
    mine, path = user_suite
    a = write(tmp_path / "a.json", result_of(mine, "skyhook", 0.4))
    refused([a, "--out", tmp_path / "board"], capsys, "a.json", "my-car-v1", "--suite")
    code, out, err = run_cli([a, "--suite", path, "--out", tmp_path / "board"], capsys)
    assert code == 0, err
    assert (tmp_path / "board" / "my-car-v1" / "leaderboard.md").exists()
    forged = write(tmp_path / "forged.json", _edit_share(result_of(mine, "other", 0.4), 2, 0.99))
    refused([a, forged, "--suite", path, "--out", tmp_path / "board2"], capsys, "forged.json", "'ISO-D'")
    # a suite file of the same id with other references: the result was not scored against it
    other = Suite(**{**{f: getattr(mine, f) for f in ("name", "version", "plant", "env_id", "description",
                                                       "options", "control_dt", "scenarios", "criteria")},
                     "references": {**mine.references, "ISO-D": Reference(-0.6, 1.0, -0.30)}})
    other_path = write_suite(other, tmp_path / "other" / "my-car-v1.json")
    refused([a, "--suite", other_path, "--out", tmp_path / "board3"], capsys, "a.json", "digest")
    # a suite given for no result is a mistake too
    refused([a, "--suite", path, "--suite", CAR, "--out", tmp_path / "board4"], capsys, CAR, "no result")


# --------------------------------------------------------------------------------------------- 4a, 9: several suites


def test_results_of_two_suites_make_one_leaderboard_per_suite_and_every_file_written_is_named(tmp_path, car, capsys):
    """The README's ``mrd-env leaderboard results/score/*.json`` failed (exit 2) once a second suite was scored
    into the folder; its "wrote" line left out leaderboard_rows.md."""
    building = suite(BUILDING)
    files = [write(tmp_path / "car_a.json", result_of(car, "a", 0.2)),
             write(tmp_path / "bld_a.json", result_of(building, "a", 0.6)),
             write(tmp_path / "car_b.json", result_of(car, "b", 0.4))]
    out = tmp_path / "board"
    code, text, err = run_cli([*files, "--out", out], capsys)
    assert code == 0, err
    assert sorted(f.name for f in out.iterdir()) == sorted([CAR, BUILDING])
    for sid, n in ((CAR, 2), (BUILDING, 1)):
        assert sorted(f.name for f in (out / sid).iterdir()) == sorted(FILES)
        md = (out / sid / "leaderboard.md").read_text(encoding="utf-8")
        assert md in text and md.count("| law |") == n
    wrote = [ln for ln in text.splitlines() if ln.startswith("wrote ")]
    assert len(wrote) == 2, text
    for sid, line in zip((CAR, BUILDING), wrote):
        assert all(str(out / sid / name) in line for name in FILES), line
    # the Python API: one Leaderboard per suite, written the same way
    boards = leaderboards(files, out=tmp_path / "py")
    assert list(boards) == [CAR, BUILDING] and [r["controller"] for r in boards[CAR].table] == ["b", "a"]
    assert sorted(f.name for f in (tmp_path / "py").iterdir()) == sorted([CAR, BUILDING])
    # one suite alone rewrites its folder and leaves the other suite's as it was
    before = (out / BUILDING / "leaderboard.md").read_bytes()
    assert run_cli([files[0], "--out", out], capsys)[0] == 0
    assert (out / BUILDING / "leaderboard.md").read_bytes() == before
    assert (out / CAR / "leaderboard.md").read_text(encoding="utf-8").count("| law |") == 1


def test_the_out_folder_holds_only_suite_folders(tmp_path, car, capsys):
    """``--out`` holds one leaderboard folder per suite: a file of the user's there (or in a suite's folder) is
    refused before anything is written; a leaderboard of the earlier layout (the five files in ``--out`` itself) is
    replaced by the suite folders."""
    a = write(tmp_path / "a.json", result_of(car, "a"))
    out = tmp_path / "board"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    refused([a, "--out", out], capsys, "notes.txt")
    assert sorted(f.name for f in out.iterdir()) == ["notes.txt"]
    (out / "notes.txt").unlink()
    (out / CAR).mkdir()
    (out / CAR / "notes.txt").write_text("mine")
    refused([a, "--out", out], capsys, "notes.txt")
    (out / CAR / "notes.txt").unlink()
    leaderboard([a], out=tmp_path / "old")  # the earlier layout: the five files in the folder itself
    assert run_cli([a, "--out", tmp_path / "old"], capsys)[0] == 0
    assert sorted(f.name for f in (tmp_path / "old").iterdir()) == [CAR]


# --------------------------------------------------------------------------------------------- 4b: the figure


def _boxes(fig):
    """The window extents (pixels) of every visible tick label, panel title, axis label and the figure's title."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.set_dpi(110)  # save_figure's
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [fig._suptitle] if fig._suptitle is not None else []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        texts += [ax.title, ax.xaxis.label]
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        # the labels drawn: matplotlib also returns those of ticks beyond the axis's limits, never drawn
        texts += [t for t in ax.get_xticklabels() if t.get_visible() and x0 <= t.get_position()[0] <= x1]
        texts += [t for t in ax.get_yticklabels() if t.get_visible() and y0 <= t.get_position()[1] <= y1]
    return [(t.get_text(), t.get_window_extent(renderer)) for t in texts if t.get_text()], renderer


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 - 0.5 and b.x0 < a.x1 - 0.5 and a.y0 < b.y1 - 0.5 and b.y0 < a.y1 - 0.5


@pytest.mark.parametrize("controllers, panels", list(itertools.product((1, 2, 5, 40), (1, 4, 12))))
def test_the_figure_has_room_for_every_label(controllers, panels, tmp_path, monkeypatch):
    """One controller on a car suite drew overlapping titles and labels ("constrained_layout not applied"); two were
    1 760 × 250 px with their row labels overlapping. For 1 to 40 controllers on 1 to 12 panels: no layout warning,
    no two labels or titles overlap, every bar at least 12 px high, at most 16 in (1 760 px) wide, long names cut
    with an ellipsis."""
    long = "a controller with a very long descriptive name that goes on and on @ 10 ms"
    names = [long if i == 1 else f"law_{i} @ 1 ms" for i in range(controllers)]
    scen = [f"ISO-C 20 m/s, a long scenario name number {k}" for k in range(panels - 1)] + ["all scenarios"]
    rows = [{"scenario": s, "controller": c, "share": 0.02 * i - 0.4, "lo": 0.02 * i - 0.5, "hi": 0.02 * i - 0.3}
            for s in scen for i, c in enumerate(names)]
    drawn = []
    save = evaluation.save_figure
    monkeypatch.setattr(evaluation, "save_figure", lambda fig, path, **kw: drawn.append(fig) or save(fig, path, **kw))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        evaluation.grouped_bars(rows, "share", "lo", "hi", tmp_path / "f.png", refs=(0.0, 1.0), xlim=(-1.0, 1.05),
                                xlabel="share of the achievable gain (dimensionless)",
                                title=f"{CAR}: share of the achievable gain, (R − R_p) / (R_c − R_p); 0: best constant "
                                      "command, dashed 1: clairvoyant optimum; " + "a long title " * 12)
        (fig,) = drawn
        boxes, renderer = _boxes(fig)
    assert not [str(w.message) for w in caught], [str(w.message) for w in caught]
    for (ta, a), (tb, b) in itertools.combinations(boxes, 2):
        assert not _overlap(a, b), f"{ta!r} overlaps {tb!r}"
    inside = fig.bbox
    assert all(inside.x0 - 0.5 <= b.x0 and b.x1 <= inside.x1 + 0.5 and inside.y0 - 0.5 <= b.y0
               and b.y1 <= inside.y1 + 0.5 for _, b in boxes), "every text inside the figure"
    bars = [p for ax in fig.axes if ax.get_visible() for p in ax.patches]
    assert len(bars) == controllers * panels
    assert min(p.get_window_extent(renderer).height for p in bars) >= 12
    assert fig.get_figwidth() * 110 <= 1760
    labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    if controllers > 1:
        assert any(t.endswith("…") and len(t) <= evaluation.MAX_LABEL for t in labels)
        assert long not in labels


def test_paired_verdicts_separate_what_unpaired_intervals_cannot(tmp_path):
    """Issue 51's leaderboard says which controller is better: each ranked row against the next on the same
    episodes. Two controllers whose shares vary a lot from episode to episode (overlapping unpaired intervals) but
    differ by a steady 0.02 on every episode are 'ahead'; two that trade places (noise whose range-weighted mean is
    0, so that their pooled shares differ by 0.005 only) are a 'tie'."""
    import math

    import numpy as np

    s = suite(CAR)
    rng = np.random.default_rng(0)
    base = {lab: float(x) for lab, x in zip(s.labels(), rng.uniform(0.0, 0.6, len(s.labels())))}
    noise = {lab: float(x) for lab, x in zip(s.labels(), rng.normal(0.0, 0.05, len(s.labels())))}
    at_stake = {lab: s.reference(lab).clairvoyant - s.reference(lab).passive for lab in s.labels()}
    drift = sum(noise[k] * at_stake[k] for k in s.labels()) / sum(at_stake.values())

    def at(name, shares):
        data = result_of(s, name)
        for e in data["episodes"]:
            ref = s.reference(e["label"])
            e["return"] = ref.passive + shares[e["label"]] * (ref.clairvoyant - ref.passive)
            e["share"] = ref.share(e["return"])
        return write(tmp_path / f"{name}.json", data)

    files = [at("first", {k: v + 0.02 for k, v in base.items()}), at("second", base),
             at("third", {k: v + noise[k] - drift - 0.005 for k, v in base.items()})]
    board = leaderboard(files)
    assert [r["controller"] for r in board.table] == ["first", "second", "third"]
    lo1, hi2 = (next(r for r in board.rows if r["controller"] == c and r["scenario"] == "all scenarios")
                for c in ("first", "second"))
    assert lo1["pooled share lo95"] < hi2["pooled share hi95"], "the unpaired intervals overlap"
    (a, b) = [v for v in board.verdicts if v["which"] == "next"]
    assert (a["controller"], a["against"], a["verdict"]) == ("first", "second", "ahead")
    assert a["episodes won"] == f"{len(s.labels())}/{len(s.labels())}"
    assert float(a["pooled share difference"].split()[0]) == pytest.approx(0.02, abs=5e-4)
    assert b["verdict"] == "tie" and math.isfinite(float(b["pooled share difference"].split()[0]))
    assert [r["against the next"] for r in board.table] == ["ahead", "tie", ""]
    assert "paired verdicts" in board.markdown() and "| ahead |" in board.markdown()