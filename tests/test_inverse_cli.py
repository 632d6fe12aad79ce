"""``mrd-env inverse``: the tracking tables and figures it writes, on short runs (the full tables of the README
come from the same commands with their defaults)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from experiments.cli import main
from mrd_env import make_damper
from mrd_env.identification import DamperRecord
from mrd_env.identification.fit import save_preset
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
