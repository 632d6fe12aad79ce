"""Comfort, quarter-car and building metrics (``mrd_env.metrics``): published values and physics."""
import math

import numpy as np
import pytest
from scipy import signal

from mrd_env import metrics as M
from mrd_env.plants.quarter_car import metrics as QM
from mrd_env.plants.shear_building import metrics as BM

# ISO 2631-1 |Wk| check values (reference page, section 6)
WK_CHECK = {1.0: 0.482, 2.0: 0.531, 4.0: 0.967, 5.0: 1.039, 6.3: 1.054, 8.0: 1.036, 10.0: 0.988,
            16.0: 0.769, 31.5: 0.405, 80.0: 0.132}
DT = 1e-3  # 1 kHz, the sample rate the digital filter's accuracy is specified at


def sine(amplitude, f, duration, dt=DT):
    t = np.arange(int(round(duration / dt))) * dt
    return t, amplitude * np.sin(2 * np.pi * f * t)


# ---------------------------------------------------------------- ISO 2631-1 weighting

def test_wk_magnitude_matches_published_check_values():
    f = np.array(list(WK_CHECK))
    expected = np.array(list(WK_CHECK.values()))
    assert M.weighting_magnitude("Wk", f) == pytest.approx(expected, rel=0.01)
    # the polynomial form and the control.TransferFunction give the same weighting
    num, den = M.iso2631_weighting("Wk")
    _, h = signal.freqs(num, den, 2 * np.pi * f)
    assert np.abs(h) == pytest.approx(expected, rel=0.01)
    tf = M.iso2631_weighting("Wk", as_tf=True)
    assert abs(tf(2j * np.pi * 6.3)) == pytest.approx(1.054, rel=0.01)


def test_weighting_asymptotes():
    # far below f1 the Butterworth high-pass gives (f/f1)², times Hs's DC gain (f5/f6)² for Wk
    f = 0.004
    assert M.weighting_magnitude("Wk", f) == pytest.approx((f / 0.4) ** 2 * (2.37 / 3.35) ** 2, rel=1e-3)
    assert M.weighting_magnitude("Wd", f) == pytest.approx((f / 0.4) ** 2, rel=1e-3)
    # between f4 and f2 the weighting is velocity-proportional: |W| → f3/f
    for f in (20.0, 25.0):
        assert M.weighting_magnitude("Wd", f) == pytest.approx(2.0 / f, rel=5e-3)


@pytest.mark.parametrize("kind", ["Wk", "Wd"])
def test_digital_filter_on_long_sines_gives_weighting_magnitude(kind):
    for f in (1.0, 4.0, 8.0, 16.0, 31.5, 63.0):
        _, a = sine(2.0, f, 20.0)
        a_w = M.weighted_acceleration(a, DT, kind)
        steady = a_w[int(8.0 / DT):]  # past the 0.4 Hz high-pass transient (time constant 0.56 s)
        ratio = M.rms(steady) / (2.0 / math.sqrt(2))
        assert ratio == pytest.approx(M.weighting_magnitude(kind, f), rel=0.01), f
        # the FFT method applies the analog weighting exactly
        a_w_fft = M.weighted_acceleration(a, DT, kind, method="fft")[int(8.0 / DT):]
        assert M.rms(a_w_fft) / (2.0 / math.sqrt(2)) == pytest.approx(M.weighting_magnitude(kind, f), rel=1e-4)


def test_weighted_rms_of_white_noise_obeys_parseval():
    # white noise of variance σ² has one-sided PSD 2σ²·dt, so E[a_w²] = 2σ²·dt·∫|W|² df over 0..fs/2
    sigma, duration = 3.0, 200.0
    a = np.random.default_rng(12).normal(0.0, sigma, int(duration / DT))
    f = np.linspace(0.0, 0.5 / DT, 100001)
    expected = sigma * math.sqrt(2 * DT * np.trapezoid(M.weighting_magnitude("Wk", f) ** 2, f))
    # ~12 000 independent samples of the weighted band → 1σ ≈ 0.7 % on the r.m.s.
    assert M.weighted_rms(a, DT, "Wk") == pytest.approx(expected, rel=0.03)
    assert M.weighted_rms(a, DT, "Wk", method="fft") == pytest.approx(expected, rel=0.03)
    # the same record through both methods differs only by the IIR's warping above ~30 Hz
    assert M.weighted_rms(a, DT) == pytest.approx(M.weighted_rms(a, DT, method="fft"), rel=0.005)


def test_weighting_is_linear_and_accepts_channels_and_time_vectors():
    t, a = sine(1.0, 5.0, 4.0)
    two = np.column_stack([a, -3 * a])
    out = M.weighted_acceleration(two, t)
    assert out.shape == two.shape
    assert np.allclose(out[:, 1], -3 * M.weighted_acceleration(a, DT))


def test_digital_wk_at_100_hz_sampling_stays_within_1_percent_up_to_fs_over_10():
    # fs < 2·f2: the band-limiting low-pass is dropped; the pre-warped corners keep the band accurate
    dt = 0.01
    sos = M.weighting_sos("Wk", dt)
    f = np.array([1.0, 4.0, 8.0, 10.0])
    _, h = signal.sosfreqz(sos, worN=f, fs=1 / dt)
    assert np.abs(h) == pytest.approx(M.weighting_magnitude("Wk", f), rel=0.01)


# ---------------------------------------------------------------- VDV and running r.m.s.

def test_vdv_of_sine():
    # mean of sin⁴ is 3/8, so VDV = A·(3T/8)^¼ over whole periods
    _, a = sine(1.5, 4.0, 10.0)
    assert M.vdv(a, DT) == pytest.approx(1.5 * (3 * 10.0 / 8) ** 0.25, rel=1e-6)


def test_running_rms_and_mtvv():
    # a constant c: the 1 s linear-integration running r.m.s. ramps as c·√(t/τ), then stays at c
    c = 2.0
    r = M.running_rms(np.full(3000, c), DT, tau=1.0)
    t = (np.arange(3000) + 1) * DT
    assert r[:1000] == pytest.approx(c * np.sqrt(t[:1000]), rel=1e-9)
    assert r[1000:] == pytest.approx(c, rel=1e-9)
    # a 0.5 s burst: MTVV = burst r.m.s. × √(0.5 s / τ), whatever quiet signal surrounds it
    _, burst = sine(4.0, 10.0, 0.5)
    a = np.concatenate([np.zeros(2000), burst, np.zeros(2000)])
    assert M.mtvv(a, DT, tau=1.0) == pytest.approx(4.0 / math.sqrt(2) * math.sqrt(0.5), rel=1e-6)
    # a steady sine: MTVV = r.m.s. = A/√2
    _, a = sine(4.0, 10.0, 5.0)
    assert M.mtvv(a, DT) == pytest.approx(4.0 / math.sqrt(2), rel=1e-6)


# ---------------------------------------------------------------- quarter car

def test_quarter_car_metrics_of_sinusoidal_responses():
    f, acc_amp, travel_amp, defl_amp, k_t = 5.0, 1.2, 0.03, 0.004, 190000.0
    t, acc = sine(acc_amp, f, 60.0)
    travel = travel_amp * np.cos(2 * np.pi * f * t)
    deflection = defl_amp * np.sin(2 * np.pi * f * t + 0.3)
    static = (320 + 40) * M.G
    m = QM.quarter_car_metrics(DT, acc, travel, tyre_deflection=deflection, tyre_stiffness=k_t,
                              static_tyre_load=static)
    # the high-pass start-up transient is a small part of a 60 s record
    assert m["acc_weighted_rms"] == pytest.approx(M.weighting_magnitude("Wk", f) * acc_amp / math.sqrt(2),
                                                  rel=0.01)
    assert m["acc_rms"] == pytest.approx(acc_amp / math.sqrt(2), rel=1e-9)
    assert m["acc_mtvv"] == pytest.approx(m["acc_weighted_rms"], rel=0.02)  # stationary signal
    # VDV⁴ = ∫a_w⁴ dt = (3/8)·(√2·a_w,rms)⁴·T for a sinusoid
    assert m["acc_vdv"] == pytest.approx((3 / 8 * 4 * m["acc_weighted_rms"] ** 4 * 60.0) ** 0.25, rel=0.01)
    assert m["travel_rms"] == pytest.approx(travel_amp / math.sqrt(2), rel=1e-9)
    assert m["travel_peak"] == pytest.approx(travel_amp, rel=1e-9)
    assert m["tyre_load_rms"] == pytest.approx(k_t * defl_amp / math.sqrt(2), rel=1e-3)
    assert m["tyre_load_ratio"] == pytest.approx(m["tyre_load_rms"] / static, rel=1e-12)
    # the tyre load given directly is equivalent to deflection × stiffness
    m2 = QM.quarter_car_metrics(t, acc, travel, k_t * deflection, static_tyre_load=static)
    assert m2 == pytest.approx(m, rel=1e-12)


def test_quarter_car_metrics_without_tyre_input_omit_tyre_keys():
    _, acc = sine(1.0, 2.0, 2.0)
    m = QM.quarter_car_metrics(DT, acc, 0 * acc)
    assert set(m) == {"acc_weighted_rms", "acc_rms", "acc_vdv", "acc_mtvv", "travel_rms", "travel_peak"}


# ---------------------------------------------------------------- buildings and benchmark criteria

def building_record(scale=1.0, n=4000):
    t = np.arange(n) * DT
    drift = scale * np.column_stack([0.010 * np.sin(2 * np.pi * 2.0 * t), 0.006 * np.sin(2 * np.pi * 2.0 * t)])
    acc = scale * np.column_stack([3.0 * np.sin(2 * np.pi * 2.0 * t), 5.0 * np.sin(2 * np.pi * 2.0 * t)])
    force = scale * 800.0 * np.cos(2 * np.pi * 2.0 * t)
    stroke = scale * 0.004 * np.sin(2 * np.pi * 2.0 * t)
    disp = scale * np.column_stack([0.010 * np.sin(2 * np.pi * 2.0 * t), 0.016 * np.sin(2 * np.pi * 2.0 * t)])
    return dict(dt=DT, drift=drift, storey_heights=[0.5, 0.3], abs_acc=acc, damper_force=force,
                floor_masses=[100.0, 200.0], damper_stroke=stroke, displacement=disp)


def test_building_metrics_of_sinusoidal_response():
    m = BM.building_metrics(**building_record())
    # drift ratio: storey 1 peaks at 0.010/0.5 = 0.02, storey 2 at 0.006/0.3 = 0.02
    assert m["drift_peak"] == pytest.approx(0.010, rel=1e-6)
    assert m["drift_ratio_peak"] == pytest.approx(0.02, rel=1e-6)
    # a pure sine over whole periods has peak/r.m.s. = √2
    for q in ("drift", "drift_ratio", "acc", "base_shear"):
        assert m[f"{q}_peak"] / m[f"{q}_rms"] == pytest.approx(math.sqrt(2), rel=1e-6), q
    # base shear = Σ m_i·ẍ_a,i = (100·3 + 200·5) sin
    assert m["base_shear_peak"] == pytest.approx(1300.0, rel=1e-6)
    assert m["acc_peak"] == pytest.approx(5.0, rel=1e-6)
    assert m["damper_force_peak"] == pytest.approx(800.0, rel=1e-9)
    assert m["damper_stroke_peak"] == pytest.approx(0.004, rel=1e-6)
    assert m["disp_peak"] == pytest.approx(0.016, rel=1e-6)
    # a given base shear takes precedence over the floor masses
    rec = building_record()
    rec["base_shear"] = 2 * (rec["abs_acc"] @ np.array(rec["floor_masses"]))
    assert BM.building_metrics(**rec)["base_shear_peak"] == pytest.approx(2600.0, rel=1e-6)


def test_benchmark_criteria_normalisation():
    unc = BM.building_metrics(**building_record())
    same = BM.benchmark_criteria(unc, unc)
    assert same == pytest.approx({f"J{i}": 1.0 for i in range(1, 7)} | {"stroke_peak": 0.004,
                                                                        "stroke_over_disp": 0.25})
    # responses scale linearly, so a uniformly halved response gives J = 1/2
    half = BM.building_metrics(**building_record(scale=0.5))
    w = 300.0 * M.G
    j = BM.benchmark_criteria(half, unc, building_weight=w)
    for i in range(1, 7):
        assert j[f"J{i}"] == pytest.approx(0.5, rel=1e-9)
    assert j["force_over_weight"] == pytest.approx(400.0 / w, rel=1e-9)
    # the benchmark reports the worst record
    worst = BM.max_over_records([j, BM.benchmark_criteria(unc, unc, building_weight=w)])
    assert worst["J1"] == pytest.approx(1.0) and worst["force_over_weight"] == pytest.approx(800.0 / w)


def test_benchmark_criteria_without_base_shear_skip_j3_j6():
    rec = building_record()
    del rec["floor_masses"]
    m = BM.building_metrics(**rec)
    assert set(BM.benchmark_criteria(m, m)) >= {"J1", "J2", "J4", "J5"}
    assert not {"J3", "J6"} & set(BM.benchmark_criteria(m, m))


# ---------------------------------------------------------------- validation

def test_zero_uncontrolled_response_is_a_clear_error():
    unc = BM.building_metrics(**building_record())
    zero = BM.building_metrics(**building_record(scale=0.0))
    with pytest.raises(ValueError, match=r"uncontrolled\['drift_ratio_peak'\] = 0.*J1"):
        BM.benchmark_criteria(unc, zero)
    with pytest.raises(ValueError, match="controlled lacks 'base_shear_peak'"):
        BM.benchmark_criteria({k: v for k, v in unc.items() if not k.startswith("base")}, unc)


@pytest.mark.parametrize("call, match", [
    (lambda: M.weighted_rms(np.ones(100), 0.0), r"dt = 0.0 is invalid: must be .*> 0"),
    (lambda: M.weighted_rms(np.ones(100), -1e-3), r"dt = -0.001 is invalid"),
    (lambda: M.weighted_rms(np.ones(100), 0.05), r"dt = 0.05 is invalid.*Wk weighting needs"),
    (lambda: M.weighted_rms(np.r_[1.0, np.nan, 2.0], DT), r"^a contains a non-finite value.*must be finite"),
    (lambda: M.weighted_rms(np.ones(100), float("nan")), r"dt = nan is invalid: must be finite"),
    (lambda: BM.building_metrics(DT, np.full((10, 2), np.inf), 3.0, np.ones((10, 2))),
     r"^drift contains a non-finite value.*must be finite"),
    (lambda: M.weighted_rms(np.ones(100), DT, kind="Wx"), r"kind = 'Wx' is invalid: must be one of"),
    (lambda: M.weighted_rms(np.ones(100), DT, method="x"), r"method = 'x' is invalid"),
    (lambda: M.weighted_rms(np.ones(3), [0.0, 0.001, 0.003]), r"uniformly spaced"),
    (lambda: M.weighting_magnitude("Wk", [-1.0]), r"^f has values .* outside the valid range"),
    (lambda: M.vdv(np.ones((0,)), DT), r"a_w must hold at least one sample"),
    (lambda: M.running_rms(np.ones(10), DT, tau=0), r"tau = 0 is invalid: must be .*> 0"),
    (lambda: QM.quarter_car_metrics(DT, np.ones(10), np.ones(9)), r"suspension_travel must have 10 samples"),
    (lambda: QM.quarter_car_metrics(DT, np.ones((10, 2)), np.ones(10)), r"sprung_acc must be 1-dimensional"),
    (lambda: QM.quarter_car_metrics(DT, np.ones(10), np.ones(10), np.ones(10), static_tyre_load=0.0),
     r"static_tyre_load = 0.0 is invalid: must be .*> 0"),
    (lambda: QM.quarter_car_metrics(DT, np.ones(10), np.ones(10), tyre_deflection=np.ones(10)),
     r"tyre_deflection needs tyre_stiffness"),
    (lambda: BM.building_metrics(DT, np.ones((10, 2)), [3.0], np.ones((10, 2))), r"storey_heights must .* 2 entries"),
    (lambda: BM.building_metrics(DT, np.ones((10, 2)), [3.0, 0.0], np.ones((10, 2))), r"storey_heights must be > 0"),
    (lambda: BM.building_metrics(DT, np.ones((10, 2)), 3.0, np.ones((9, 2))), r"abs_acc must have 10 samples"),
    (lambda: BM.building_metrics(DT, np.ones((10, 2, 1)), 3.0, np.ones((10, 2))), r"drift must be \(n_samples"),
    (lambda: BM.building_metrics(DT, np.ones((10, 2)), 3.0, np.ones((10, 2)), floor_masses=[1.0]),
     r"floor_masses must have shape \(2,\)"),
    (lambda: BM.benchmark_criteria({"acc_peak": 1.0, "damper_force_peak": 1.0}, {"acc_peak": 1.0},
                                  building_weight=-1), r"building_weight = -1 is invalid"),
    (lambda: BM.max_over_records([{"J1": 1.0}, {"J2": 1.0}]), r"records\[1\] has keys"),
    (lambda: BM.max_over_records([]), r"records must hold at least one"),
])
def test_invalid_inputs_raise_value_error_naming_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
