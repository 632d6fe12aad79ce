"""Disturbances: checked against the standards and the physics (ISO 8608 PSD, PEER record values, the
Kanai–Tajimi spectrum), not against the code's own formulas."""
import math

import numpy as np
import pytest
from scipy.signal import welch

from mrd_env.disturbances import (STANDARD_GRAVITY, Record, available_peer_records, bump, el_centro,
                                  iso8608_class_limits, iso8608_classify, iso8608_gd, iso8608_psd, iso8608_road,
                                  jennings_envelope, kanai_tajimi, kanai_tajimi_psd, kanai_tajimi_variance,
                                  peak_ground_acceleration, peer_record, read_at2, read_two_column, road_from_csv,
                                  saragoni_hart_envelope, scale_record, sine_sweep)

G = 9.80665


def _rel_rms(a, b):
    return np.sqrt(np.mean((a - b) ** 2)) / np.std(b)


# ---------------------------------------------------------------------------------------------------------------
# Record

def test_record_validates_fields_with_named_ranges():
    ok = np.zeros((3, 1))
    with pytest.raises(ValueError, match=r"dt .*> 0"):
        Record(0.0, ok, ("a",), ("m",))
    with pytest.raises(ValueError, match="dt"):
        Record(float("nan"), ok, ("a",), ("m",))
    with pytest.raises(ValueError, match="data must be 2-D"):
        Record(0.1, np.zeros(3), ("a",), ("m",))
    bad = ok.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="data must be finite.*sample 1"):
        Record(0.1, bad, ("a",), ("m",))
    with pytest.raises(ValueError, match="channels must be 1"):
        Record(0.1, ok, ("a", "b"), ("m",))
    with pytest.raises(ValueError, match="units must be 1"):
        Record(0.1, ok, ("a",), ())


def test_record_is_read_only_copy_with_time_grid():
    src = np.arange(10.0)[:, None]
    r = Record(0.5, src, ("a",), ("m",), "ramp")
    src[0, 0] = 99.0
    assert r.data[0, 0] == 0.0
    with pytest.raises(ValueError):
        r.data[0, 0] = 1.0
    assert r.duration == pytest.approx(4.5)
    np.testing.assert_allclose(r.t, 0.5 * np.arange(10))
    with pytest.raises(ValueError, match=r"channel must be one of \('a',\)"):
        r.channel("b")


def test_record_resample_is_linear_interpolation():
    r = Record(0.1, np.column_stack([np.arange(11) * 0.1, np.sin(np.arange(11))]), ("x", "y"), ("m", "m"))
    fine = r.resample(0.025)
    assert fine.dt == 0.025 and fine.duration == pytest.approx(1.0) and fine.n_samples == 41
    np.testing.assert_allclose(fine.channel("x"), fine.t, atol=1e-12)  # a ramp is reproduced exactly
    np.testing.assert_allclose(fine.channel("y")[::4], r.channel("y"), atol=1e-12)  # old samples kept
    with pytest.raises(ValueError, match="dt"):
        r.resample(-1)


# ---------------------------------------------------------------------------------------------------------------
# ISO 8608 roads

def test_iso8608_class_values_are_geometric_means_not_upper_limits():
    assert iso8608_gd("C") == pytest.approx(256e-6)
    assert iso8608_gd("a") == pytest.approx(16e-6)
    assert iso8608_gd("H") == pytest.approx(262144e-6)
    assert iso8608_class_limits("C") == pytest.approx((128e-6, 512e-6))
    assert iso8608_class_limits("A")[0] == 0.0 and iso8608_class_limits("H")[1] == math.inf
    for k in "BCDEFG":  # each class is 4x the previous, and its mean is the geometric mean of its limits
        lo, hi = iso8608_class_limits(k)
        assert math.sqrt(lo * hi) == pytest.approx(iso8608_gd(k))
    assert iso8608_classify(300e-6) == "C" and iso8608_classify(600e-6) == "D"
    assert iso8608_psd(0.2, "C") == pytest.approx(64e-6)  # (n/n0)^-2 = 1/4
    with pytest.raises(ValueError, match=r"road_class must be one of A\.\.H, got 'Z'"):
        iso8608_gd("Z")


def _spatial_psd(rec: Record, speed: float, seg_s: float = 5.12):
    fs = 1.0 / rec.dt
    f, p = welch(rec.channel("z_r"), fs=fs, nperseg=int(round(seg_s * fs)))
    return f / speed, p * speed  # G_d(n) = v G_z(f) at n = f / v


@pytest.mark.parametrize("method", ["sinusoids", "fft"])
def test_iso8608_road_psd_matches_standard_class_C(method):
    speed = 20.0
    rec = iso8608_road("C", speed, duration=40.0, dt=5e-3, rng=7, method=method)
    assert rec.channels == ("z_r", "zdot_r") and rec.units == ("m", "m/s")
    n, g = _spatial_psd(rec, speed)
    band = (n >= 0.05) & (n <= 2.5)
    ratio = g[band] / (256e-6 * (n[band] / 0.1) ** -2)
    assert abs(np.mean(np.log(ratio))) < math.log(1.3)
    # per octave as well, so that a wrong slope cannot hide behind a right average
    for lo in (0.05, 0.1, 0.2, 0.4, 0.8, 1.6):
        sel = (n[band] >= lo) & (n[band] < 2 * lo)
        assert abs(np.mean(np.log(ratio[sel]))) < math.log(1.3), lo
    slope = np.polyfit(np.log(n[band]), np.log(g[band]), 1)[0]
    assert slope == pytest.approx(-2.0, abs=0.15)


def test_iso8608_road_variance_is_integral_of_psd():
    # var z = int G_d dn = G_d(n0) n0^2 (1/n_min - 1/n_max) for w = 2: 15.2 mm rms for class C
    rec = iso8608_road("C", 20.0, duration=1000.0, dt=5e-3, rng=3, method="fft")
    expected = 256e-6 * 0.1 ** 2 * (1 / 0.011 - 1 / 2.83)
    assert np.var(rec.channel("z_r")) == pytest.approx(expected, rel=0.1)


def test_iso8608_class_D_has_four_times_the_psd_of_C():
    speed = 20.0
    n, gc = _spatial_psd(iso8608_road("C", speed, 40.0, 5e-3, rng=1), speed)
    _, gd = _spatial_psd(iso8608_road("D", speed, 40.0, 5e-3, rng=2), speed)
    band = (n >= 0.05) & (n <= 2.5)
    assert np.exp(np.mean(np.log(gd[band] / gc[band]))) == pytest.approx(4.0, rel=0.3)
    # with the same phases the D road is exactly the C road scaled by sqrt(4)
    c = iso8608_road("C", speed, 5.0, rng=11).data
    d = iso8608_road("D", speed, 5.0, rng=11).data
    np.testing.assert_allclose(d, 2.0 * c, rtol=1e-12, atol=1e-15)


def test_iso8608_zdot_is_the_derivative_of_z():
    rec = iso8608_road("C", 20.0, duration=2.0, dt=1e-4, rng=5)
    z, zdot = rec.channel("z_r"), rec.channel("zdot_r")
    assert _rel_rms(np.gradient(z, rec.dt), zdot) < 1e-3
    rec = iso8608_road("E", 10.0, duration=5.0, dt=1e-3, rng=5, method="fft")
    assert _rel_rms(np.gradient(rec.channel("z_r"), rec.dt), rec.channel("zdot_r")) < 5e-3


def test_iso8608_seeds_reproduce_and_differ():
    a = iso8608_road("B", 15.0, 3.0, rng=42)
    b = iso8608_road("B", 15.0, 3.0, rng=np.random.default_rng(42))
    c = iso8608_road("B", 15.0, 3.0, rng=43)
    assert np.array_equal(a.data, b.data)
    assert not np.allclose(a.data, c.data)
    assert np.array_equal(iso8608_road("B", 15.0, 3.0, rng=4, method="fft").data,
                          iso8608_road("B", 15.0, 3.0, rng=4, method="fft").data)


def test_iso8608_bad_inputs_name_the_parameter():
    with pytest.raises(ValueError, match=r"speed .*> 0 m/s"):
        iso8608_road("C", -3.0, 1.0)
    with pytest.raises(ValueError, match="duration"):
        iso8608_road("C", 20.0, 0.0)
    with pytest.raises(ValueError, match=r"dt must be < .* s"):  # 2.83 cycle/m at 40 m/s = 113 Hz > Nyquist
        iso8608_road("C", 40.0, 1.0, dt=5e-3)
    with pytest.raises(ValueError, match="method"):
        iso8608_road("C", 20.0, 1.0, method="wavelets")
    with pytest.raises(ValueError, match="rng"):
        iso8608_road("C", 20.0, 1.0, rng="seed")
    with pytest.raises(ValueError, match="n_max"):
        iso8608_road("C", 20.0, 1.0, n_min=1.0, n_max=0.5)


# ---------------------------------------------------------------------------------------------------------------
# Bump, sweep, CSV profile

def test_bump_shape_timing_and_pothole():
    rec = bump(height=0.05, length=2.0, speed=10.0, t_start=0.5, duration=2.0, dt=1e-3)
    z, zdot, t = rec.channel("z_r"), rec.channel("zdot_r"), rec.t
    assert z.max() == pytest.approx(0.05)
    assert t[np.argmax(z)] == pytest.approx(0.5 + 0.1, abs=1e-3)  # crest at half the length
    on = np.flatnonzero(z > 1e-12)
    assert t[on[0]] >= 0.5 and t[on[-1]] <= 0.7 + 1e-9  # length / speed = 0.2 s on the bump
    assert np.all(z[t > 0.7 + 1e-9] == 0) and np.all(z[t < 0.5] == 0)
    # over the bump: central differences err by (w dt)^2 / 6 = 2e-4, and by O(dt) at the curvature jumps
    on = (t >= 0.5) & (t <= 0.7)
    assert _rel_rms(np.gradient(z, rec.dt)[on], zdot[on]) < 5e-3
    pit = bump(height=-0.03, length=0.5, speed=5.0, t_start=0.2, duration=1.0)
    assert pit.channel("z_r").min() == pytest.approx(-0.03) and pit.channel("z_r").max() == 0.0
    with pytest.raises(ValueError, match="duration must be >= "):
        bump(0.05, 2.0, 1.0, t_start=0.5, duration=1.0)
    with pytest.raises(ValueError, match="length"):
        bump(0.05, 0.0, 1.0)


@pytest.mark.parametrize("kind", ["linear", "log"])
def test_sine_sweep_covers_the_frequency_band(kind):
    f0, f1, T = 0.5, 20.0, 20.0
    rec = sine_sweep(0.01, f0, f1, T, dt=1e-3, kind=kind)
    z = rec.channel("z_r")
    assert np.max(np.abs(z)) == pytest.approx(0.01, rel=1e-3)
    cycles = (f0 + f1) / 2 * T if kind == "linear" else (f1 - f0) * T / math.log(f1 / f0)
    crossings = np.count_nonzero(np.diff(np.signbit(z)))
    assert crossings == pytest.approx(2 * cycles, abs=2)
    assert _rel_rms(np.gradient(z, rec.dt), rec.channel("zdot_r")) < 5e-3
    with pytest.raises(ValueError, match="f_end"):
        sine_sweep(0.01, 1.0, 600.0, 1.0, dt=1e-3)


def test_road_from_csv_distance_profile_in_mm(tmp_path):
    x = np.arange(0.0, 50.0 + 1e-9, 0.05)
    z_mm = 10.0 * np.sin(2 * np.pi * x / 5.0)
    p = tmp_path / "profile.csv"
    p.write_text("x [m],z [mm]\n" + "".join(f"{a:.4f},{b:.6f}\n" for a, b in zip(x, z_mm)))
    rec = road_from_csv(p, distance_column="x", height_column="z", speed=10.0, dt=1e-3)
    assert rec.duration == pytest.approx(5.0)  # 50 m at 10 m/s
    t = rec.t
    np.testing.assert_allclose(rec.channel("z_r"), 0.01 * np.sin(2 * np.pi * 2.0 * t), atol=2e-5)  # 2 Hz
    zdot_exact = 0.01 * 2 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * t)
    # straight lines between points 0.05 m apart: piecewise slopes, rms error k h / sqrt(12) = 1.8 %
    assert _rel_rms(rec.channel("zdot_r"), zdot_exact) < 0.025


def test_road_from_csv_time_profile_with_units_mapping(tmp_path):
    p = tmp_path / "prof.txt"
    p.write_text("# measured\ntime height\n0 0\n100 1\n200 0\n")
    rec = road_from_csv(p, time_column="time", height_column="height", units={"time": "ms", "height": "cm"},
                        dt=0.01)
    assert rec.duration == pytest.approx(0.2)
    assert rec.channel("z_r").max() == pytest.approx(0.01)
    assert rec.channel("zdot_r")[5] == pytest.approx(0.1)  # 1 cm over 0.1 s


def test_road_from_csv_errors(tmp_path):
    good = tmp_path / "good.csv"
    good.write_text("x [m],z [m]\n0,0\n1,0.01\n2,0\n")
    with pytest.raises(ValueError, match=r"height_column 'h' is not a column .*names 2 columns\)$"):
        road_from_csv(good, distance_column="x", height_column="h", speed=10.0)
    with pytest.raises(ValueError, match="speed must be given"):
        road_from_csv(good, distance_column="x", height_column="z")
    with pytest.raises(ValueError, match="exactly one of distance_column"):
        road_from_csv(good, height_column="z", speed=10.0)
    nonmono = tmp_path / "nonmono.csv"
    nonmono.write_text("x [m],z [m]\n0,0\n2,0.01\n1,0\n")
    with pytest.raises(ValueError, match="strictly increasing.*line 4"):
        road_from_csv(nonmono, distance_column="x", height_column="z", speed=10.0)
    nan = tmp_path / "nan.csv"
    nan.write_text("x [m],z [m]\n0,0\n1,nan\n2,0\n")
    with pytest.raises(ValueError, match="non-finite value on line 3"):
        road_from_csv(nan, distance_column="x", height_column="z", speed=10.0)
    nounit = tmp_path / "nounit.csv"
    nounit.write_text("x,z\n0,0\n1,0.01\n2,0\n")
    with pytest.raises(ValueError, match="units missing for column 'x'"):
        road_from_csv(nounit, distance_column="x", height_column="z", speed=10.0)
    with pytest.raises(ValueError, match="unit of column 'z'"):
        road_from_csv(nounit, distance_column="x", height_column="z", speed=10.0, units={"x": "m", "z": "inch"})


# ---------------------------------------------------------------------------------------------------------------
# Earthquake records

def test_el_centro_peer_values():
    ns = el_centro("NS", dt=None)
    ew = el_centro("EW", dt=None)
    assert ns.dt == pytest.approx(0.01) and ew.dt == pytest.approx(0.01)
    assert 5300 <= ns.n_samples <= 5400 and 5300 <= ew.n_samples <= 5400
    assert peak_ground_acceleration(ns) / G == pytest.approx(0.281, abs=0.001)
    assert peak_ground_acceleration(ew) / G == pytest.approx(0.211, abs=0.001)
    assert ns.channels == ("xg_ddot",) and ns.units == ("m/s^2",)
    fine = el_centro("NS")  # default: resampled to 1 ms, same duration and (grid-aligned) peak
    assert fine.dt == 1e-3 and fine.duration == pytest.approx(ns.duration)
    assert peak_ground_acceleration(fine) == pytest.approx(peak_ground_acceleration(ns), rel=1e-9)
    classic = el_centro("NS", dt=None, source="classic")
    assert classic.dt == pytest.approx(0.02)
    assert peak_ground_acceleration(classic) / G == pytest.approx(0.319, abs=0.001)
    with pytest.raises(ValueError, match="component must be one of"):
        el_centro("XY")


def test_time_scaling_compresses_duration_and_keeps_pga():
    ns = el_centro("NS", dt=None)
    half = el_centro("NS", time_scale=0.5, dt=None)
    assert half.duration == pytest.approx(ns.duration / 2)
    assert half.dt == pytest.approx(0.005)
    lab = el_centro("NS", time_scale=0.2, amplitude_scale=1.5, dt=1e-3)
    assert lab.duration == pytest.approx(0.2 * ns.duration, abs=1e-3)
    assert peak_ground_acceleration(lab) == pytest.approx(1.5 * peak_ground_acceleration(ns), rel=1e-6)
    t_peak = ns.t[np.argmax(np.abs(ns.channel("xg_ddot")))]
    t_peak_lab = lab.t[np.argmax(np.abs(lab.channel("xg_ddot")))]
    assert t_peak_lab == pytest.approx(0.2 * t_peak, abs=1e-3)
    with pytest.raises(ValueError, match=r"time_scale .*> 0"):
        scale_record(ns, time_scale=0.0)
    with pytest.raises(ValueError, match="time_scale must be 1 for a multi-channel record"):
        scale_record(bump(0.05, 1.0, 10.0), time_scale=0.5)


def test_peer_records_load_and_unknown_name_lists_them():
    names = available_peer_records()
    assert "el_centro_1940_180" in names and any(n.startswith("loma_prieta") for n in names)
    for name in names:
        rec = peer_record(name)
        assert rec.dt in (0.005, 0.01, 0.02) and 0 < peak_ground_acceleration(rec) / G < 1.5
    with pytest.raises(ValueError, match="name must be one of el_centro_1940_180.*got 'kobe'"):
        peer_record("kobe")


AT2_HEADER = "PEER NGA STRONG MOTION DATABASE RECORD\nTest, 1/1/2000, Somewhere, 0\n" \
             "ACCELERATION TIME SERIES IN UNITS OF G\n"


def test_read_at2_tolerant_header_and_units(tmp_path):
    p = tmp_path / "ok.AT2"
    p.write_text(AT2_HEADER + "npts =6 ,dt= 0.0200 sec\n  .1E+00  -.2E+00   .3E+00\n  0.0 0.5D-01\n -1.0\n")
    rec = read_at2(p)
    assert rec.dt == 0.02 and rec.n_samples == 6
    np.testing.assert_allclose(rec.channel("xg_ddot"), np.array([0.1, -0.2, 0.3, 0.0, 0.05, -1.0]) * G)
    old = tmp_path / "old.AT2"
    old.write_text(AT2_HEADER + "    3    0.0050    NPTS, DT\n 0.1 0.2 0.3\n")
    assert read_at2(old).dt == 0.005 and read_at2(old).n_samples == 3


@pytest.mark.parametrize("line4, body, match", [
    ("DT= .0100 SEC\n", "0.1 0.2\n", "line 4 must give NPTS and DT"),
    ("NPTS= 5, DT= .0100 SEC\n", "0.1 0.2 0.3\n", "NPTS = 5 but the file has 3 values"),
    ("NPTS= 3, DT= .0100 SEC\n", "0.1 abc 0.3\n", "line 5 holds a value that is not a number"),
    ("NPTS= 3, DT= -.01 SEC\n", "0.1 0.2 0.3\n", "DT must be finite and > 0"),
])
def test_read_at2_malformed_files_raise(tmp_path, line4, body, match):
    p = tmp_path / "bad.AT2"
    p.write_text(AT2_HEADER + line4 + body)
    with pytest.raises(ValueError, match=match):
        read_at2(p)


def test_read_at2_short_file_raises(tmp_path):
    p = tmp_path / "short.AT2"
    p.write_text("only one line\n")
    with pytest.raises(ValueError, match="4 header lines"):
        read_at2(p)


def test_read_two_column(tmp_path):
    p = tmp_path / "eq.csv"
    t = np.arange(6) * 0.02
    p.write_text("time,acc (g)\n" + "".join(f"{a:.2f},{b}\n" for a, b in zip(t, [0, 0.1, -0.2, 0.0, 0.3, 0.0])))
    rec = read_two_column(p, accel_unit="g")
    assert rec.dt == pytest.approx(0.02) and peak_ground_acceleration(rec) == pytest.approx(0.3 * G)
    ws = tmp_path / "eq.txt"
    ws.write_text("0.0  1.0\n0.01 2.0\n0.02 3.0\n")
    assert read_two_column(ws, accel_unit="m/s^2").channel("xg_ddot")[2] == 3.0
    irregular = tmp_path / "irr.txt"
    irregular.write_text("0.0 0.0\n0.01 1.0\n0.03 3.0\n")
    with pytest.raises(ValueError, match="not uniform"):
        read_two_column(irregular, accel_unit="m/s^2")
    res = read_two_column(irregular, accel_unit="m/s^2", resample_dt=0.005)
    np.testing.assert_allclose(res.channel("xg_ddot"), 100.0 * res.t, atol=1e-12)  # the ramp a = 100 t
    backwards = tmp_path / "back.txt"
    backwards.write_text("0.0 0.0\n0.02 1.0\n0.01 3.0\n")
    with pytest.raises(ValueError, match="strictly increasing"):
        read_two_column(backwards, accel_unit="m/s^2", resample_dt=0.01)
    with pytest.raises(ValueError, match="accel_unit must be one of"):
        read_two_column(ws, accel_unit="furlongs")


# ---------------------------------------------------------------------------------------------------------------
# Kanai–Tajimi

def test_kanai_tajimi_psd_and_variance_match_analytic():
    S0 = 2e-3
    rec = kanai_tajimi(2000.0, dt=0.01, S0=S0, envelope=None, rng=3)
    a = rec.channel("xg_ddot")
    assert np.var(a) == pytest.approx(kanai_tajimi_variance(15.6, 0.6, S0), rel=0.05)
    f, p = welch(a, fs=100.0, nperseg=2048)
    band = (f >= 0.2) & (f <= 10.0)  # away from DC and from the aliasing near the 50 Hz Nyquist
    ratio = p[band] / (4 * np.pi * kanai_tajimi_psd(2 * np.pi * f[band], 15.6, 0.6, S0))
    assert abs(np.mean(np.log(ratio))) < math.log(1.05)
    assert np.all(np.abs(np.log(ratio)) < math.log(1.35))
    # the spectrum peaks near the ground frequency: S(w_g) / S(0) = 1 + 1 / (4 z^2) = 1.69
    assert kanai_tajimi_psd(15.6, 15.6, 0.6, 1.0) == pytest.approx(1 + 1 / (4 * 0.36))


def test_kanai_tajimi_pga_envelope_and_seeds():
    a = kanai_tajimi(20.0, pga=3.0, rng=1)
    b = kanai_tajimi(20.0, pga=3.0, rng=np.random.default_rng(1))
    c = kanai_tajimi(20.0, pga=3.0, rng=2)
    assert np.array_equal(a.data, b.data) and not np.allclose(a.data, c.data)
    x = a.channel("xg_ddot")
    assert np.max(np.abs(x)) == pytest.approx(3.0, rel=1e-12)
    assert a.channels == ("xg_ddot",) and a.dt == 1e-3 and a.duration == pytest.approx(20.0)
    assert x[0] == 0.0  # the Jennings envelope starts from zero
    t = a.t
    strong = np.std(x[(t > 2.0) & (t < 10.0)])
    assert np.std(x[t < 0.5]) < 0.2 * strong and np.std(x[t > 18.0]) < 0.3 * strong
    sh = kanai_tajimi(20.0, S0=1e-3, envelope="saragoni_hart", envelope_params={"eps": 0.3}, rng=1)
    assert sh.n_samples == a.n_samples


def test_envelopes():
    t = np.linspace(0, 20, 2001)
    e = jennings_envelope(t, 2.0, 10.0, 0.5)
    assert e[0] == 0.0 and e[100] == pytest.approx(0.25) and e[500] == 1.0
    assert e[-1] == pytest.approx(math.exp(-5.0))
    s = saragoni_hart_envelope(t, 20.0, eps=0.2, eta=0.05)
    assert t[np.argmax(s)] == pytest.approx(4.0, abs=0.01) and s.max() == pytest.approx(1.0, abs=1e-6)
    assert s[-1] == pytest.approx(0.05)


def test_kanai_tajimi_bad_inputs():
    with pytest.raises(ValueError, match="exactly one of pga"):
        kanai_tajimi(10.0)
    with pytest.raises(ValueError, match="exactly one of pga"):
        kanai_tajimi(10.0, pga=1.0, S0=1.0)
    with pytest.raises(ValueError, match=r"zeta_g .*> 0"):
        kanai_tajimi(10.0, zeta_g=0.0, pga=1.0)
    with pytest.raises(ValueError, match="dt must be < pi / omega_g"):
        kanai_tajimi(10.0, dt=0.5, pga=1.0)
    with pytest.raises(ValueError, match="envelope must be"):
        kanai_tajimi(10.0, pga=1.0, envelope="boxcar")
    with pytest.raises(ValueError, match="unknown"):
        kanai_tajimi(10.0, pga=1.0, envelope_params={"t3": 1.0})
    with pytest.raises(ValueError, match=r"pga .*> 0 m/s\^2"):
        kanai_tajimi(10.0, pga=-1.0)


def test_standard_gravity():
    assert STANDARD_GRAVITY == 9.80665
