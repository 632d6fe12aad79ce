"""A controller's score over many episodes: the share of the pooled achievable gain, and two controllers compared on
the same episodes.

An episode's share (R − R_p) / (R_c − R_p) divides by its range R_c − R_p, which differs from episode to episode by
two orders of magnitude (a 5 cm bump: 0.05 to 0.09; a 1 s random road: about 1). The mean of the shares weighs every
episode alike, so an episode with little at stake — whose share is then large and noisy, −1.3 to −12 on the shipped
bumps — decides the mean. The **pooled share**

    Σ (R − R_p) / Σ (R_c − R_p)

is the share of the gain achievable on all the episodes together that the controller captures: each episode counts
by what is at stake on it. 0 is the best constant command on every episode, 1 the clairvoyant on every one.

Its 95 % interval is a percentile bootstrap (:data:`RESAMPLES` resamples from a ``numpy.random.Generator`` seeded
with :data:`SEED`: the same figures on every run): the episodes of each scenario are drawn with replacement within
the scenario (stratified — a resample keeps the suite's design, as many episodes of each scenario), a scenario's
interval from its own draws, the interval over all scenarios from every scenario's draws pooled. A scenario of one
episode has no interval (its draws are that episode, a fixed part of the pool); nor has the pool where every
scenario has one episode.

Two controllers a and b on the same episodes (:func:`paired_comparison`) differ by Σ (R_a − R_b) / Σ (R_c − R_p),
the difference of their pooled shares, with the interval of the same bootstrap — both controllers on the same
resampled episodes, so what every controller finds hard is not counted against either; and the episodes a wins
(R_a > R_b). The verdict (:func:`verdict`): ``ahead`` or ``behind`` where the interval excludes 0, ``tie`` where it
holds it.

Everything here reads episodes as the result files hold them (dicts with ``label``, ``scenario``, ``return`` and the
episode's references ``passive`` R_p and ``clairvoyant`` R_c); an episode without references, or whose range is not
positive (a share without a number), counts in no pooled figure.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: The row pooling every episode of the suite.
ALL = "all scenarios"
#: The bootstrap's resamples, and the seed of its generator (fixed: a leaderboard is the same on every run).
RESAMPLES = 2_000
SEED = 51
#: The intervals' confidence.
CONFIDENCE = 0.95
#: The most indices drawn at once (resamples × episodes of a scenario): bounds the memory a 5 000-episode scenario
#: takes (32 MiB of indices at a time), the draws being the same in chunks as in one piece.
_CHUNK = 4 * 1024 ** 2


class Estimate(NamedTuple):
    """A pooled figure over ``episodes`` episodes and its 95 % bootstrap interval [lo, hi] (NaN where there is none)."""

    value: float
    lo: float
    hi: float
    episodes: int


def references(episode: dict) -> tuple[float, float] | None:
    """(R_p, R_c) of an episode, or None where it holds none or its range R_c − R_p is not positive."""
    rp, rc = episode.get("passive"), episode.get("clairvoyant")
    if not isinstance(rp, (int, float)) or not isinstance(rc, (int, float)) or not rc - rp > 0:
        return None
    return float(rp), float(rc)


def pooled_shares(episodes: list[dict]) -> dict[str, Estimate]:
    """{scenario (in the order of ``episodes``) and :data:`ALL`: the pooled share Σ (R − R_p) / Σ (R_c − R_p) and its
    interval} (the module docstring)."""
    strata: dict[str, tuple[list[float], list[float]]] = {}
    for e in episodes:
        gained, at_stake = strata.setdefault(e["scenario"], ([], []))
        refs = references(e)
        if refs is not None and math.isfinite(e["return"]):
            gained.append(e["return"] - refs[0])
            at_stake.append(refs[1] - refs[0])
    return pooled(strata)


def paired_comparison(a, b, suite=None) -> list[dict]:
    """Result ``a`` against result ``b`` (:class:`~experiments.benchmark.scoring.SuiteResult`\\ s of one suite) on the
    episodes both scored, per scenario and over all (:data:`ALL`, last): ``episodes``, the ``difference`` of their
    pooled shares Σ (R_a − R_b) / Σ (R_c − R_p) with ``lo95`` and ``hi95``, ``won`` (the episodes where R_a > R_b)
    and the ``verdict``. The references are ``suite``'s (a :class:`mrd_env.suites.Suite`) where given, else those
    the episodes hold. ``ValueError`` for results of different suites."""
    if a.suite.get("digest") != b.suite.get("digest"):
        raise ValueError(f"{a.name} was scored on suite {a.suite.get('id')}, {b.name} on {b.suite.get('id')} "
                         "(another digest): a paired comparison needs the same episodes and references")
    theirs = {e["label"]: e["return"] for e in b.episodes}
    strata: dict[str, tuple[list[float], list[float]]] = {}
    won: dict[str, int] = {}
    for e in a.episodes:
        if e["label"] not in theirs:
            continue
        if suite is not None:
            ref = suite.references.get(e["label"])
            e = {**e, "passive": None if ref is None else ref.passive,
                 "clairvoyant": None if ref is None else ref.clairvoyant}
        refs, other = references(e), theirs[e["label"]]
        diff, at_stake = strata.setdefault(e["scenario"], ([], []))
        if refs is None or not (math.isfinite(e["return"]) and math.isfinite(other)):
            continue
        diff.append(e["return"] - other)
        at_stake.append(refs[1] - refs[0])
        won[e["scenario"]] = won.get(e["scenario"], 0) + int(e["return"] > other)
    won[ALL] = sum(won.values())
    out = []
    for s, est in pooled(strata).items():
        out.append({"scenario": s, "episodes": est.episodes, "difference": est.value, "lo95": est.lo,
                    "hi95": est.hi, "won": won.get(s, 0), "verdict": verdict(est.lo, est.hi)})
    return out


def verdict(lo: float, hi: float) -> str:
    """``ahead`` (the interval of a − b above 0), ``behind`` (below), ``tie`` (it holds 0), ``n/a`` (no interval)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return "n/a"
    return "ahead" if lo > 0 else "behind" if hi < 0 else "tie"


def pooled(strata: dict[str, tuple[list[float], list[float]]]) -> dict[str, Estimate]:
    """{stratum and :data:`ALL`: Σ x / Σ w and its stratified percentile-bootstrap interval}, for ``strata``
    {scenario: (x per episode, w per episode > 0)}. The generator is seeded anew on every call, and its draws go
    through the strata in order: two calls on strata of the same sizes resample the same episodes (what makes
    :func:`paired_comparison`'s interval a paired one)."""
    rng = np.random.default_rng(SEED)
    out: dict[str, Estimate] = {}
    total_x = np.zeros(RESAMPLES)
    total_w = np.zeros(RESAMPLES)
    resampled = n_all = 0
    for s, (x, w) in strata.items():
        x, w = np.asarray(x, dtype=float), np.asarray(w, dtype=float)
        n = x.size
        n_all += n
        if n == 0:
            out[s] = Estimate(math.nan, math.nan, math.nan, 0)
            continue
        value = float(x.sum() / w.sum())
        if n == 1:  # nothing to resample: the episode is a fixed part of every resample of the pool
            total_x += x[0]
            total_w += w[0]
            out[s] = Estimate(value, math.nan, math.nan, 1)
            continue
        sx, sw = np.empty(RESAMPLES), np.empty(RESAMPLES)
        step = max(1, _CHUNK // n)
        for start in range(0, RESAMPLES, step):
            idx = rng.integers(0, n, size=(min(step, RESAMPLES - start), n))
            sx[start:start + len(idx)] = x[idx].sum(axis=1)
            sw[start:start + len(idx)] = w[idx].sum(axis=1)
        total_x += sx
        total_w += sw
        resampled += 1
        out[s] = Estimate(value, *_percentiles(sx / sw), n)
    if n_all == 0:
        out[ALL] = Estimate(math.nan, math.nan, math.nan, 0)
    else:
        xs = sum(float(np.sum(x)) for x, _ in strata.values())
        ws = sum(float(np.sum(w)) for _, w in strata.values())
        bounds = _percentiles(total_x / total_w) if resampled else (math.nan, math.nan)
        out[ALL] = Estimate(xs / ws, *bounds, n_all)
    return out


def _percentiles(values: np.ndarray) -> tuple[float, float]:
    tail = 100 * (1 - CONFIDENCE) / 2
    lo, hi = np.percentile(values, [tail, 100 - tail])
    return float(lo), float(hi)
