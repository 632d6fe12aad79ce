"""A test gone wrong is excluded as a whole (issue 36): the faults of a run-away that never rejoins the test (force
spikes, the load cell saturated, speeds 20 times the record's median, then a creep out of the test's stroke range)
are one segment running to the end of the record, and a fit that excludes it matches a fit of the record with the
tail cut by hand. Synthetic records only."""
import re
import warnings

import numpy as np
import pytest

from mrd_env import make_damper
from mrd_env.dampers import CommandSpec
from mrd_env.identification import DamperRecord, FaultsExcluded, find_faults, fit_model
from mrd_env.identification import faults as faults_module
from mrd_env.identification import prepare
from mrd_env.identification.faults import fault_mask
from mrd_env.rig import simulate

DT = 2.5e-4
CMD = CommandSpec("V", 0.0, 2.25, eta=300.0)
FREE = ["fc_a", "fc_b", "c0a", "c0b"]


def _gone_wrong(seconds=3.0, tail=0.5):
    """A 2 Hz, 10 mm sine test, the command switched every 0.25 s, Bingham's force with 0.5 % noise; its last
    ``tail`` seconds: 0.4 s of run-away (speed ramping to 20 × the median within 50 ms, reversing every 0.1 s,
    force spikes in its first 0.1 s, the load cell ringing and saturated), then a creep out of the test's stroke
    range at a test's speed until the end. Returns (damper, record, first sample of the tail)."""
    d = make_damper("bingham", command=CMD)
    n = int(round(seconds / DT)) + 1
    t = np.arange(n) * DT
    w = 2 * np.pi * 2.0
    x, v = 0.01 * np.sin(w * t), 0.01 * w * np.cos(w * t)
    cmd = np.where((t // 0.25) % 2 == 0, 0.0, 2.25)
    k_a = n - int(round(tail / DT))
    tau = t[k_a:] - t[k_a]
    median = np.median(np.abs(v[:k_a]))
    ramp = np.minimum(1.0, tau / 0.05)
    v[k_a:] = 20 * median * ramp * np.tanh(np.sin(2 * np.pi * tau / 0.2) / 0.05)
    creep = tau >= tail - 0.1
    v[k_a:][creep] = 0.5 * median  # the last 0.1 s: slow, but the stroke leaves the test's range
    x[k_a:] = x[k_a - 1] + np.cumsum(v[k_a:]) * DT
    x[k_a:][creep] = 0.04 + np.cumsum(v[k_a:][creep]) * DT  # the actuator creeps 40 mm off the test's ±10 mm
    F = simulate(d, x, cmd, DT, v=v)[0].force
    rng = np.random.default_rng(0)
    F = F + 0.005 * np.std(F[:k_a]) * rng.standard_normal(n)
    peak = np.abs(F[:k_a]).max()
    F[k_a:] += 0.4 * peak * np.sin(2 * np.pi * 60 * tau)  # the load cell rings: no model's force
    F[k_a:] = np.clip(F[k_a:], -1.3 * peak, 1.3 * peak)  # and saturates
    for k in k_a + rng.choice(int(0.1 / DT), 8, replace=False):
        F[k] += 3 * peak * rng.choice([-1, 1])
    return d, DamperRecord(t, x, cmd, F, v, label="gone wrong"), k_a


def test_a_run_away_that_never_rejoins_the_test_is_one_segment_to_the_end():
    _, rec, k_a = _gone_wrong()
    pieces = find_faults(rec, merge_gap=0)  # as found: many pieces, the stretches between them left in
    kinds = {f.kind for f in pieces}
    assert len(pieces) >= 8 and {"spike", "saturation", "run-away"} <= kinds
    assert np.count_nonzero(~fault_mask(rec.n, pieces)[k_a:]) > 0.1 / DT  # the creep and gaps would be fitted
    found = find_faults(rec)
    assert len(found) == 1
    seg = found[0]
    assert seg.kind == "run-away" and seg.i1 == rec.n - 1 and k_a - 5 <= seg.i0 <= k_a + int(0.002 / DT)
    assert set(seg.parts) == set(pieces) and re.search(r"samples: \d+ spikes, 1 run-away, \d+ saturations\)$", str(seg))
    head = DamperRecord(rec.t[:k_a], rec.x[:k_a], rec.command[:k_a], rec.force[:k_a], rec.v[:k_a])
    assert find_faults(head) == []


def test_a_lone_fault_beside_the_test_stays_as_found_and_near_ones_merge():
    """A spike in the middle of a good test is left as it is; two saturations starting 50 ms apart are one segment
    (with the default 0.1 s), two 0.3 s apart stay two."""
    _, rec, k_a = _gone_wrong()
    F = rec.force[:k_a].copy()
    F[4000] += 40 * np.std(np.diff(F))
    head = DamperRecord(rec.t[:k_a], rec.x[:k_a], rec.command[:k_a], F, rec.v[:k_a])
    assert [(f.kind, f.i0, f.i1, f.parts) for f in find_faults(head)] == [("spike", 4000, 4000, ())]
    for gap, segments in ((0.05, 1), (0.3, 2)):
        G = F.copy()
        for k in (6000, 6000 + int(round(gap / DT))):
            G[k:k + 100] = F.max() * 1.1  # a load cell pinned for 25 ms
        r = DamperRecord(head.t, head.x, head.command, G, head.v)
        found = [f for f in find_faults(r) if f.kind != "spike"]
        assert len(found) == segments
        assert len(find_faults(r, merge_gap=0)) == 3  # the spike and both saturations
    with pytest.raises(ValueError, match="merge_gap"):
        find_faults(head, merge_gap=-0.1)


def test_excluding_the_segment_fits_as_the_tail_cut_by_hand(monkeypatch):
    """Bingham's four coefficients fitted (from 30 % off) on the whole record with its faults excluded: the E_t of
    the record with the tail cut by hand, within 0.1 % (of the force); with the pieces alone excluded, the
    stretches between them (a ringing load cell, a creep off the test) spoil the fit."""
    d, rec, k_a = _gone_wrong()
    start = {k: 1.3 * getattr(d.params, k) for k in FREE}
    search = {"progress": False, "maxiter": 60}
    head = DamperRecord(rec.t[:k_a], rec.x[:k_a], rec.command[:k_a], rec.force[:k_a], rec.v[:k_a])
    cut = fit_model(d, head, free=FREE, initial=start, search=search)
    with pytest.warns(FaultsExcluded, match=r"1 fault\(s\) found.*run-away.*: \d+ spikes, 1 run-away"):
        auto = fit_model(d, rec, free=FREE, initial=start, search=search)
    assert auto.overall["E_t"] == pytest.approx(cut.overall["E_t"], abs=1e-3)
    for k in FREE:
        assert auto.params[k] == pytest.approx(cut.params[k], rel=0.02)
    monkeypatch.setattr(prepare, "find_faults", lambda r: faults_module.find_faults(r, merge_gap=0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FaultsExcluded)
        pieces = fit_model(d, rec, free=FREE, initial=start, search=search)
    assert pieces.overall["E_t"] > 3 * cut.overall["E_t"]
