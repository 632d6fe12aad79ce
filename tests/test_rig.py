"""The virtual test rig and the ``mrd-env rig`` command."""
import csv

import numpy as np
import pytest

from experiments.cli import main
from mrd_env import make_damper
from mrd_env.rig import random_test, simulate, sinusoidal_test


def test_sinusoidal_test_records_are_consistent():
    rs = sinusoidal_test("spencer_dyke", 0.01, 2.0, [0.0, 2.25], cycles=2)
    assert len(rs) == 2
    r = rs[1]
    assert r.t[0] == 0 and r.dt == pytest.approx(1e-3)
    assert np.allclose(r.x, 0.01 * np.sin(2 * np.pi * 2.0 * r.t))
    assert np.allclose(r.v, 0.01 * 2 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * r.t))
    assert np.all(r.command == 2.25) and r.command_unit == "V"
    assert r.label == "2.25 V"


def test_user_record_matches_sinusoid_with_finite_difference_velocity():
    d = make_damper("bouc_wen")
    exact = sinusoidal_test(d, 0.01, 1.0, [1.0], cycles=1, dt=1e-3)[0]
    rec = simulate(d, exact.x, np.full(len(exact.x), 1.0), 1e-3)[0]
    # second-order differences: velocity error O((ωdt)²) → force within 0.1 % RMS
    err = np.sqrt(np.mean((rec.force[5:-5] - exact.force[5:-5]) ** 2)) / np.sqrt(np.mean(exact.force ** 2))
    assert err < 1e-3


def test_random_test_is_reproducible_with_a_seed():
    a = random_test("spencer_dyke", 0.005, 20.0, 1.0, switch_rate=3.0, rng=7)
    b = random_test("spencer_dyke", 0.005, 20.0, 1.0, switch_rate=3.0, rng=7)
    c = random_test("spencer_dyke", 0.005, 20.0, 1.0, switch_rate=3.0, rng=8)
    assert np.array_equal(a.force, b.force) and np.array_equal(a.command, b.command)
    assert not np.array_equal(a.x, c.x)
    assert np.sqrt(np.mean(a.x ** 2)) == pytest.approx(0.005)
    assert set(np.unique(a.command)) == {0.0, 2.25}


def test_cli_rig_writes_table_csv_and_figure(tmp_path, capsys):
    assert main(["rig", "--model", "bouc_wen", "--cycles", "2", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "bouc_wen_loops.png").stat().st_size > 10_000
    md = (tmp_path / "bouc_wen_summary.md").read_text()
    assert "| command | F_max (N) | F_min (N) | energy per cycle (J) |" in md
    with (tmp_path / "bouc_wen_summary.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 and all(float(r["energy per cycle (J)"]) > 0 for r in rows)
    with (tmp_path / "bouc_wen_2.25V.csv").open() as fh:
        head = next(csv.reader(fh))
    assert head == ["t_s", "x_m", "v_m_per_s", "command_V", "u_V", "force_N"]


def test_cli_rig_replays_a_user_record(tmp_path):
    t = np.arange(0, 1.0, 1e-3)
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.c_[t, 0.005 * np.sin(2 * np.pi * 3 * t), np.where(t < 0.5, 0.0, 2.0)],
               delimiter=",", header="t_s,x_m,command_V", comments="")
    assert main(["rig", "--record", str(path), "--out", str(tmp_path / "o")]) == 0
    assert (tmp_path / "o" / "spencer_dyke_rec_record.csv").exists()
    # a record has no cycles: the table gives the energy it dissipated, a number (issue 22: it printed nan)
    with (tmp_path / "o" / "spencer_dyke_rec_summary.csv").open() as fh:
        row = next(csv.DictReader(fh))
    assert float(row["energy dissipated (J)"]) > 0


def test_cli_rig_says_when_it_replaces_an_earlier_run(tmp_path, capsys):
    assert main(["rig", "--model", "bingham", "--cycles", "1", "--out", str(tmp_path)]) == 0
    assert "replaced" not in capsys.readouterr().err
    assert main(["rig", "--model", "bingham", "--cycles", "1", "--out", str(tmp_path)]) == 0
    assert "replaced" in capsys.readouterr().err


def test_a_fitted_preset_file_drives_the_rig_and_the_environments(tmp_path):
    """Issue 22: a preset file written by identify is accepted wherever a model or preset name is."""
    from mrd_env.dampers import make_damper
    from mrd_env.identification import save_preset

    fitted = make_damper("bouc_wen", "spencer1997", alpha_b=2 * 69_500.0)
    path = save_preset(fitted, tmp_path / "fitted.json")
    for argv in (["--preset", str(path)], ["--model", str(path)]):
        assert main(["rig", *argv, "--cycles", "1", "--out", str(tmp_path / "o")]) == 0
    with (tmp_path / "o" / "bouc_wen_summary.csv").open() as fh:
        ours = [float(r["F_max (N)"]) for r in csv.DictReader(fh)]
    assert main(["rig", "--model", "bouc_wen", "--preset", "spencer1997", "--cycles", "1",
                 "--out", str(tmp_path / "p")]) == 0
    with (tmp_path / "p" / "bouc_wen_summary.csv").open() as fh:
        published = [float(r["F_max (N)"]) for r in csv.DictReader(fh)]
    assert ours[-1] > published[-1]            # the fitted α_b, not the preset's, drives the rig
    assert make_damper(str(path)).params == fitted.params
    with pytest.raises(ValueError, match="preset file"):
        make_damper(str(path), "spencer1997")


def test_cli_rig_replays_its_own_output_and_any_csv_with_declared_columns(tmp_path):
    """Regression: the rig rejected the CSVs it writes itself ('missing column command')."""
    assert main(["rig", "--model", "bouc_wen", "--commands", "1.0", "--out", str(tmp_path / "a")]) == 0
    own = tmp_path / "a" / "bouc_wen_1V.csv"
    assert main(["rig", "--model", "bouc_wen", "--record", str(own), "--out", str(tmp_path / "b")]) == 0
    replayed = np.genfromtxt(tmp_path / "b" / "bouc_wen_bouc_wen_1V_record.csv", delimiter=",", names=True)
    original = np.genfromtxt(own, delimiter=",", names=True)
    # the same stroke, velocity and command give the same force (the file holds 9 significant digits, so an
    # error-controlled step may split where the original did not: differences far below the integrator's error)
    diff = replayed["force_N"] - original["force_N"]
    assert np.sqrt(np.mean(diff ** 2)) <= 1e-4 * np.sqrt(np.mean(original["force_N"] ** 2))
    np.testing.assert_allclose(replayed["force_N"], original["force_N"], rtol=2e-3, atol=0)
    # a measured file: semicolons, cm, ms, its own column names
    t = np.arange(0, 500) * 1.0
    path = tmp_path / "lab.csv"
    np.savetxt(path, np.c_[t, 0.5 * np.sin(2 * np.pi * 3e-3 * t), np.full(t.size, 1.0)], delimiter=";",
               header="time;D;Y", comments="")
    assert main(["rig", "--record", str(path), "--columns", "t=time,x=D,command=Y", "--units", "t=ms,x=cm,command=V",
                 "--out", str(tmp_path / "c")]) == 0
    out = np.genfromtxt(tmp_path / "c" / "spencer_dyke_lab_record.csv", delimiter=",", names=True)
    assert out["x_m"].max() == pytest.approx(0.005, rel=1e-3) and out["t_s"][-1] == pytest.approx(0.499)


def test_cli_reports_bad_input_without_traceback(tmp_path, capsys):
    assert main(["rig", "--model", "nope", "--out", str(tmp_path)]) == 2
    assert "unknown damper model 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("dt,match", [
    (0.0, r"dt = 0.0 is invalid: must be finite and > 0 s"), (-1e-3, r"dt = -0.001 is invalid: must be finite and > 0 s"),
    (float("nan"), r"dt = nan is invalid"), ("x", r"dt must be a real number"),
    (1.0, r"dt = 1 s cannot resolve"), (10.0, r"dt = 10 s cannot resolve"),
    (0.02, r"cannot resolve the damper's command lag")])
def test_rig_tests_reject_a_step_that_cannot_resolve_the_test(dt, match):
    """Regression: dt = 0 gave ZeroDivisionError, NaN a conversion error, 1 s or 10 s ran silently."""
    with pytest.raises(ValueError, match=match):
        sinusoidal_test("spencer_dyke", 0.01, 0.05 if dt == 0.02 else 2.5, [1.0], dt=dt)
    with pytest.raises(ValueError, match=match):
        random_test("spencer_dyke", 0.003, 0.05 if dt == 0.02 else 20.0, 30.0, command=1.0, dt=dt)
