"""Measured records, the CSV loader and the simulated rig sensors (review Table 7).

All files are synthetic and written here; the real NEES record is never read by the tests.
"""
import math

import numpy as np
import pytest

from mrd_env import make_damper
from mrd_env.identification import (DamperRecord, DataOptions, DisplacementSensor, LoadCell, NeuralOptions,
                                    SearchOptions, SensorSet, apply_sensors, load_record_csv)
from mrd_env.inverse import make_inverse

NEES_LIKE_COLUMNS = {"t": "t", "x": "D", "command": "Y", "force": "F", "v": "V"}
NEES_LIKE_UNITS = {"t": "s", "x": "cm", "command": "V", "force": "N", "v": "cm/s"}


def synthetic_signals(n=400, fs=1000.0):
    t = np.arange(n) / fs
    x = 0.005 * np.sin(2 * np.pi * 3 * t)
    v = 0.005 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t)
    cmd = np.where(t < t[n // 2], 0.0, 2.25)
    F = 800 * np.tanh(v / 0.02) + 300 * cmd * np.sign(v)
    return t, x, v, cmd, F


def write_nees_like(path, n=400, fs=3000.0, mutate=None):
    """Imitate the layout of the real export: quoted header, trailing commas, 'fs' only on the first line."""
    t, x, v, cmd, F = synthetic_signals(n, fs)
    A = np.cos(t * 50)
    rows = [[f"{t[i]:.7g}", f"{A[i]:.6g}", f"{100 * x[i]:.8g}", f"{cmd[i]:.5g}", f"{fs:g}" if i == 0 else "",
             f"{100 * v[i]:.8g}", f"{F[i]:.7g}"] for i in range(n)]
    if mutate:
        mutate(rows)
    lines = ['"t","A","D","Y","fs","V","F",'] + [",".join(r) + "," for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return t, x, v, cmd, F


def load(path, **kw):
    return load_record_csv(path, kw.pop("columns", NEES_LIKE_COLUMNS), kw.pop("units", NEES_LIKE_UNITS), **kw)


# --- DamperRecord -------------------------------------------------------------------------------------------------

def test_record_validation_names_column_and_row():
    t, x, v, cmd, F = synthetic_signals(50)
    r = DamperRecord(t, x, cmd, F, v)
    assert r.n == 50 and r.command_unit == "V"
    with pytest.raises(ValueError):
        r.x[0] = 1.0  # arrays are read-only
    bad_t = t.copy()
    bad_t[12] = bad_t[11]
    with pytest.raises(ValueError, match=r"column 't' is not strictly increasing at row 12"):
        DamperRecord(bad_t, x, cmd, F)
    with pytest.raises(ValueError, match=r"column 'force' has a non-finite value \(nan\) at row 3"):
        DamperRecord(t, x, cmd, np.where(np.arange(50) == 3, np.nan, F))
    with pytest.raises(ValueError, match="column 'x' has 49 samples, expected 50"):
        DamperRecord(t, x[:-1], cmd, F)
    with pytest.raises(ValueError, match="command_unit"):
        DamperRecord(t, x, cmd, F, command_unit="mA")


def test_velocity_falls_back_to_derivative():
    t, x, v, cmd, F = synthetic_signals(1000)
    r = DamperRecord(t, x, cmd, F)
    assert np.max(np.abs(r.velocity() - v)) < 1e-3 * np.max(np.abs(v))
    assert np.array_equal(DamperRecord(t, x, cmd, F, v).velocity(), v)  # the measured velocity when given


def test_slice_split_resample():
    t, x, v, cmd, F = synthetic_signals(401)
    r = DamperRecord(t, x, cmd, F, v, label="run")
    s = r.slice(0.1, 0.2)
    assert s.t[0] == pytest.approx(0.1) and s.t[-1] == pytest.approx(0.2) and s.n == 101
    with pytest.raises(ValueError, match=r"the time window \[0.2, 0.1\] s is invalid: its start must be finite and "
                                         "before its finite end"):
        r.slice(0.2, 0.1)
    with pytest.raises(ValueError, match="holds 0 samples"):
        r.slice(5.0, 6.0)
    fit, val = r.split(0.75)
    assert fit.n + val.n == r.n and fit.t[-1] < val.t[0] and fit.n == 301
    assert fit.label == "run (fit)"
    with pytest.raises(ValueError, match="fraction"):
        r.split(1.0)
    # upsampling: linear signals are reproduced, the switched command keeps its two levels
    lin = DamperRecord(t, 2 * t + 1, cmd, 5 * t, 2 + 0 * t)
    up = lin.resample(0.00025)
    assert up.n == 1601
    np.testing.assert_allclose(up.x, 2 * up.t + 1, rtol=1e-12)
    assert set(np.unique(up.command)) == {0.0, 2.25}
    # downsampling with the anti-alias filter keeps a 3 Hz stroke (filter at 0.8 × 50 Hz)
    down = r.resample(0.01)
    assert down.n == 41
    np.testing.assert_allclose(down.x, 0.005 * np.sin(2 * np.pi * 3 * down.t), atol=2e-5)
    with pytest.raises(ValueError, match="dt"):
        r.resample(-1.0)


def test_csv_round_trip(tmp_path):
    t, x, v, cmd, F = synthetic_signals(100)
    for rec in (DamperRecord(t, x, cmd, F, v, "A"), DamperRecord(t, x, cmd, F)):
        back = DamperRecord.read_csv(rec.to_csv(tmp_path / "rec.csv"))
        for k in ("t", "x", "command", "force"):
            np.testing.assert_array_equal(getattr(back, k), getattr(rec, k))
        assert (back.v is None) == (rec.v is None) and back.command_unit == rec.command_unit


# --- load_record_csv ---------------------------------------------------------------------------------------------

def test_loads_nees_like_layout_and_converts_units(tmp_path):
    p = tmp_path / "ranran_like.csv"
    t, x, v, cmd, F = write_nees_like(p)
    r = load(p)
    assert r.n == 400 and r.label == "ranran_like" and r.command_unit == "V"
    np.testing.assert_allclose(r.t, t, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(r.x, x, rtol=1e-6, atol=1e-12)  # cm -> m
    np.testing.assert_allclose(r.v, v, rtol=1e-6, atol=1e-12)  # cm/s -> m/s
    np.testing.assert_allclose(r.force, F, rtol=1e-6)
    # without trimming, the trailing comma is an unnamed last column present on every line: still readable
    r2 = load(p, skip_trailing_empty=False)
    np.testing.assert_array_equal(r2.force, r.force)


def test_other_units(tmp_path):
    p = tmp_path / "mm_kN.csv"
    p.write_text('time ms,stroke,"cmd",load\n0,1.5,0.1,2.0\n1,2.5,0.2,-1.0\n2,3.5,0.3,0.5\n')
    r = load_record_csv(p, {"t": "time ms", "x": "stroke", "command": "cmd", "force": "load"},
                        {"t": "ms", "x": "mm", "command": "mA", "force": "kN"})
    np.testing.assert_allclose(r.t, [0, 1e-3, 2e-3])
    np.testing.assert_allclose(r.x, [1.5e-3, 2.5e-3, 3.5e-3])
    np.testing.assert_allclose(r.force, [2000.0, -1000.0, 500.0])
    np.testing.assert_allclose(r.command, [1e-4, 2e-4, 3e-4])
    assert r.command_unit == "A" and r.v is None


def _set(row, col, value):
    def mutate(rows):
        rows[row][col] = value
    return mutate


@pytest.mark.parametrize("kwargs, mutate, match", [
    ({"columns": {**NEES_LIKE_COLUMNS, "force": "Force"}}, None,
     r"column 'Force' \(for 'force'\) not found; available columns: \['t', 'A', 'D', 'Y', 'fs', 'V', 'F'\]"),
    ({"units": {k: u for k, u in NEES_LIKE_UNITS.items() if k != "x"}}, None,
     r"units\['x'\] is not given for column 'D': declare its unit, one of \['m', 'cm', 'mm'\]"),
    ({"units": {**NEES_LIKE_UNITS, "force": "lbf"}}, None, r"units\['force'\] = 'lbf'.*one of \['N', 'kN'\]"),
    ({"columns": {k: c for k, c in NEES_LIKE_COLUMNS.items() if k != "command"},
      "units": {k: u for k, u in NEES_LIKE_UNITS.items() if k != "command"}}, None, r"roles \['command'\]"),
    ({"columns": {**NEES_LIKE_COLUMNS, "a": "A"}}, None, r"unknown roles \['a'\]"),
    ({}, _set(10, 6, "abc"), r"column 'F' \(force\) has a value that is not a number at data row 10 \(file line 12\)"),  # no content quoted
    ({}, _set(7, 2, ""), r"column 'D' \(x\) has an empty cell at data row 7 \(file line 9\)"),
    ({}, _set(5, 5, "nan"), r"column 'V' \(v\) has a non-finite value \(nan\) at data row 5"),
    ({}, _set(20, 0, "0.001"), r"column 't' \(t\) is not strictly increasing at data row 20"),
])
def test_loader_errors_are_clear(tmp_path, kwargs, mutate, match):
    p = tmp_path / "bad.csv"
    write_nees_like(p, n=50, mutate=mutate)
    with pytest.raises(ValueError, match=match):
        load(p, **kwargs)


def test_loader_row_width_and_empty_file(tmp_path):
    p = tmp_path / "ragged.csv"
    p.write_text("t,x,c,F\n0,0,0,0\n1,1,1,1,5\n2,2,2,2\n")
    cols, units = {"t": "t", "x": "x", "command": "c", "force": "F"}, {"t": "s", "x": "m", "command": "V",
                                                                         "force": "N"}
    with pytest.raises(ValueError, match="line 3 has 5 cells but the header has 4"):
        load_record_csv(p, cols, units)
    (tmp_path / "empty.csv").write_text("\n\n")
    with pytest.raises(ValueError, match="empty"):
        load_record_csv(tmp_path / "empty.csv", cols, units)


# --- rig sensors (Table 7) -------------------------------------------------------------------------------------------

IDEAL = SensorSet(LoadCell(accuracy_fs=0.0, noise_rms=0.0, resolution=0.0),
                  DisplacementSensor(accuracy_fs=0.0, noise_rms_m=0.0, resolution_m=0.0),
                  sample_rate_Hz=1000.0, velocity_cutoff_Hz=None)


def test_noise_free_sensor_returns_input():
    t, x, v, cmd, F = synthetic_signals(300, fs=1000.0)
    out = apply_sensors(t, x, F, IDEAL, 0, command=cmd)
    np.testing.assert_array_equal(out.t, t)
    np.testing.assert_array_equal(out.x, x)
    np.testing.assert_array_equal(out.force, F)
    assert not (out.saturated_x.any() or out.saturated_force.any())
    assert isinstance(out, DamperRecord) and np.array_equal(out.command, cmd)


def test_quantisation_to_resolution():
    t, x, v, cmd, F = synthetic_signals(300)
    s = SensorSet(LoadCell(accuracy_fs=0.0, noise_rms=0.0, resolution=2.0),
                  DisplacementSensor(accuracy_fs=0.0, noise_rms_m=0.0, resolution_m=1e-4), 1000.0)
    out = apply_sensors(t, x, F, s, 0, command=cmd)
    np.testing.assert_allclose(out.force / 2.0, np.round(out.force / 2.0), atol=1e-9)
    assert np.max(np.abs(out.force - F)) <= 1.0 + 1e-9
    np.testing.assert_allclose(out.x / 1e-4, np.round(out.x / 1e-4), atol=1e-9)
    assert np.max(np.abs(out.x - x)) <= 0.5e-4 + 1e-12
    assert len(np.unique(out.force)) > 50


def test_static_error_within_datasheet_bound():
    t, x, v, cmd, F = synthetic_signals(200)
    lc = LoadCell(noise_rms=0.0, resolution=0.0)  # ±0.03 % FS only
    ds = DisplacementSensor(noise_rms_m=0.0, resolution_m=0.0)  # ±0.02 % of 150 mm
    for seed in range(20):
        out = apply_sensors(t, x, F, SensorSet(lc, ds, 1000.0), seed, command=cmd)
        assert np.max(np.abs(out.force - F)) <= 0.0003 * 5394.0
        assert np.max(np.abs(out.x - x)) <= 0.0002 * 0.150 + 1e-15


def test_velocity_from_measured_sine():
    # 10 mm, 2 Hz stroke sampled at 1 kHz by the default (noisy, quantised) sensors, filtered at 50 Hz
    fs_true = 10000.0
    t = np.arange(int(2.0 * fs_true) + 1) / fs_true
    w = 2 * np.pi * 2.0
    x = 0.010 * np.sin(w * t)
    out = apply_sensors(t, x, 500 * np.cos(w * t), SensorSet(), 3, command=0.0)
    v_true = 0.010 * w * np.cos(w * out.t)
    err = np.abs(out.v - v_true) / (0.010 * w)
    assert np.max(err[20:-20]) < 0.01  # < 1 % of the velocity amplitude away from the record ends
    assert np.max(err) < 0.03  # the zero-phase filter is padded, so the ends stay close
    # ideal sensors and plain central differences: truncation error (ω dt)²/6 of the amplitude
    ideal = apply_sensors(t, x, 0 * t, IDEAL, 0, command=0.0)
    v_ideal = 0.010 * w * np.cos(w * ideal.t)
    assert np.max(np.abs(ideal.v - v_ideal)[1:-1]) < (w / 1000.0) ** 2 / 6 * 0.010 * w * 1.01


def test_seeds_are_reproducible_and_streams_independent():
    t, x, v, cmd, F = synthetic_signals(300)
    a = apply_sensors(t, x, F, SensorSet(), 11, command=cmd)
    b = apply_sensors(t, x, F, SensorSet(), np.random.default_rng(11), command=cmd)
    c = apply_sensors(t, x, F, SensorSet(), 12, command=cmd)
    for k in ("x", "v", "force"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert not np.array_equal(a.force, c.force)
    # a quieter load cell leaves the displacement errors unchanged
    d = apply_sensors(t, x, F, SensorSet(load_cell=LoadCell(noise_rms=0.0)), 11, command=cmd)
    np.testing.assert_array_equal(a.x, d.x)
    with pytest.raises(ValueError, match="rng"):  # the project's one rule (validation.as_generator): None is
        apply_sensors(t, x, F, SensorSet(), -1, command=cmd)   # fresh entropy, a negative seed is refused


def test_out_of_range_detected_or_clipped():
    t, x, v, cmd, F = synthetic_signals(300)
    big = 3 * F + 6000 * np.sin(2 * np.pi * t)
    with pytest.raises(ValueError, match=r"F exceeds the sensor range ±5394 N"):
        apply_sensors(t, x, big, SensorSet(), 0, command=cmd)
    with pytest.raises(ValueError, match=r"x exceeds the sensor range ±0.075 m"):
        apply_sensors(t, 20 * x, F, SensorSet(), 0, command=cmd)
    out = apply_sensors(t, x, big, SensorSet(), 0, command=cmd, overrange="clip")
    assert out.saturated_force.any() and not out.saturated_x.any()
    assert np.max(np.abs(out.force)) <= 5394.0
    assert np.all(np.abs(out.force[out.saturated_force]) >= 5394.0 - LoadCell().resolution)


def test_sensor_parameters_are_validated():
    with pytest.raises(ValueError, match=r"LoadCell.range_N = -1 is invalid: must be > 0 N"):
        LoadCell(range_N=-1)
    with pytest.raises(ValueError, match="velocity_cutoff_Hz"):
        SensorSet(sample_rate_Hz=100.0, velocity_cutoff_Hz=60.0)
    assert math.isclose(DisplacementSensor().range_m, 0.150)


@pytest.mark.parametrize("make, shown", [
    (lambda: DataOptions(dt=np.float64(-0.002)), "dt = -0.002 is invalid"),
    (lambda: SearchOptions(seed=np.int64(-1)), "seed = -1 is invalid"),
    (lambda: NeuralOptions(lr=np.float64(2.0)), "lr = 2.0 is invalid"),
    (lambda: DamperRecord(np.array([0, 1e-3, 2e-3, 2e-3, 4e-3]), *np.zeros((3, 5))),
     "(0.002 followed by 0.002)"),
    (lambda: make_inverse("heaviside", make_damper("bouc_wen"), f_static=np.float64(np.inf)), "f_static = inf is"),
])
def test_bad_numpy_values_are_shown_as_numbers(make, shown):
    """A NumPy scalar in an error message reads as the number it holds, never np.float64(...)."""
    with pytest.raises(ValueError) as err:
        make()
    assert shown in str(err.value) and "np." not in str(err.value)
