"""The Mavroeidis–Papageorgiou (2003) near-fault pulse: the generated ground acceleration, integrated here by the
trapezoid rule, against the paper's closed-form velocity written out below (its peak, its period, its length), and
the pulse as the building's ground motion (a fixed record, a family drawn per episode, replayed at the building's
time scale)."""
import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.disturbances import mavroeidis_papageorgiou


def closed_form_velocity(t, A, fp, gamma, nu, t0):
    """Mavroeidis & Papageorgiou (2003), their velocity pulse: A/2 (1 + cos(2π fp (t − t0)/γ)) cos(2π fp (t − t0)
    + ν) for t0 − γ/(2 fp) ≤ t ≤ t0 + γ/(2 fp), zero elsewhere."""
    tau = t - t0
    v = A / 2 * (1 + np.cos(2 * np.pi * fp * tau / gamma)) * np.cos(2 * np.pi * fp * tau + nu)
    return np.where(np.abs(tau) <= gamma / (2 * fp), v, 0.0)


def _velocity(rec):
    a = rec.channel("xg_ddot")
    t = np.arange(a.size) * rec.dt
    return t, cumulative_trapezoid(a, t, initial=0.0)


@pytest.mark.parametrize("period, gamma, nu", [(1.0, 2.0, 0.0), (0.6, 3.0, math.pi / 2), (2.5, 1.5, 1.0)])
def test_pulse_velocity_is_the_published_closed_form(period, gamma, nu):
    A, dt = 0.8, 1e-4
    rec = mavroeidis_papageorgiou(3 * gamma * period, dt, period=period, gamma=gamma, nu=nu, amplitude=A)
    t, v = _velocity(rec)
    t0 = gamma * period / 2  # the default: the pulse starts at t = 0
    expected = closed_form_velocity(t, A, 1 / period, gamma, nu, t0)
    assert np.max(np.abs(v - expected)) < 1e-5 * A
    # nothing before the pulse, no acceleration after it
    assert np.all(rec.channel("xg_ddot")[t > t0 + gamma * period / 2 + dt] == 0.0)


def test_pulse_peak_velocity_is_A_and_its_zero_crossings_are_half_a_period_apart():
    A, period, gamma, dt = 0.5, 1.2, 3.0, 1e-4
    t, v = _velocity(mavroeidis_papageorgiou(8.0, dt, period=period, gamma=gamma, nu=0.0, amplitude=A))
    t0 = gamma * period / 2
    assert np.max(np.abs(v)) == pytest.approx(A, rel=1e-6)  # ν = 0: the carrier's crest at the envelope's peak
    assert t[np.argmax(v)] == pytest.approx(t0, abs=dt)
    inside = (t > t0 - gamma * period / 2 + 0.05) & (t < t0 + gamma * period / 2 - 0.05)
    s = np.sign(v[inside])
    crossings = t[inside][1:][s[1:] != s[:-1]]
    assert crossings.size >= 4
    np.testing.assert_allclose(np.diff(crossings), period / 2, atol=2 * dt)  # the carrier's period T_p = 1/f_p


def test_pulse_scaled_to_a_peak_ground_acceleration():
    rec = mavroeidis_papageorgiou(6.0, 1e-3, period=1.6, gamma=2.0, nu=0.0, pga=0.3 * 9.80665)
    assert np.max(np.abs(rec.channel("xg_ddot"))) == pytest.approx(0.3 * 9.80665, rel=1e-4)


@pytest.mark.parametrize("kwargs, match", [
    (dict(gamma=1.0, amplitude=1.0), "gamma"),
    (dict(period=0.0, amplitude=1.0), "period"),
    (dict(amplitude=1.0, pga=2.0), "exactly one of amplitude"),
    (dict(), "exactly one of amplitude"),
    (dict(period=0.01, amplitude=1.0), "dt must be <= period / 20"),
    (dict(amplitude=1.0, t0=0.1), "t0"),
])
def test_pulse_refuses_bad_parameters_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        mavroeidis_papageorgiou(4.0, 1e-3, **kwargs)


def _record(**params):
    env = gym.make("mrd_env/ShearBuildingPhysical-v0", ground_motion="mavroeidis_papageorgiou",
                   ground_motion_params=params, episode_seconds=2.0)
    return env.unwrapped


def test_pulse_on_the_building_replays_at_its_time_scale_and_a_family_draws_per_episode():
    fixed = _record(period=1.0, gamma=2.0, nu=0.0, amplitude=0.4)
    assert not fixed.assembly.disturbance.random
    rec = fixed.assembly.disturbance.sample(np.random.default_rng(0), 1e-3)
    t, v = _velocity(rec)
    # the lab model replays records 5× faster: a 1 s pulse lasts 2 × 0.2 s, its velocity 1/5 of A at the peak
    assert t[np.flatnonzero(rec.channel("xg_ddot"))[-1]] == pytest.approx(0.4, abs=2e-3)
    assert np.max(np.abs(v)) == pytest.approx(0.4 * 0.2, rel=1e-3)
    family = _record(period=[0.8, 1.6], gamma=(1.5, 3.0), nu=(0.0, 2 * math.pi))
    d = family.assembly.disturbance
    assert d.random
    a, b = (d.sample(np.random.default_rng(s), 1e-3).channel("xg_ddot") for s in (1, 2))
    again = d.sample(np.random.default_rng(1), 1e-3).channel("xg_ddot")
    np.testing.assert_array_equal(a, again)
    assert not np.array_equal(a, b)
    with pytest.raises(ValueError, match="gamma"):
        _record(period=1.0, gamma=(0.5, 2.0))  # every end of a range is checked when the environment is made


def test_every_ground_motion_has_its_source_and_licence():
    from mrd_env.disturbances import available_peer_records, record_provenance

    for name in (*available_peer_records(), "el_centro_classic", "kanai_tajimi", "mavroeidis_papageorgiou"):
        p = record_provenance(name)
        assert p["source"] and p["licence"] and isinstance(p["suites"], bool)
    # the suites' recorded ground motion is a US-government recording; the generated ones hold no recorded data
    assert record_provenance("el_centro_1940_180")["suites"] and "public domain" in record_provenance(
        "el_centro_1940_270")["licence"]
    assert not record_provenance("loma_prieta_1989_corralitos_000")["suites"]  # its terms were not verified
    with pytest.raises(ValueError, match="name must be one of"):
        record_provenance("kobe_1995")
