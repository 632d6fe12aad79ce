"""``mrd-env inverse``: the tracking tables and figures it writes, on short runs (the full tables of the README
come from the same commands with their defaults)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from experiments.cli import main
from mrd_env import make_damper
from mrd_env.identification import DamperRecord
from mrd_env.identification import save_preset
from mrd_env.identification.presets import read_preset
from mrd_env.inverse import achievable_forces


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_achievable_writes_the_table_and_figures(tmp_path, capsys):
    code = main(["inverse", "achievable", "--plants", "bouc_wen", "--inverses", "heaviside", "model",
                 "--mismatch", "--duration", "0.6", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    rows = {r["inverse"]: r for r in _rows(tmp_path / "achievable.csv")}
    assert set(rows) == {"heaviside", "model"} and float(rows["model"]["NRMSE %"]) < 2.0
    assert (tmp_path / "achievable_bouc_wen_on_bouc_wen.png").stat().st_size > 10_000


def test_record_tracks_a_measured_force_with_a_given_plant(tmp_path, capsys):
    """A record made by the preset itself, the plant given as that preset: the model inverse reproduces the
    measured force nearly exactly, the replayed command exactly up to the start from rest."""
    d = make_damper("bouc_wen")
    r = achievable_forces(d, duration=1.0, rng=0)
    path = DamperRecord(r.t, r.x, r.command, r.force, r.v).to_csv(tmp_path / "rec.csv")
    preset = save_preset(d, tmp_path / "plant.json")
    code = main(["inverse", "record", "--data", str(path), "--plant-preset", str(preset), "--fs", "1000",
                 "--inverses", "heaviside", "sid", "model", "--out", str(tmp_path / "out")])
    assert code == 0, capsys.readouterr().err
    rows = {r["inverse"]: r for r in _rows(tmp_path / "out" / "record_tracking.csv")}
    assert set(rows) == {"measured command", "heaviside", "sid", "model"}
    assert float(rows["model"]["E_t %"]) < 2.0 and float(rows["measured command"]["E_t %"]) < 2.0
    assert (tmp_path / "out" / "record_tracking.png").is_file()


def test_record_tracks_the_force_as_the_plant_was_fitted_to_it(tmp_path, capsys):
    """The tracking target is the measured force moved by the force offset (the one the plant was fitted with),
    and a clipped span of the load cell is left out of the scores: the replayed command then tracks it as well as
    on a clean record."""
    d = make_damper("bouc_wen")
    r = achievable_forces(d, duration=1.0, rng=0)
    s = 2  # the force channel lags the motion by 2 samples
    f = r.force[:-s].copy()
    f[850:900] = f.max()  # and the load cell clips in the held-back part
    path = DamperRecord(r.t[:-s], r.x[s:], r.command[s:], f, r.v[s:]).to_csv(tmp_path / "rec.csv")
    preset = save_preset(d, tmp_path / "plant.json")
    e_t = {}
    for offset in ("0", str(s)):
        out = tmp_path / f"out{offset}"
        code = main(["inverse", "record", "--data", str(path), "--plant-preset", str(preset), "--fs", "1000",
                     "--inverses", "heaviside", "--force-offset", offset, "--out", str(out)])
        assert code == 0, capsys.readouterr().err
        e_t[offset] = float({r["inverse"]: r for r in _rows(out / "record_tracking.csv")}["measured command"]["E_t %"])
    assert e_t[str(s)] < 2.0 < e_t["0"]


def test_train_writes_a_network_that_reproduces_itself(tmp_path, capsys):
    pytest.importorskip("torch")
    from mrd_env.inverse.neural import load_network

    out = tmp_path / "net.npz"
    argv = ["inverse", "train", "--model", "bouc_wen", "--records", "2", "--duration", "0.4", "--epochs", "1",
            "--hidden", "8", "--history", "3", "--no-progress", "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    net = load_network(out)
    assert net.meta["reproduce"].split() == ["mrd-env"] + ["inverse", "train", "--model", "bouc_wen", "--preset",
                                                           "spencer1997", "--dt", "0.001", "--history", "3",
                                                           "--hidden", "8", "--epochs", "1", "--records", "2",
                                                           "--duration", "0.4", "--rms", "0.001", "0.006",
                                                           "--bandwidth", "2", "15", "--hold", "0.005", "0.1",
                                                           "--seed", "0", "--out", str(out)]
    again = tmp_path / "again.npz"
    assert main(net.meta["reproduce"].split()[1:-1] + [str(again), "--no-progress"]) == 0
    assert all(np.array_equal(a, b) for a, b in zip(net.weights, load_network(again).weights))


def test_a_fitted_preset_file_is_a_damper_wherever_a_model_name_is(tmp_path, capsys):
    """achievable --plants/--mismatch, record --model and train --model take a preset file (as identify
    --save-preset writes); with no shipped network for its parameters the neural inverse is left out, saying so;
    a neural forward model's preset is refused in one line (the inverses step and invert a parametric model)."""
    fitted = save_preset(make_damper("bouc_wen", c0a=1.2 * make_damper("bouc_wen").params.c0a),
                         tmp_path / "fitted.json")
    out = tmp_path / "achievable"
    code = main(["inverse", "achievable", "--plants", str(fitted), "--mismatch", f"bouc_wen:{fitted}",
                 "--inverses", "model", "neural", "--duration", "0.6", "--out", str(out)])
    printed, err = capsys.readouterr()
    assert code == 0, err
    rows = _rows(out / "achievable.csv")
    assert [(r["plant"], r["inverse model"], r["inverse"]) for r in rows] == [
        ("fitted", "fitted", "model"), ("fitted", "bouc_wen", "model"), ("fitted", "bouc_wen", "neural")]
    assert float(rows[0]["NRMSE %"]) < 2.0 < float(rows[1]["NRMSE %"])  # its own model, then the published one
    assert "note: no neural inverse for this bouc_wen damper" in printed
    assert (out / "achievable_fitted_on_fitted.png").is_file()

    r = achievable_forces(make_damper(fitted), duration=1.0, rng=0)
    data = DamperRecord(r.t, r.x, r.command, r.force, r.v).to_csv(tmp_path / "rec.csv")
    code = main(["inverse", "record", "--data", str(data), "--model", str(fitted), "--maxiter", "2", "--fs", "1000",
                 "--inverses", "model", "--no-progress", "--out", str(tmp_path / "record")])
    assert code == 0, capsys.readouterr().err
    plant = read_preset(tmp_path / "record" / "plant_fitted.json")
    assert plant["model"] == "bouc_wen" and plant["provenance"]["initial"]["c0a"] == make_damper(fitted).params.c0a

    pytest.importorskip("torch")
    net = tmp_path / "net.npz"
    assert main(["inverse", "train", "--model", str(fitted), "--records", "1", "--duration", "0.3", "--epochs", "1",
                 "--hidden", "4", "--history", "2", "--no-progress", "--out", str(net)]) == 0
    from mrd_env.inverse.neural import load_network
    meta = load_network(net).meta
    assert meta["parameters"]["c0a"] == make_damper(fitted).params.c0a
    assert f"--model {fitted} --dt" in meta["reproduce"] and "--preset" not in meta["reproduce"]


def test_a_neural_forward_model_preset_is_refused_by_the_inverses(tmp_path, capsys):
    d = make_damper("bouc_wen")
    r = achievable_forces(d, duration=0.5, rng=0)
    rec = DamperRecord(r.t, r.x, r.command, r.force, r.v)
    pytest.importorskip("torch")
    from mrd_env.identification import fit_model
    net = save_preset(fit_model("neural", rec, search={"maxiter": 1, "progress": False}), tmp_path / "net.json")
    for argv in (["achievable", "--plants", str(net)], ["train", "--model", str(net)],
                 ["record", "--data", str(rec.to_csv(tmp_path / "rec.csv")), "--plant-preset", str(net)]):
        assert main(["inverse", *argv, "--out", str(tmp_path / "out.npz")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "holds a neural forward model; the inverses need a parametric" in err
