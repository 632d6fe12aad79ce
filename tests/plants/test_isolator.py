"""The MR isolator (issue 38 item 6: a fourth plant, its folder and one registry line): its 1 kHz physics against a
tight-tolerance reference (LSODA; Radau too in the slow tier) of the base-excited equation written here in absolute
coordinates, the textbook transmissibility of its linear limit, the damper's dissipation, the Gymnasium contract of
both ids, option errors, and every command reaching it through ``--plant isolator``."""
import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mrd_env  # noqa: F401  (registers the environments)
from experiments.cli import main
from experiments.common.plants import profile
from mrd_env import make_damper
from mrd_env.plants import CoupledPlant, plant
from mrd_env.plants.isolator import isolator

from tests.plants.contract import (check_reset_reproduces_an_episode, check_train_then_score,
                                   check_vector_steps_as_scalar_ones)
from tests.reference_models import REFERENCE_METHODS, bouc_wen_zdot, nrmse

V0 = "mrd_env/IsolatorPhysical-v0"
V1 = "mrd_env/Isolator-v1"
DT = 1e-3
SHORT = {"episode_seconds": 0.5}
M, K = 100.0, 8883.0   # the "seat" preset: 100 kg, 1.5 Hz, no parallel dashpot


def test_the_registry_line_makes_both_ids_and_the_preset_is_the_documented_one():
    spec = plant("isolator")
    assert spec.ids == (V0, V1) and spec.name == "isolator"
    p = isolator("seat")
    assert (p.m, p.k, p.c_p) == (M, K, 0.0)
    assert abs(math.sqrt(K / M) / (2 * math.pi) - 1.5) < 1e-4
    assert "illustrative" in p.source


# --- (a) the physics against a tight reference -------------------------------------------------------------------
# the base: three waves of 1 − cos (at rest at t = 0, as the payload): z_b = Σ A_i (1 − cos ω_i t)
WAVES = ((0.02, 1.3), (0.005, 3.7), (0.001, 9.0))   # (m, Hz): base accelerations 1.3, 2.7, 3.2 m/s²


def base(t):
    z = zd = zdd = 0.0
    for a, f in WAVES:
        w = 2 * math.pi * f
        z += a * (1 - np.cos(w * t))
        zd += a * w * np.sin(w * t)
        zdd += a * w * w * np.cos(w * t)
    return z, zd, zdd


@pytest.mark.parametrize("method", REFERENCE_METHODS)
def test_isolator_with_spencer_dyke_matches_the_tight_reference_on_a_smooth_base_motion(method):
    """m ẍ = −k (x − z_b) − (F − F_static) in the payload's absolute coordinate x, the Spencer–Dyke damper (review
    eq. 12) on the stroke x − z_b, integrated by ``method`` (rtol 1e-10) from the equation written here; the plant
    steps in the stroke coordinate, driven by the sampled base acceleration."""
    T, V = 2.0, 0.3
    d = make_damper("spencer_dyke", "automotive")
    p, eta = d.params, d.command.eta
    F_static = -p.k1 * p.x0                       # the accumulator's preload, balanced at rest

    n = int(round(T / DT))
    t_grid = np.arange(n + 1) * DT
    w = np.array([base(t) for t in t_grid])     # z_b, ż_b, z̈_b at 1 kHz
    cp = CoupledPlant(isolator("seat").plant(), d, N=1, n_steps=n, dt=DT)
    F, Y = cp.step(np.full((1, n, 1), V), w[None])
    acc = cp.accelerations(Y, F, cp.inputs(w[None])[:, 1:])[0, :, 0] + w[1:, 2]   # absolute: ẍ_d + z̈_b
    F, stroke = F[0, :, 0].copy(), Y[0, :, 0].copy()

    def terms(x, v, y, z, u, t):
        zb, zbd, _ = base(t)
        xd, vd = x - zb, v - zbd
        c0, c1, al = p.c0a + p.c0b * u, p.c1a + p.c1b * u, p.alpha_a + p.alpha_b * u
        yd = (al * z + c0 * vd + p.k0 * (xd - y)) / (c0 + c1)
        return xd, yd, bouc_wen_zdot(z, vd - yd, p.A, p.beta, p.gamma, p.n), c1 * yd + p.k1 * (xd - p.x0)

    def rhs(t, s):
        x, v, y, z, u = s
        xd, yd, zd, Fd = terms(x, v, y, z, u, t)
        return [v, (-K * xd - (Fd - F_static)) / M, yd, zd, -eta * (u - V)]

    sol = solve_ivp(rhs, (0.0, T), np.zeros(5), method=method, rtol=1e-10, atol=1e-12, t_eval=t_grid[1:],
                    max_step=DT)
    assert sol.success
    x, v, y, z, u = sol.y
    xd_ref, _, _, F_ref = terms(x, v, y, z, u, t_grid[1:])
    acc_ref = (-K * xd_ref - (F_ref - F_static)) / M
    # stroke, damper force and payload acceleration within 0.1 % (measured: 0.021 %, 0.052 %, 0.050 %)
    assert nrmse(stroke, xd_ref) <= 1e-3
    assert nrmse(F, F_ref) <= 1e-3
    assert nrmse(acc, acc_ref) <= 1e-3
    # the damper works: its force varies by hundreds of newtons and the payload moves against the base
    assert np.ptp(F_ref) > 500.0 and np.sqrt(np.mean(xd_ref ** 2)) > 3e-3


# --- (b) the linear limit: the textbook transmissibility -----------------------------------------------------------
def transmissibility(r, zeta):
    """Base excitation of a viscously damped oscillator (e.g. Rao, Mechanical Vibrations, §3.6): |X/Z_b| =
    |ẍ/z̈_b| = √((1 + (2ζr)²) / ((1 − r²)² + (2ζr)²))."""
    return math.sqrt((1 + (2 * zeta * r) ** 2) / ((1 - r * r) ** 2 + (2 * zeta * r) ** 2))


@pytest.mark.parametrize("r", [0.5, 1.0, math.sqrt(2.0), 2.0, 3.0])
def test_a_viscous_damper_gives_the_textbook_transmissibility(r):
    """Bingham with no yield force and no offset is the dashpot F = c ẋ_d; under a harmonic base the payload's
    steady absolute acceleration over the base's is T(r), to 0.5 %."""
    zeta = 0.2
    c = 2 * zeta * math.sqrt(K * M)
    f = r * math.sqrt(K / M) / (2 * math.pi)
    amp = 1e-3
    env = gym.make(V0, damper="bingham", damper_params={"fc_a": 0.0, "fc_b": 0.0, "c0a": c, "c0b": 0.0, "f0": 0.0},
                   base_motion="harmonic", base_motion_params={"amplitude": amp, "frequency": f},
                   episode_seconds=12.0)
    env.reset(seed=0)
    while not env.step(env.action_space.low)[3]:
        pass
    base_env = env.unwrapped
    acc = base_env.signal("payload_acc")[:, 0]
    t = np.arange(acc.size) * DT
    tail = t >= 8.0                               # the transient has decayed by e^(−ζ ω_n 8 s) ≈ 3e-7
    wt = 2 * math.pi * f * t[tail]
    coef, *_ = np.linalg.lstsq(np.column_stack([np.sin(wt), np.cos(wt), np.ones_like(wt)]), acc[tail], rcond=None)
    ratio = math.hypot(coef[0], coef[1]) / (amp * (2 * math.pi * f) ** 2)
    # measured: within 0.009 % at every r (the 1 kHz step and the sampled base)
    assert abs(ratio / transmissibility(r, zeta) - 1) < 5e-3, (ratio, transmissibility(r, zeta))


# --- (c) the damper dissipates -------------------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["low", "high", "random"])
def test_the_damper_dissipates_energy_over_an_episode(command):
    """The work done on the damper, ∫ F ẋ_d dt, is positive at the lowest, the highest and random commands, and
    nearly all of it is dissipated: the energy its conservative parts hold at the end — the accumulator k1 (from
    the stroke), the spring k0 (from the internal displacement y) and at most α z_s²/(2A) in the Bouc–Wen
    element — is under 5 % of it."""
    env = gym.make(V0, base_motion={"kind": "random", "acc_rms": 2.0}, episode_seconds=5.0,
                   sensors=("stroke", "damper_states"))
    env.reset(seed=5)
    env.action_space.seed(5)
    while True:
        a = env.action_space.sample() if command == "random" else getattr(env.action_space, command)
        if env.step(a)[3]:
            break
    base_env = env.unwrapped
    F, v, x = (base_env.signal(s)[:, 0] for s in ("damper_force", "stroke_rate", "stroke"))
    y = base_env.signal("damper_states")[:, 0]
    work = float(np.sum(0.5 * (F[1:] * v[1:] + F[:-1] * v[:-1])) * DT)
    p = base_env.damper.params
    accumulator = 0.5 * p.k1 * ((x[-1] - p.x0) ** 2 - p.x0 ** 2)
    spring = 0.5 * p.k0 * (x[-1] - y[-1]) ** 2
    hysteretic = (p.alpha_a + 2.0 * p.alpha_b) * (p.A / (p.beta + p.gamma)) / (2.0 * p.A)
    assert work > 1.0 and abs(accumulator) + spring + hysteretic < 0.05 * work, (work, accumulator, spring)


# --- (d) the Gymnasium contract ------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", [V0, V1])
def test_both_ids_pass_the_checker_and_reset_reproduces_an_episode(env_id):
    check_reset_reproduces_an_episode(env_id, SHORT, 500 if env_id == V0 else 50)


def test_the_vector_environment_steps_as_the_scalar_ones():
    check_vector_steps_as_scalar_ones(V0, SHORT, n_dampers=1)


def test_signals_roles_and_the_starting_state():
    env = gym.make(V0, base_motion="harmonic", **SHORT)
    env.reset(seed=0)
    base_env = env.unwrapped
    assert base_env.roles == {"body_velocity": "payload_vel", "wheel_velocity": "base_vel",
                              "damper_velocity": "stroke_rate", "damper_stroke": "stroke",
                              "damper_force": "damper_force"}
    assert np.array_equal(base_env.plant_state, [0.0, 0.0])         # moving with the base: no stroke, no rate
    for _ in range(50):
        env.step(env.action_space.high)
    s = {k: base_env.signal(k)[:, 0] for k in ("stroke", "stroke_rate", "payload_vel", "base_vel", "_x", "_base")}
    np.testing.assert_allclose(s["_x"] - s["_base"], s["stroke"], atol=1e-15)
    np.testing.assert_allclose(s["payload_vel"] - s["base_vel"], s["stroke_rate"], atol=1e-15)
    amp, f = 0.01, 1.5   # the harmonic kind's defaults
    t = np.arange(s["_base"].size) * DT
    np.testing.assert_allclose(s["_base"], amp * np.sin(2 * np.pi * f * t), atol=1e-15)
    np.testing.assert_allclose(s["base_vel"], amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t), atol=1e-13)


def test_the_random_base_motion_has_its_rms_its_band_and_a_new_draw_per_seed():
    env = gym.make(V0, base_motion={"kind": "random", "acc_rms": 1.5, "f_low": 1.0, "f_high": 5.0})
    env.reset(seed=1)
    rec = env.unwrapped.record
    assert rec.n_samples == 10_001 and np.array_equal(rec.data[0], rec.data[-1])   # one period, closed
    z, zd, zdd = rec.data[:-1].T
    assert abs(np.sqrt(np.mean(zdd ** 2)) - 1.5) < 1e-9
    # the three channels are one motion: the derivative of the displacement is the velocity, and so on
    for lo, hi in ((z, zd), (zd, zdd)):
        np.testing.assert_allclose(np.gradient(lo, DT)[5:-5], hi[5:-5], atol=2e-3 * np.abs(hi).max())
    spectrum = np.abs(np.fft.rfft(zdd))
    freqs = np.fft.rfftfreq(zdd.size, DT)
    assert spectrum[(freqs < 0.99) | (freqs > 5.01)].max() < 1e-9 * spectrum.max()
    env.reset(seed=2)
    assert not np.array_equal(env.unwrapped.record.data, rec.data)
    # a short episode is the start of a 10 s period (lines 0.1 Hz apart, whatever the episode's length)
    short = gym.make(V0, base_motion={"kind": "random", "acc_rms": 1.5, "f_low": 1.0, "f_high": 5.0},
                     episode_seconds=0.05)
    short.reset(seed=1)
    assert np.array_equal(short.unwrapped.record.data, rec.data[:51])


@pytest.mark.parametrize("sweep", ["log", "linear"])
def test_the_sweep_is_one_motion_in_its_three_channels(sweep):
    """The sweep's displacement and velocity are :func:`mrd_env.disturbances.sine_sweep`'s; its acceleration,
    derived here, is their derivative (to the central difference's (ω dt)²/6 at 10 Hz)."""
    from mrd_env.disturbances import sine_sweep

    env = gym.make(V0, base_motion={"kind": "sine_sweep", "sweep": sweep})
    env.reset(seed=0)
    z, zd, zdd = env.unwrapped.record.data.T
    np.testing.assert_array_equal(np.column_stack([z, zd]), sine_sweep(0.002, 0.5, 10.0, 10.0, kind=sweep).data)
    np.testing.assert_allclose(np.gradient(zd, DT)[1:-1], zdd[1:-1], atol=1e-3 * np.abs(zdd).max())


# --- (e) bad options -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("options, match", [
    ({"plant_preset": "washing_machine"}, "isolator preset"),
    ({"plant_params": {"m": -1.0}}, "IsolatorParams.m"),
    ({"plant_params": {"mass": 1.0}}, "unknown isolator parameter"),
    ({"base_motion": "earthquake"}, "base_motion: unknown kind"),
    ({"base_motion": "harmonic", "base_motion_params": {"amplitude": 0.0}}, r"base_motion_params\['amplitude'\]"),
    ({"base_motion": "harmonic", "base_motion_params": {"frequency": 600.0}}, r"base_motion_params\['frequency'\]"),
    ({"base_motion": "random", "base_motion_params": {"acc_rms": (2.0, 1.0)}}, "acc_rms"),
    ({"base_motion": "random", "base_motion_params": {"f_low": 5.0, "f_high": 2.0}}, "f_high"),
    ({"base_motion": "random", "base_motion_params": {"shape": 1}}, "unknown option"),
    ({"base_motion": "sine_sweep", "base_motion_params": {"sweep": "cubic"}}, "sweep must"),
    ({"base_motion": {"kind": "harmonic"}, "base_motion_params": {"amplitude": 0.1}}, "base_motion_params"),
    ({"stroke_limit": 0.0}, "stroke_limit"),
    ({"reward_weights": {"comfort": 1.0}}, "reward_weights"),
    ({"damper_preset": "nope"}, "damper_preset"),
    ({"sensors": ("road",)}, "road"),
    ({"road": "iso8608"}, "road"),
])
def test_bad_options_raise_value_error_naming_the_option(options, match):
    with pytest.raises(ValueError, match=match):
        gym.make(V0, **options)


def test_a_record_is_a_base_motion_and_needs_its_three_channels():
    from mrd_env.disturbances import Record

    t = np.arange(501) * DT
    rec = Record(DT, np.column_stack([0.01 * np.sin(9 * t), 0.09 * np.cos(9 * t), -0.81 * np.sin(9 * t)]),
                 ("z_b", "zdot_b", "zddot_b"), ("m", "m/s", "m/s^2"), "mine")
    env = gym.make(V0, base_motion=rec, episode_seconds=None)
    env.reset(seed=0)
    assert env.spec.max_episode_steps == 500
    with pytest.raises(ValueError, match="zddot_b"):
        gym.make(V0, base_motion=Record(DT, rec.data[:, :2], ("z_b", "zdot_b"), ("m", "m/s")))


# --- (f) the commands reach it ----------------------------------------------------------------------------------
def test_the_benchmark_says_the_isolator_has_no_suite_yet(tmp_path, capsys):
    """No shipped suite is of the isolator: the benchmark says so in one line (a suite of its own: mrd-env suite
    build); its laws and MPC rows are the ones a suite of it would offer."""
    assert main(["benchmark", "--plant", "isolator", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "isolator" in err and "mrd-env suite build" in err, err
    assert not (tmp_path / "b").exists()
    laws = profile("isolator").laws
    assert {"passive_off", "hybrid", "clipped_optimal"} <= set(laws)
    assert any(label == "mpc (reward)" for label, *_ in profile("isolator").mpc)


def test_train_then_score_an_agent_on_the_isolator(tmp_path):
    check_train_then_score("isolator", V0, tmp_path)


@pytest.mark.slow
def test_the_yardstick_runs_on_the_isolator(tmp_path, monkeypatch):
    """The clairvoyant (IPOPT) on a quick test episode: about two minutes on two cores. No law beats it, and it
    beats the best constant command."""
    from experiments.benchmark.yardstick import yardsticks
    from experiments.common.scenarios import held_out_scenarios

    monkeypatch.setattr("mrd_env.optimal.cache.cache_dir", lambda: tmp_path / "optimal")
    sc = held_out_scenarios(profile("isolator"), seeds=1, quick=True)[:1]
    y = yardsticks(profile("isolator"), sc, bound=False, progress=False, backend="serial")[0]
    assert y.passive <= y.clairvoyant and all(r <= y.clairvoyant + 1e-9 for r in y.warm_starts.values())
