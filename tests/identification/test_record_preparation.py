"""Identification on imperfect records: command dynamics, channel offsets, faults, the neural forward model and
cross-record validation — all on synthetic rig records whose truth is known (the real record is never read)."""
import argparse
import csv

import numpy as np
import pytest

from mrd_env import make_damper
from mrd_env.dampers import CommandSpec
from mrd_env.identification import DamperRecord, FaultsExcluded, find_faults, fit_model, predict
from mrd_env.identification.align import best_offset
from mrd_env.identification.compare import compare_models
from mrd_env.identification.prepare import prepare_record
from mrd_env.identification.presets import load_preset, save_preset
from mrd_env.rig import random_test

QUIET = {"progress": False}
LAG = CommandSpec("V", 0.0, 2.25, eta=300.0, eta_fall=125.0, delay=6.0e-4)
DT = 2.5e-4


def _record(model="bingham", command=LAG, duration=1.5, rng=4, noise=0.0, switch_rate=8.0):
    d = make_damper(model, command=command)
    r = random_test(d, rms=0.004, bandwidth=8.0, duration=duration, switch_rate=switch_rate, dt=DT, rng=rng)
    F = r.force + noise * np.std(r.force) * np.random.default_rng(rng).standard_normal(r.force.size)
    return d, DamperRecord(r.t, r.x, r.command, F, r.v, label="synthetic")


def _shifted(rec, s):
    """The record with the force channel lagging the motion by s samples: sample j holds the motion of time j + s
    and the force of time j."""
    n = rec.n - s
    return DamperRecord(rec.t[:n], rec.x[s:], rec.command[s:], rec.force[:n], rec.v[s:], label=rec.label)


def test_asymmetric_lag_and_delay_are_recovered():
    """A Bingham damper (force affine in u) behind a 3.3 ms rise / 8 ms fall lag and a 0.6 ms delay: the fit
    starts from a symmetric 190 1/s lag without delay and finds all three."""
    truth, rec = _record()
    res = fit_model("bingham", rec, free=["command_eta", "command_eta_fall", "command_delay"],
                    initial={"command_eta": 190.0, "command_eta_fall": 190.0}, search=QUIET)
    c = res.damper.command
    assert c.eta == pytest.approx(300.0, rel=1e-3) and c.eta_fall == pytest.approx(125.0, rel=1e-3)
    assert c.delay == pytest.approx(6.0e-4, rel=1e-2)
    assert res.overall["E_t"] < 1e-3


def test_channel_offset_is_estimated_and_corrected():
    d, rec = _record(noise=0.01)
    moved = _shifted(rec, 2)
    for s, r in ((2, moved), (0, rec)):  # the true model's force finds the offset
        prep = prepare_record(r, d.command)
        assert best_offset(predict(d, prep)[1], prep) == s
    free = ["fc_a", "fc_b", "c0a", "c0b"]
    start = {k: 1.3 * getattr(d.params, k) for k in free}
    aligned = fit_model(d, moved, free=free, initial=start, search=QUIET, data={"align": True})
    plain = fit_model(d, moved, free=free, initial=start, search=QUIET)
    assert aligned.settings["offsets"] == [2] and aligned.records[0]["offset_samples"] == 2
    assert aligned.overall["E_t"] < 0.02 < plain.overall["E_t"]  # at the 1 % noise floor once aligned
    for k in free:
        assert aligned.params[k] == pytest.approx(getattr(d.params, k), rel=0.02)


def test_each_records_held_back_part_is_scored_with_its_own_offset():
    """Two records whose force channels lag by 0 and 3 samples, fitted with alignment: the held-back part of each
    is scored with the offset found for it (record 0's offset applied to both would misalign the second)."""
    from mrd_env.identification.compare import split_records, validate, validation_offsets

    d, rec = _record(noise=0.01)
    _, other = _record(noise=0.01, rng=7)
    whole, fits, idx = split_records([rec, _shifted(other, 3)], 0.6)
    free = ["fc_a", "fc_b", "c0a", "c0b"]
    fr = fit_model(d, fits, free=free, search=QUIET, data={"align": True})
    assert fr.settings["offsets"] == [0, 3]
    assert validation_offsets(fr, whole, idx) == [0, 3]
    rows, _, _, _ = validate(fr.damper, whole, idx, offset=validation_offsets(fr, whole, idx))
    alone = validate(fr.damper, whole[1:], idx[1:], offset=3)[0][0]
    assert rows[1]["E_t"] == alone["E_t"] < 0.02 < validate(fr.damper, whole[1:], idx[1:], offset=0)[0][0]["E_t"]
    with pytest.raises(ValueError, match="force offsets differ"):
        validation_offsets(fr, whole, [0, 0])  # other records to score: which offset is theirs?


def test_offset_of_a_hysteretic_model_is_fitted_exactly():
    """Spencer–Dyke's force lags its velocity by itself (pre-yield stiffness); the offset the fitted model
    prefers is the imposed one."""
    d, rec = _record("spencer_dyke", command=None, duration=1.0, noise=0.005)
    moved = _shifted(rec, 3)
    res = fit_model(d, moved, free=["c0a", "alpha_b"], initial={"c0a": 1.2 * d.params.c0a}, search=QUIET,
                    data={"align": True})
    assert res.settings["offsets"] == [3]


def test_injected_saturation_and_spike_are_detected_and_excluded():
    d, rec = _record(noise=0.005)
    F = rec.force.copy()
    v = rec.v.copy()
    limit = 0.8 * F.max()
    F = np.minimum(F, limit)  # the load cell clips
    sat = np.flatnonzero(F == limit)
    k = 3001
    v[k] += 40 * np.std(np.diff(v))  # one velocity sample spikes
    bad = DamperRecord(rec.t, rec.x, rec.command, F, v, label="faulty")
    pieces = find_faults(bad, merge_gap=0)  # as found, before faults close together are joined
    assert [p for f in find_faults(bad) for p in (f.parts or (f,))] == pieces
    kinds = {(f.kind, f.channel) for f in pieces}
    assert ("saturation", "force") in kinds and ("spike", "v") in kinds
    assert len(pieces) >= 2 and not any(f.channel in ("x", "command") for f in pieces)
    spike = next(f for f in pieces if f.kind == "spike")
    assert spike.i0 == spike.i1 == k and spike.start == rec.t[k]
    covered = {i for f in pieces if f.kind == "saturation" for i in range(f.i0, f.i1 + 1)}
    assert covered == set(sat)  # every clipped sample, and nothing else
    assert find_faults(rec) == []  # the clean record has none
    free = ["fc_a", "fc_b", "c0a", "c0b"]
    start = {k: 1.3 * getattr(d.params, k) for k in free}
    with pytest.warns(FaultsExcluded, match=r"fault\(s\) found and excluded.*saturation of force"):
        res = fit_model(d, bad, free=free, initial=start, search=QUIET)
    assert res.records[0]["samples_scored"] < rec.n - len(sat)
    kept = fit_model(d, bad, free=free, initial=start, search=QUIET, data={"faults": "keep"})
    for k_ in free:
        assert res.params[k_] == pytest.approx(getattr(d.params, k_), rel=0.01)
    assert max(abs(kept.params[k_] / getattr(d.params, k_) - 1) for k_ in free) > 0.2
    with pytest.raises(ValueError, match="has faults: .*spike of v"):
        prepare_record(bad, d.command, faults="raise")


def test_gap_in_the_time_column_is_a_fault():
    _, rec = _record(duration=0.5)
    t = rec.t.copy()
    t[1000:] += 0.01
    faults = find_faults(DamperRecord(t, rec.x, rec.command, rec.force, rec.v))
    assert [(f.kind, f.channel, f.i0, f.i1) for f in faults] == [("gap", "t", 999, 1000)]


def test_neural_forward_model_fits_predicts_and_reloads_exactly(tmp_path):
    d, rec = _record("spencer_dyke", command=None, duration=2.0, noise=0.005)
    fit, held = rec.split(0.7)
    res = fit_model("neural", fit, search={"maxiter": 25, "progress": False, "seed": 1})
    assert res.model == "neural" and res.method == "adam" and res.n_free > 1000
    assert res.overall["E_t"] < 0.15
    prep, F = predict(res.damper, held)
    assert F.shape == (held.n,) and np.all(np.isfinite(F))
    again = fit_model("neural", fit, search={"maxiter": 25, "progress": False, "seed": 1})
    assert np.array_equal(again.damper.predict_prepared(prep), F)  # bit-reproducible training
    path = save_preset(res, tmp_path / "neural.json")
    loaded = load_preset(path)
    assert np.array_equal(predict(loaded, held)[1], F)
    with pytest.raises(ValueError, match="takes no preset"):
        fit_model("neural", fit, free=["c0a"])
    with pytest.raises(ValueError, match="cannot find the force offset itself"):
        fit_model("neural", fit, data={"align": True})
    shifted = fit_model("neural", _shifted(fit, 1), search={"maxiter": 2, "progress": False}, data={"offset": 1})
    assert shifted.settings["offsets"] == [1]


def test_cross_record_validation_table(tmp_path):
    d, a = _record(duration=1.0, rng=1)
    _, b = _record(duration=1.0, rng=2)
    res = compare_models([a], ["bingham"], search={"maxiter": 20, "progress": False}, validation_records=[b],
                         out=tmp_path)
    m = res.by_model("bingham")
    assert res.cross_record and m.validation[0]["n"] == b.n  # scored on the whole other record
    row = res.rows[0]
    assert row["fit E_t %"] < 100 and row["E_t %"] < 100
    assert "validation" in (tmp_path / "comparison.md").read_text()


def test_identify_cli_validate_and_align(tmp_path, capsys):
    from experiments.commands import identify
    d, a = _record(duration=1.0, rng=1)
    _, b = _record(duration=1.0, rng=2)
    pa, pb = a.to_csv(tmp_path / "a.csv"), b.to_csv(tmp_path / "b.csv")
    p = argparse.ArgumentParser()
    identify.add_arguments(p)
    out = tmp_path / "out"
    args = p.parse_args(["--data", str(pa), "--validate", str(pb), "--model", "bingham", "--fit-lag", "--align",
                         "--maxiter", "30", "--no-progress", "--out", str(out)])
    assert identify.run(args) == 0
    with (out / "bingham_identify.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["part"] for r in rows] == ["fit", "validation (other record)"]
    assert int(rows[1]["samples"]) == b.n
    with (out / "bingham_params.csv").open() as fh:
        names = [r["parameter"] for r in csv.DictReader(fh)]
    assert {"command_eta", "command_eta_fall", "command_delay"} <= set(names)
    assert "force offset [0] samples" in capsys.readouterr().out


def test_identify_cli_gives_the_neural_model_its_force_offset(tmp_path, capsys):
    """--force-offset SAMPLES imposes the offset on the neural model; auto has a Spencer–Dyke fit find it first
    (the network cannot) and says so; a value that is not whole samples is refused in one line naming the option."""
    from experiments.cli import main
    _, rec = _record("spencer_dyke", command=None, duration=0.5, noise=0.005)
    path = _shifted(rec, 3).to_csv(tmp_path / "shifted.csv")
    base = ["identify", "--data", str(path), "--model", "neural", "--maxiter", "2", "--no-progress"]
    assert main(base + ["--force-offset", "3", "--out", str(tmp_path / "given")]) == 0
    out = capsys.readouterr().out
    assert "force offset [3] samples" in out and "spencer_dyke fit" not in out
    assert main(base + ["--force-offset", "auto", "--out", str(tmp_path / "auto")]) == 0
    out = capsys.readouterr().out
    assert "note: force offset 3 samples, found by the spencer_dyke fit" in out and "force offset [3] samples" in out
    for bad in ("12.5", "one"):
        assert main(base + ["--force-offset", bad]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"--force-offset {bad!r} is invalid: give a whole number of samples" in err
    assert main(["identify", "--help"]) == 0
    assert "--force-offset SAMPLES|auto" in capsys.readouterr().out


def test_neural_model_takes_records_of_one_rate_whose_time_stamps_round_differently():
    """Two tests at 3004.8 Hz with time stamps written to 0.1 µs (as the NEES export does) have mean intervals that
    differ in the 10th digit: one rate. A record at another rate is refused, naming both rates."""
    fs = 3004.8
    d = make_damper("bingham")
    recs = []
    for rng, duration in ((1, 0.6), (2, 0.8)):
        r = random_test(d, rms=0.004, bandwidth=8.0, duration=duration, switch_rate=8.0, dt=1 / fs, rng=rng)
        recs.append(DamperRecord(np.round(r.t, 7), r.x, r.command, r.force, r.v, label=f"test {rng}"))
    assert recs[0].dt != recs[1].dt
    res = fit_model("neural", recs, search={"maxiter": 2, "progress": False})
    assert [r["label"] for r in res.records] == ["test 1", "test 2"]
    r = random_test(d, rms=0.004, bandwidth=8.0, duration=0.6, switch_rate=8.0, dt=1e-3, rng=3)
    slow = DamperRecord(r.t, r.x, r.command, r.force, r.v, label="slow")
    with pytest.raises(ValueError, match=r"one sampling rate: 'test 1' is sampled at 3004.8 Hz .*'slow' at 1000 Hz"):
        fit_model("neural", [recs[0], slow], search={"maxiter": 2, "progress": False})
    with pytest.raises(ValueError, match=r"trained at 3004.8 Hz .*'slow' is sampled at 1000 Hz"):
        predict(res.damper, slow)


def test_a_run_away_is_excluded_as_a_whole_not_only_where_the_force_clips():
    """The last 0.6 s of a test: the actuator runs away at ±0.9 m/s (more than twice the test's peak speed), switched
    off for 0.1 s, then on, so that the load cell is pinned at its limit for the last 0.5 s (but at the reversals).
    The whole segment, from the first run-away sample to the end, is one fault, left out of the fit and the errors
    and reported — not only its clipped samples, which would leave the first 0.1 s and every reversal in."""
    from mrd_env.rig import simulate
    d, rec = _record(noise=0.0, duration=3.0)
    k_a = rec.n - int(round(0.6 / DT))
    tau = rec.t[k_a:] - rec.t[k_a]
    v = rec.v.copy()
    v[k_a:] = 0.9 * np.tanh(np.sin(2 * np.pi * tau / 0.3) / 0.05)  # ±0.9 m/s, reversing every 0.15 s
    x = rec.x.copy()
    x[k_a:] = x[k_a - 1] + np.cumsum(v[k_a:]) * DT
    cmd = rec.command.copy()
    cmd[k_a:] = np.where(tau < 0.1, 0.0, LAG.v_max)
    F = simulate(d, x, cmd, DT, v=v)[0].force
    limit = 1.05 * np.abs(F[k_a:k_a + int(0.1 / DT)]).max()
    assert limit > np.abs(F[:k_a]).max()  # the test itself never reaches the load cell's limit
    F = np.clip(F + 0.005 * np.std(F[:k_a]) * np.random.default_rng(0).standard_normal(rec.n), -limit, limit)
    bad = DamperRecord(rec.t, x, cmd, F, v, label="run-away")
    assert np.count_nonzero(np.abs(F) == limit) < 0.5 / DT  # the clipped samples: not the whole segment
    run = [f for f in find_faults(bad) if f.kind == "run-away"]
    assert len(run) == 1 and run[0].i1 == rec.n - 1 and k_a <= run[0].i0 <= k_a + int(round(0.002 / DT))
    assert find_faults(DamperRecord(rec.t[:k_a], x[:k_a], cmd[:k_a], F[:k_a], v[:k_a])) == []
    with pytest.warns(FaultsExcluded, match=r"run-away \(speed far beyond the test's, with a saturated channel\) "
                                            r"at t = 2\.4"):
        prep = prepare_record(bad, d.command)
    first = run[0].i0 - int(round(0.005 / DT))  # the fault margin (its edge sample: by time, either way)
    assert not prep.mask[first + 1:].any() and prep.mask[:first - 1].all()
    free = ["fc_a", "fc_b", "c0a", "c0b"]
    with pytest.warns(FaultsExcluded, match=r"\(2\d\d\d of 12001 samples"):
        res = fit_model(d, bad, free=free, initial={k: 1.3 * getattr(d.params, k) for k in free}, search=QUIET)
    assert res.records[0]["samples_scored"] == np.count_nonzero(prep.mask)
    for k in free:
        assert res.params[k] == pytest.approx(getattr(d.params, k), rel=0.01)


def test_compare_models_gives_the_neural_model_the_reference_offset(tmp_path, capsys):
    """compare-models --force-offset auto: the parametric models find their own offset, the neural model gets the
    one a Spencer–Dyke reference fit finds on the same fit part."""
    from experiments.cli import main
    _, rec = _record("spencer_dyke", command=None, duration=0.5, noise=0.005)
    path = _shifted(rec, 3).to_csv(tmp_path / "shifted.csv")
    assert main(["compare-models", "--data", str(path), "--models", "spencer_dyke", "neural", "--force-offset",
                 "auto", "--maxiter", "3", "--no-progress", "--out", str(tmp_path / "out")]) == 0
    assert "note: force offset 3 samples, found by the spencer_dyke fit" in capsys.readouterr().out
    with (tmp_path / "out" / "comparison.csv").open() as fh:
        offsets = {r["model"]: r["offset samples"] for r in csv.DictReader(fh)}
    assert offsets["neural"] == "3"
