"""The shares docs/suites.md and the README publish (issue 39, "must show"): they are the figures of
``docs/suites-scores.json``, which ``python -m experiments.benchmark.shipped`` wrote, and ``mrd-env score``'s code
path (``mrd-env benchmark``'s too) reproduces them to the stored tolerance (±0.005) — re-scored here on a few controllers of each kind (a law on a
whole suite, MPC with its options, an agent, a robustness twin), each in seconds."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from experiments.benchmark.scoring import score
from experiments.benchmark import shipped as score_suites
from experiments.benchmark.run import shipped_controllers
from mrd_env.suites import suites

ROOT = Path(__file__).resolve().parents[2]
SCORES = ROOT / "docs" / "suites-scores.json"


@pytest.fixture(scope="module")
def stored() -> dict:
    return json.loads(SCORES.read_text(encoding="utf-8"))


def _entry(stored: dict, suite_id: str, name: str) -> dict:
    for c in stored["suites"][suite_id]["controllers"]:
        if c["name"] == name:
            return c
    raise AssertionError(f"{name} is not among the stored controllers of {suite_id}")


def test_the_stored_figures_are_of_the_shipped_suites_and_every_one_is_scored(stored):
    """Every shipped suite has its figures, of its current digest (a suite whose references changed is a new version:
    its old figures would be stale), and every candidate controller is either scored or listed with the reason."""
    shipped = suites()
    redo = "run python -m experiments.benchmark.shipped --suite {} --update-docs (a minute or two)"
    for sid in shipped:
        assert sid in stored["suites"], f"suite {sid} has no scores in {SCORES.name}: " + redo.format(sid)
    assert set(stored["suites"]) <= set(shipped), "scores of a suite no longer shipped: rerun the script"
    for sid, entry in stored["suites"].items():
        assert entry["digest"] == shipped[sid].digest, f"{sid}'s references changed: " + redo.format(sid)
        names = {c["name"] for c in entry["controllers"]} | {c["name"] for c in entry["not_applicable"]}
        assert names == {c["name"] for c in shipped_controllers(shipped[sid])}, sid
        assert entry["controllers"], sid


def test_the_docs_show_the_stored_figures(stored):
    """docs/suites.md holds the script's tables of the stored figures verbatim, the README its summary."""
    docs = (ROOT / "docs" / "suites.md").read_text(encoding="utf-8")
    assert score_suites.markdown(stored).strip() in docs
    assert score_suites.summary_table(stored).strip() in (ROOT / "README.md").read_text(encoding="utf-8")


def test_no_shipped_controller_scores_above_the_clairvoyant(stored):
    """Issue 51: R_c is the optimum of the suite's own action space, so no causal controller's return may exceed it
    on any episode of any suite — a share above 1 would mean a reference that is not an optimum (the stored shares
    are rounded to 4 decimals: 1e-4 of slack)."""
    above = [(sid, c["name"], label, share) for sid, entry in stored["suites"].items()
             for c in entry["controllers"] for label, share in c["episode_shares"].items()
             if share is not None and share > 1 + 1e-4]
    assert not above, f"controllers above the clairvoyant: {above}"


CASES = [  # (suite, controller row, episodes per scenario: None for all)
    ("car-comfort-v1", "skyhook_continuous", None),
    ("car-preview-v1", "mpc+preview (reward)", 1),
    ("car-comfort-robust-v1", "quarter_car_cmaes", 1),
    ("building-seismic-v1", "clipped_optimal_reward", None),
]


@pytest.mark.parametrize("suite_id, name, episodes", CASES)
def test_score_reproduces_the_stored_shares(stored, suite_id, name, episodes):
    c = _entry(stored, suite_id, name)
    controller = c["spec"] if c["kind"] == "law" else str(ROOT / c["spec"])
    result = score(suite_id, controller, name=name, options=c["options"], episodes=episodes)
    tol = stored["tolerance"]
    assert tol == 0.005
    got = {e["label"]: e["share"] for e in result.episodes}
    assert len(got) == (sum(len(sc.seeds[:episodes]) for sc in suites()[suite_id].scenarios))
    for label, share in got.items():
        assert share == pytest.approx(c["episode_shares"][label], abs=tol), label
    if episodes is None:   # the whole suite: the published means and intervals
        for scenario, (m, lo, hi) in c["shares"].items():
            mine = result.shares()[scenario]
            for a, b in zip(mine, (m, lo, hi)):
                assert (b is None and math.isnan(a)) or a == pytest.approx(b, abs=tol), scenario


def test_update_docs_rewrites_only_the_marked_blocks(stored, tmp_path):
    """``--update-docs`` puts the tables between the markers and leaves the rest; a file without them is refused."""
    for name, marker, _ in score_suites.DOC_BLOCKS:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(f"before\n<!-- {marker}: begin -->\nold table\n<!-- {marker}: end -->\nafter\n")
    score_suites.update_docs(stored, tmp_path)
    text = (tmp_path / "docs" / "suites.md").read_text()
    assert text.startswith("before\n") and text.endswith("\nafter\n") and "old table" not in text
    assert score_suites.markdown(stored).strip() in text
    score_suites.update_docs(stored, tmp_path)
    assert (tmp_path / "docs" / "suites.md").read_text() == text          # idempotent
    (tmp_path / "README.md").write_text("no markers\n")
    with pytest.raises(ValueError, match="needs one <!-- score_suites summary: begin -->"):
        score_suites.update_docs(stored, tmp_path)
