"""The pooled share and the paired verdicts (issue 51, items 3 and 4): Σ(R − R_p) / Σ(R_c − R_p) per scenario and
over all, with a stratified bootstrap interval reproducible bit for bit; an episode with little at stake no longer
decides the ranking; each ranked row against the next and against the best law on the same episodes; result files
of format 1 (no references stored) still read and rank.

The results here are built from references (no episode is run, except one short score): each episode's return is
R_p + f (R_c − R_p) for its share f."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from experiments.benchmark import aggregate
from experiments.benchmark.aggregate import ALL, paired_comparison, pooled_shares
from experiments.benchmark.ranking import leaderboard, read_result
from experiments.benchmark.scoring import SuiteResult
from mrd_env.suites import Reference, Suite, SuiteScenario, read_suite, suite, write_suite

CAR = "car-comfort-v1"
#: A road episode's range and a bump's: 1 against 0.01 (the shipped bumps: 0.046 to 0.089 against about 1).
ROAD, BUMP = 1.0, 0.01


@pytest.fixture
def bumpy(tmp_path) -> tuple[Suite, Path]:
    """A suite of four road episodes of range about 1 and one bump of range 0.01, written to a file."""
    scen = (SuiteScenario("road", {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}}, (1, 2, 3, 4)),
            SuiteScenario("bump", {"road": "bump", "road_params": {"height": 0.05, "speed": 5.0}}, (0,)))
    refs = {"road s1": Reference(-2.0, 0.0, -2.0 + ROAD), "road s2": Reference(-1.5, 0.0, -1.5 + 1.2 * ROAD),
            "road s3": Reference(-2.5, 0.0, -2.5 + 0.8 * ROAD), "road s4": Reference(-1.8, 0.0, -1.8 + ROAD),
            "bump": Reference(-0.3, 0.0, -0.3 + BUMP)}
    mine = Suite(name="bumpy-car", version=1, plant="quarter_car", env_id="mrd_env/QuarterCarPhysical-v0",
                 description="four roads and a bump", options={"episode_seconds": 0.2}, control_dt=0.01,
                 scenarios=scen, criteria=("acc_weighted_rms",), references=refs)
    path = write_suite(mine, tmp_path / "bumpy-car-v1.json")
    return read_suite(path), path


def result_data(s: Suite, name: str, shares: dict[str, float], *, version: int = 2, kind: str = "law") -> dict:
    """A result file's data on suite ``s``: each episode at its share in ``shares`` (format ``version``: 2 stores
    the references, 1 does not)."""
    eps = []
    for sc, seed in s.episodes():
        label = sc.label(seed)
        ref = s.reference(label)
        ret = ref.passive + shares[label] * (ref.clairvoyant - ref.passive)
        e = {"label": label, "scenario": sc.name, "seed": seed, "return": ret, "share": ref.share(ret),
             "criteria": {"acc_weighted_rms": 0.5}, "terminated": None}
        if version >= 2:
            e.update(passive=ref.passive, clairvoyant=ref.clairvoyant)
        eps.append(e)
    return {"format": "mrd-env-score", "format_version": version,
            "suite": {"id": s.id, "name": s.name, "version": s.version, "digest": s.digest, "plant": s.plant,
                      "episodes": len(s.labels())},
            "controller": {"name": name, "kind": kind, "spec": name}, "criteria": ["acc_weighted_rms"],
            "units": {"acc_weighted_rms": "m/s²"}, "episodes": eps, "created": "2026-12-01T00:00:00+00:00",
            "mrd_env_version": "0", "command": ["mrd-env", "score"]}


def write(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def as_result(data: dict) -> SuiteResult:
    return SuiteResult(suite=data["suite"], controller=data["controller"], episodes=data["episodes"],
                       criteria=data["criteria"], units=data["units"])


def test_the_pooled_share_is_the_share_of_the_pooled_gain(bumpy):
    """Per scenario and over all: Σ(R − R_p) / Σ(R_c − R_p), computed by hand from the references, in the summary
    that mrd-env score prints and writes, beside the mean of the shares."""
    s, _ = bumpy
    shares = {"road s1": 0.5, "road s2": 0.1, "road s3": -0.4, "road s4": 0.9, "bump": -6.0}
    r = as_result(result_data(s, "a", shares))
    refs = {lab: s.reference(lab) for lab in s.labels()}
    gained = {lab: (ref.passive + shares[lab] * (ref.clairvoyant - ref.passive)) - ref.passive
              for lab, ref in refs.items()}
    at_stake = {lab: ref.clairvoyant - ref.passive for lab, ref in refs.items()}
    roads = [f"road s{i}" for i in range(1, 5)]
    rows = {row["scenario"]: row for row in r.summary()}
    assert rows["road"]["pooled share"] == pytest.approx(sum(gained[k] for k in roads) / sum(at_stake[k] for k in roads))
    assert rows["bump"]["pooled share"] == pytest.approx(-6.0)
    assert rows[ALL]["pooled share"] == pytest.approx(sum(gained.values()) / sum(at_stake.values()))
    assert rows[ALL]["share"] == pytest.approx(np.mean(list(shares.values())))   # the mean share stays, second
    assert r.pooled_shares()[ALL][0] == rows[ALL]["pooled share"]
    assert math.isnan(rows["bump"]["pooled share lo95"]), "one episode: no interval"
    assert rows["road"]["pooled share lo95"] < rows["road"]["pooled share"] < rows["road"]["pooled share hi95"]
    md = r.markdown()
    assert "| pooled share |" in md and "| mean share |" in md and "| -6.000 |" in md   # one episode: the value alone
    header = md.splitlines()[2]
    assert header.index("pooled share") < header.index("mean share"), "the pooled share is the primary figure"


def test_an_episode_with_little_at_stake_no_longer_decides_the_ranking(bumpy):
    """a captures 30 % of every road's gain and loses 10 bump ranges (0.1, a tenth of one road's range); b captures
    20 % of every road and nothing on the bump. The mean share ranks b first (0.16 against −1.76), driven by the
    bump alone; the pooled share ranks a first, as its road episodes say."""
    s, path = bumpy
    roads = [lab for lab in s.labels() if lab.startswith("road")]
    a = write(path.parent / "a.json", result_data(s, "a", {**{k: 0.3 for k in roads}, "bump": -10.0}))
    b = write(path.parent / "b.json", result_data(s, "b", {**{k: 0.2 for k in roads}, "bump": 0.0}))
    board = leaderboard([b, a], suite=path)
    mean = {r.name: r.shares()[ALL][0] for r in board.results}
    assert mean["b"] > 0 > mean["a"], "the mean share is driven by the bump"
    assert [r["controller"] for r in board.table] == ["a", "b"]
    pooled = {r.name: r.pooled_shares()[ALL][0] for r in board.results}
    at_stake = sum(s.reference(k).clairvoyant - s.reference(k).passive for k in s.labels())
    road_stake = at_stake - BUMP
    assert pooled["a"] == pytest.approx((0.3 * road_stake - 10 * BUMP) / at_stake)
    assert pooled["b"] == pytest.approx(0.2 * road_stake / at_stake)
    assert board.table[0][ALL].startswith(f"{pooled['a']:.3f}") and board.table[0]["mean share"].startswith(
        f"{mean['a']:.3f}")
    (v,) = [v for v in board.verdicts if v["which"] == "next"]
    assert (v["controller"], v["against"], v["episodes won"], v["verdict"]) == ("a", "b", "4/5", "ahead")


def test_the_bootstrap_is_reproducible_and_holds_its_estimate(bumpy, monkeypatch):
    """The same interval bit for bit on every call (a seeded generator); it holds the point estimate; another seed
    gives another interval (the draws are random, not a fixed rule)."""
    s, _ = bumpy
    rng = np.random.default_rng(7)
    shares = {lab: float(x) for lab, x in zip(s.labels(), rng.normal(0.3, 0.4, len(s.labels())))}
    eps = result_data(s, "a", shares)["episodes"]
    first, again = pooled_shares(eps), pooled_shares(eps)
    assert first == again
    for est in (first["road"], first[ALL]):
        assert est.lo < est.value < est.hi
    monkeypatch.setattr(aggregate, "SEED", aggregate.SEED + 1)
    other = pooled_shares(eps)
    assert other[ALL].value == first[ALL].value and (other[ALL].lo, other[ALL].hi) != (first[ALL].lo, first[ALL].hi)


def test_the_pooled_interval_resamples_within_each_scenario():
    """Stratified: a scenario whose episodes all capture the same share has a zero-width interval, whichever of its
    episodes a resample draws, and so has the pool of two such scenarios of the same share; every scenario of one
    episode: no interval, for the pool either."""
    eps = [{"label": f"{s}{i}", "scenario": s, "return": -1.0 + 0.25 * w, "passive": -1.0, "clairvoyant": -1.0 + w}
           for s in "AB" for i, w in enumerate((0.5, 1.0, 2.0))]
    out = pooled_shares(eps)
    assert out["A"] == (0.25, 0.25, 0.25, 3) and out[ALL].lo == pytest.approx(0.25) == pytest.approx(out[ALL].hi)
    single = pooled_shares([eps[0], eps[3]])
    assert single[ALL].value == pytest.approx(0.25) and math.isnan(single[ALL].lo) and math.isnan(single[ALL].hi)


def test_a_paired_verdict_is_a_tie_for_noise_and_ahead_for_a_controller_better_everywhere():
    """Two controllers whose returns differ by symmetric noise only: a tie; one better by a little on every episode:
    ahead (and the other behind), winning every episode, however much the episodes differ from one another."""
    rng = np.random.default_rng(3)
    n = 30
    at_stake = rng.uniform(0.5, 1.5, n)
    base = -2.0 + at_stake * rng.uniform(-0.5, 0.8, n)
    noise = rng.normal(0.0, 0.01, n)
    noise -= noise.mean()

    def result(name, returns):
        eps = [{"label": f"s{i}", "scenario": "road" if i % 2 else "other road", "seed": i, "return": float(r),
                "share": math.nan, "passive": -2.0, "clairvoyant": -2.0 + float(w), "criteria": {},
                "terminated": None} for i, (r, w) in enumerate(zip(returns, at_stake))]
        return SuiteResult(suite={"id": "x-v1", "digest": "0" * 64, "episodes": n}, controller={"name": name},
                           episodes=eps, criteria=[])

    same = paired_comparison(result("a", base + noise), result("b", base - noise))
    assert same[-1]["scenario"] == ALL and same[-1]["verdict"] == "tie"
    assert same[-1]["lo95"] < 0 < same[-1]["hi95"]
    better = paired_comparison(result("a", base + 0.02 * at_stake), result("b", base))
    assert [r["verdict"] for r in better] == ["ahead", "ahead", "ahead"]
    assert better[-1]["won"] == n and better[-1]["difference"] == pytest.approx(0.02)
    worse = paired_comparison(result("b", base), result("a", base + 0.02 * at_stake))
    assert worse[-1]["verdict"] == "behind" and worse[-1]["won"] == 0
    assert (worse[-1]["lo95"], worse[-1]["hi95"]) == pytest.approx((-better[-1]["hi95"], -better[-1]["lo95"]))


def test_each_row_is_compared_with_the_next_and_with_the_best_law(tmp_path):
    """Four results of the shipped car suite: agent > law > law > agent. The agent on top is compared with the next
    (the best law, once), the second law with the next and with the best law, the last agent with the law above it
    and with the best law; the table's column says each row's verdict against the next."""
    s = suite(CAR)
    labels = s.labels()
    spread = {lab: 0.05 * ((i % 5) - 2) for i, lab in enumerate(labels)}
    files = [write(tmp_path / f"{name}.json", result_data(s, name, {k: f + v for k, v in spread.items()}, kind=kind))
             for name, f, kind in (("law low", 0.10, "law"), ("agent top", 0.40, "agent"),
                                   ("agent low", 0.05, "agent"), ("law top", 0.30, "law"))]
    board = leaderboard(files)
    assert [r["controller"] for r in board.table] == ["agent top", "law top", "law low", "agent low"]
    pairs = [(v["controller"], v["against"], v["which"], v["verdict"]) for v in board.verdicts]
    assert pairs == [("agent top", "law top", "next, best law", "ahead"),
                     ("law top", "law low", "next", "ahead"),
                     ("law low", "agent low", "next", "ahead"), ("law low", "law top", "best law", "behind"),
                     ("agent low", "law top", "best law", "behind")]
    assert [r["against the next"] for r in board.table] == ["ahead", "ahead", "ahead", ""]
    md = board.markdown()
    assert "| next, best law |" in md and "| best law |" in md


def test_result_files_of_format_1_still_read_and_rank(tmp_path, bumpy):
    """A format-1 file stores no references: on a shipped suite, or with the suite given, they come from the suite
    and its pooled share is the same as a format-2 file's; merged unchecked, it has none (n/a), and is ranked by its
    mean share after any result that has one."""
    s = suite(CAR)
    shares = {lab: 0.1 + 0.01 * i for i, lab in enumerate(s.labels())}
    old = write(tmp_path / "old.json", result_data(s, "old", shares, version=1))
    new = write(tmp_path / "new.json", result_data(s, "new", {k: v + 0.01 for k, v in shares.items()}))
    assert "passive" not in read_result(old).episodes[0]
    board = leaderboard([old, new])
    assert [r["controller"] for r in board.table] == ["new", "old"]
    got = {r.name: r.pooled_shares()[ALL][0] for r in board.results}
    v2 = as_result(result_data(s, "old", shares))
    assert got["old"] == pytest.approx(v2.pooled_shares()[ALL][0]) and math.isfinite(got["old"])

    mine, _ = bumpy   # a suite that is not shipped, merged without it: the file's own references, or none
    unchecked = [write(tmp_path / "u1.json", result_data(mine, "v1 file", {k: 0.5 for k in mine.labels()}, version=1)),
                 write(tmp_path / "u2.json", result_data(mine, "v2 file", {k: 0.2 for k in mine.labels()}))]
    board = leaderboard(unchecked)
    assert not board.checked and [r["controller"] for r in board.table] == ["v2 file", "v1 file"]
    assert board.table[1][ALL] == "n/a" and board.table[0][ALL].startswith("0.200")


def test_a_stored_reference_edited_by_hand_is_refused(tmp_path):
    """Format 2 stores each episode's R_p and R_c; they are checked against the suite's like the share."""
    s = suite(CAR)
    data = result_data(s, "a", {k: 0.2 for k in s.labels()})
    data["episodes"][3]["clairvoyant"] += 0.5
    with pytest.raises(ValueError, match=r"a\.json: episode .*reference clairvoyant"):
        leaderboard([write(tmp_path / "a.json", data)])
    del data["episodes"][3]["clairvoyant"]
    with pytest.raises(ValueError, match="must give its references"):
        read_result(write(tmp_path / "a.json", data))


def test_score_stores_the_references_it_scored_against():
    """The result of a score holds each episode's references (format 2) and its summary's pooled share."""
    from experiments.benchmark.scoring import FORMAT_VERSION, score

    s = suite(CAR)
    r = score(s, "skyhook_continuous", episodes=1, backend="serial")
    assert FORMAT_VERSION == 2 and r.to_json()["format_version"] == 2
    for e in r.episodes:
        ref = s.reference(e["label"])
        assert (e["passive"], e["clairvoyant"]) == (ref.passive, ref.clairvoyant)
    row = r.to_json()["summary"][-1]
    assert row["scenario"] == ALL and row["pooled share"] == pytest.approx(
        sum(e["return"] - e["passive"] for e in r.episodes) / sum(e["clairvoyant"] - e["passive"] for e in r.episodes))


def test_scores_summary_against_a_reference_controller(bumpy):
    """What mrd-env score prints when a reference controller is given: per scenario and over all, the paired
    difference, the episodes won and the verdict, with the suite's references; results of another suite refused."""
    s, _ = bumpy
    roads = [lab for lab in s.labels() if lab.startswith("road")]
    mine = as_result(result_data(s, "mine", {**{k: 0.3 + 0.01 * i for i, k in enumerate(roads)}, "bump": 0.1},
                                 version=1))
    ref = as_result(result_data(s, "ref", {k: 0.1 for k in s.labels()}, version=1))
    rows = paired_comparison(mine, ref, s)
    assert [(r["scenario"], r["episodes"], r["won"], r["verdict"]) for r in rows] == [
        ("road", 4, 4, "ahead"), ("bump", 1, 0, "n/a"), (ALL, 5, 4, "ahead")]
    assert math.isnan(paired_comparison(mine, ref)[-1]["difference"]), "format 1, no suite: no references"
    md = mine.paired_markdown(ref, s)
    assert md.splitlines()[0].startswith("### mine against ref on bumpy-car-v1") and "| all scenarios | 5 |" in md
    other = as_result({**result_data(s, "other", {k: 0.1 for k in s.labels()}),
                       "suite": {**ref.suite, "id": "other-v1", "digest": "1" * 64}})
    with pytest.raises(ValueError, match="same episodes and references"):
        paired_comparison(mine, other)
