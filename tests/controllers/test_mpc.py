"""Linear MPC (controllers/mpc.py) and the sampled-data design of clipped-optimal control: against python-control's
LQR designs, numerical quadrature of the continuous cost, a brute-force bounded minimisation, the environment's own
road, and the clipped-optimal law it reduces to; the reward's own cost (weights="reward": its Wk filter, nominal
scales, the car's road frame) against the environment's reward signals and an LQR built by hand."""
import itertools
import subprocess
import sys

import control
import gymnasium as gym
import numpy as np
import pytest
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm
from scipy.optimize import minimize

import mrd_env  # noqa: F401
from controllers import MPC, ClippedOptimal, available_controllers, make_controller
from controllers.model_based import dlqr, sampled_lq, van_loan
from controllers.mpc import damper_force_limit
from experiments.common.plants import profile

CAR = "mrd_env/QuarterCarPhysical-v0"
BUILDING = "mrd_env/ShearBuildingPhysical-v0"


def _env(env_id, **options):
    return gym.make(env_id, **options).unwrapped


def _lockstep(env, a, b, seed=0):
    """Drive ``env`` with controller ``a`` while ``b`` sees the same observations; the per-step commands and
    desired forces of both."""
    obs, _ = env.reset(seed=seed)
    ua, ub, fa, fb = [], [], [], []
    while True:
        u, _ = a.predict(obs)
        v, _ = b.predict(obs)
        ua.append(u)
        ub.append(v)
        fa.append(a.last_desired[0].copy())
        fb.append(b.last_desired[0].copy())
        obs, _, term, trunc, _ = env.step(u)
        if term or trunc:
            return np.array(ua), np.array(ub), np.array(fa), np.array(fb)


@pytest.mark.parametrize("env_id,options", [(CAR, {}), (BUILDING, {"damper_floors": (2,)})])
def test_horizon_one_mpc_is_the_sampled_clipped_optimal_law(env_id, options):
    """Unconstrained, H = 1 with the Riccati terminal cost is the sampled-data LQR: the same command at every step."""
    env = _env(env_id, control_dt=0.01, episode_seconds=2.0, **options)
    mpc = MPC(env, horizon=1, f_max=1e7)
    co = ClippedOptimal(env, design="sampled")
    ua, ub, fa, fb = _lockstep(env, mpc, co)
    assert len(ua) == 200
    np.testing.assert_array_equal(ua, ub)
    np.testing.assert_allclose(fa, fb, rtol=1e-7, atol=1e-9 * np.abs(fb).max())
    assert np.abs(fb).max() > 10.0  # the law did act


def test_sampled_cost_is_the_integral_of_the_continuous_cost():
    """Van Loan's Q_d equals ∫₀ᵀ e^{Aᵀt} Q e^{At} dt by adaptive quadrature (the building: 6 states, a damper)."""
    co = ClippedOptimal(_env(BUILDING))
    d, (Q, R, N) = co.design, co.lq
    n, m = d.n, d.nd
    Ac = np.zeros((n + m, n + m))
    Ac[:n, :n], Ac[:n, n:] = d.A, d.Bf
    Qc = np.block([[Q, N], [N.T, R]])
    T = 0.01
    ref, _ = quad_vec(lambda t: expm(Ac.T * t) @ Qc @ expm(Ac * t), 0.0, T, epsrel=1e-11)
    Phi, Qd = van_loan(Ac, Qc, T)
    np.testing.assert_allclose(Qd, ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    np.testing.assert_allclose(Phi, expm(Ac * T), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("env_id", [CAR, BUILDING])
def test_sampled_design_tends_to_the_continuous_lqr(env_id):
    """The sampled-data LQR gain tends to python-control's continuous LQR gain linearly in the control period."""
    co = ClippedOptimal(_env(env_id))
    Q, R, N = co.lq
    diff = []
    for T in (1e-3, 1e-4, 1e-5):
        K, _ = dlqr(*sampled_lq(co.design.A, co.design.Bf, Q, R, N, T))
        diff.append(np.linalg.norm(K - co.K) / np.linalg.norm(co.K))
    assert all(8.0 < a / b < 12.0 for a, b in itertools.pairwise(diff))  # O(T)
    assert diff[1] < 0.02  # 0.1 ms
    if env_id == CAR:
        assert diff[0] < 0.01  # the car at 1 ms (the building's faster closed loop: 13 %)
    # and the controller's design="sampled" at the environment's control period is that design
    env = _env(env_id, control_dt=0.002)
    Kd = ClippedOptimal(env, design="sampled").K
    K2, _, _ = control.dlqr(*sampled_lq(co.design.A, co.design.Bf, Q, R, N, 0.002))
    np.testing.assert_allclose(Kd, K2, rtol=1e-8)


@pytest.mark.parametrize("env_id", [CAR, BUILDING])
def test_unconstrained_mpc_gain_is_the_discrete_lqr(env_id):
    """With the Riccati terminal cost every horizon gives python-control's infinite-horizon discrete LQR gain;
    without a terminal cost the finite-horizon gain converges to it as the horizon grows."""
    env = _env(env_id, control_dt=0.01)
    co = ClippedOptimal(env)
    Q, R, N = co.lq
    K_inf, _, _ = control.dlqr(*sampled_lq(co.design.A, co.design.Bf, Q, R, N, 0.01))
    for H in (1, 7):
        np.testing.assert_allclose(MPC(env, horizon=H, f_max=1e6).K_horizon, K_inf, rtol=1e-7)
    gaps = [np.linalg.norm(MPC(env, horizon=H, f_max=1e6, terminal="zero").K_horizon - K_inf)
            / np.linalg.norm(K_inf) for H in (2, 20, 300)]
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 1e-4


def _continuous_cost(co, x0, f, T, P=None):
    """∫₀^{HT} zᵀz + fᵀR₀f dt for forces f held over periods T, by adaptive ODE integration of [x, J]."""
    d, (Q, R, N) = co.design, co.lq
    n = d.n

    def rhs(t, s):
        fj = f[min(int(t / T), len(f) - 1)]
        x = s[:n]
        return np.concatenate([d.A @ x + d.Bf @ fj, [x @ Q @ x + 2 * x @ N @ fj + fj @ R @ fj]])

    s = np.concatenate([x0, [0.0]])
    for j in range(len(f)):  # period by period: the force jumps at the boundaries
        sol = solve_ivp(rhs, (j * T, (j + 1) * T), s, rtol=1e-11, atol=1e-14, method="DOP853")
        s = sol.y[:, -1]
    return s[n]


def test_bounded_plan_minimises_the_continuous_cost():
    """With active force bounds (OSQP's path) the plan is the bounded minimiser of the continuous-time cost
    (no terminal cost), found by L-BFGS-B on the cost integrated by an ODE solver."""
    env = _env(CAR, control_dt=0.01)
    H, f_max = 4, 150.0
    mpc = MPC(env, horizon=H, f_max=f_max, terminal="zero")
    x0 = np.array([0.01, -0.005, 0.3, -0.4])
    plan = mpc.plan(x0[None])[0, :, 0]
    assert np.max(np.abs(plan)) == pytest.approx(f_max)  # a bound is active
    s = 100.0  # in units of 100 N
    ref = minimize(lambda u: _continuous_cost(mpc, x0, (u * s)[:, None], 0.01) * 1e3, np.zeros(H),
                   method="L-BFGS-B", bounds=[(-f_max / s, f_max / s)] * H, options={"ftol": 1e-14, "gtol": 1e-10})
    np.testing.assert_allclose(plan, ref.x * s, atol=1e-3 * f_max)
    # H = 1: the bounded optimum of a scalar quadratic is the clipped unconstrained one
    one = MPC(env, horizon=1, f_max=f_max)
    x = np.random.default_rng(0).normal(0, [0.01, 0.01, 0.2, 0.5], (50, 4))
    np.testing.assert_allclose(one.plan(x)[:, 0], np.clip(-x @ one.K_horizon.T, -f_max, f_max), rtol=1e-6,
                               atol=1e-6 * f_max)


def test_bad_options_raise_value_errors_naming_them():
    env = _env(CAR)
    for bad in (0, 501, 2.5, True, "10"):
        with pytest.raises(ValueError, match="horizon"):
            MPC(env, horizon=bad)
    for bad in (0.0, -5.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="f_max"):
            MPC(env, f_max=bad)
    with pytest.raises(ValueError, match="terminal"):
        MPC(env, terminal="none")
    with pytest.raises(ValueError, match="preview"):
        MPC(env, preview="yes")
    with pytest.raises(ValueError, match="road_preview"):
        MPC(env, preview=True)  # the sensor is not measured
    with pytest.raises(ValueError, match="design"):
        MPC(env, design="continuous")
    with pytest.raises(ValueError, match="osqp"):
        MPC(env, osqp=3)
    with pytest.raises(ValueError, match="osqp"):
        MPC(env, osqp={"no_such_setting": 1})
    assert MPC(env, osqp={"max_iter": 500}, f_max=500.0).horizon == 10
    with pytest.raises(ValueError, match="design"):
        ClippedOptimal(env, design="discrete")
    with pytest.raises(ValueError, match="damper_force"):
        MPC(_env(CAR, sensors=("sprung_acc", "travel")))


def test_registered_and_optional_dependencies_stay_lazy():
    env = _env(CAR)
    assert "mpc" in available_controllers()
    assert isinstance(make_controller("mpc", env, horizon=3, f_max=500.0), MPC)
    code = ("import sys, controllers, mrd_env.envs, mrd_env.optimal.bound; "
            "assert not {'osqp', 'clarabel', 'cvxpy'} & set(sys.modules), sorted(sys.modules)")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_default_force_limit_grows_with_the_stroke_velocity():
    """The damper's force at the maximum command over a steady cycle grows with the velocity and exceeds its
    force at the minimum command (the rig)."""
    env = _env(BUILDING)
    lo, mid, hi = (damper_force_limit(env, v) for v in (0.05, 0.1, 0.2))
    assert lo < mid < hi
    assert MPC(env).f_max == pytest.approx(mid)


# --- road preview ------------------------------------------------------------------------------------------------
PREVIEW = tuple(round(0.01 * k, 2) for k in range(1, 11))


def _preview_env(**options):
    from mrd_env.plants.quarter_car.env import DEFAULT_SENSORS

    return _env(CAR, sensors=(*DEFAULT_SENSORS, "road_preview"), preview=PREVIEW, **options)


@pytest.mark.parametrize("control_dt", [0.01, 0.001])
def test_preview_memory_gives_the_road_over_the_horizon(control_dt):
    """The previewed heights of this and earlier readings are the environment's road at the horizon's period
    boundaries (to float32), at a control step equal to and ten times finer than the preview's spacing."""
    env = _preview_env(control_dt=control_dt, episode_seconds=1.0)
    H = 12
    mpc = MPC(env, horizon=H, f_max=1e4)
    assert mpc.preview
    obs, _ = env.reset(seed=3)
    road = env.record.data[:, 0]
    n_sub = int(round(control_dt / env.dt))
    for k in range(int(0.5 / control_dt)):
        a, _ = mpc.predict(obs)
        rows = (k + np.arange(H + 1)) * n_sub
        inside = np.arange(H + 1) * control_dt <= PREVIEW[-1] + 1e-12
        if k * control_dt >= PREVIEW[0]:  # the memory holds the road under the wheel
            np.testing.assert_allclose(mpc.last_road[0, inside, 0], road[rows[inside]], atol=1e-6)
        obs, *_ = env.step(a)


def test_preview_acts_before_the_bump_and_pays():
    """On a bump 0.5 s into the episode the preview MPC commands exactly as the blind one until the bump enters the
    preview window (0.4 s), acts differently before it reaches the wheel, and scores a better return."""
    opts = dict(road="bump", road_params={"height": 0.05, "length": 0.5, "speed": 10.0, "t_start": 0.5},
                control_dt=0.01, episode_seconds=2.0)
    env = _preview_env(**opts)
    seen, blind = MPC(env, horizon=20), MPC(env, horizon=20, preview=False)
    _, _, fa, fb = _lockstep(env, seen, blind)
    t = np.arange(len(fa)) * 0.01
    early = t < 0.4 - 1e-9
    np.testing.assert_allclose(fa[early], fb[early], rtol=1e-9, atol=1e-9)
    window = (t >= 0.4 - 1e-9) & (t < 0.5 - 1e-9)
    assert np.max(np.abs(fa[window] - fb[window])) > 50.0
    assert _returns(env, seen, [0])[0] > _returns(env, blind, [0])[0]


# --- the reward's own cost (weights="reward") -----------------------------------------------------------------------
def _car_road(seconds, dt=1e-3, seed=0):
    from mrd_env.disturbances import iso8608_road

    return iso8608_road("C", 20.0, seconds, dt, rng=seed, method="fft")


def test_continuous_filter_is_the_analog_prototype_of_the_rewards_wk_filter():
    """The continuous realisation of the car's Wk sections is the filter whose bilinear transform they are: its
    response at the pre-warped frequency equals the digital filter's; below 20 Hz it is ISO 2631's analog Wk."""
    import scipy.signal

    from controllers.model_based import continuous_filter
    from mrd_env.metrics import weighting_magnitude

    env = _env(CAR)
    (src, out, sos), = env.assembly.filters
    assert (src, out) == ("sprung_acc", "sprung_acc_wk")
    T = env.dt
    A, B, C, D = continuous_filter(sos, T)
    assert np.all(np.linalg.eigvals(A).real < 0)

    def H(s):
        return (C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D)[0, 0]

    f = np.array([0.2, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 50.0, 120.0, 300.0])
    _, Hd = scipy.signal.sosfreqz(sos, worN=f, fs=1.0 / T)
    Hc = np.array([H(2j / T * np.tan(np.pi * fi * T)) for fi in f])
    np.testing.assert_allclose(Hc, Hd, rtol=1e-8)
    low = f < 20.0
    np.testing.assert_allclose([abs(H(2j * np.pi * fi)) for fi in f[low]], weighting_magnitude("Wk", f[low]),
                               rtol=1e-3)


@pytest.mark.parametrize("frame", ["absolute", "road"])
def test_reward_cost_outputs_are_the_rewards_signals(frame):
    """The design's weighted outputs, driven by the passive car (the set's dashpot as the force) on a road, have
    the reward's mean squares: Wk-weighted sprung acceleration, travel and tyre load as
    :func:`~mrd_env.plants.quarter_car.env.passive_reference` computes them (exact simulation and scipy's digital Wk)."""
    from mrd_env.plants.quarter_car.env import passive_reference
    from mrd_env.mechanics.response import foh_response

    env = _env(CAR)
    co = ClippedOptimal(env, weights={"sprung_acc_wk": 1.0, "travel": 1.0, "_tyre_load": 1.0}, frame=frame)
    d, (Cz, Dz, Dzw) = co.design, co.cost
    assert d.frame == frame and d.n == 4 + 8  # the plant and the Wk filter's four sections
    c = env.plant_params.passive_c
    Cv = d.signal("travel_rate")[0]
    rec = _car_road(10.0)
    w = rec.data
    x0 = np.zeros(d.n)
    x0[2:4] = w[0, 1]
    if frame == "absolute":
        x0[:2] = w[0, 0]
    X = foh_response(d.A + c * d.Bf @ Cv, d.Bw, w, env.dt, x0=x0)  # f = c·(travel rate): dissipative
    z = X @ (Cz + c * Dz @ Cv).T + w @ Dzw.T
    ms = np.mean(z[1:] ** 2, axis=0)
    z0, zd0 = w[0]
    ref = passive_reference(env.plant_params, rec, np.array([z0, z0, zd0, zd0]), rec.n_samples, env.dt)
    np.testing.assert_allclose(ms, [ref["comfort"], ref["travel"], ref["tyre"]], rtol=2e-3)


def test_reward_weights_are_the_reward_over_the_nominal_passive_car():
    """weights="reward" on the car: the reward's weights over the passive car's mean squares on the nominal class-C
    road at 20 m/s (100 s), so that the passive car costs 1 per second there; on the building over the
    uncontrolled building's; the reward's own weights (reward_weights) are followed."""
    from controllers.model_based import nominal_reference, reward_weights
    from mrd_env.plants.quarter_car.env import NOMINAL_ROAD
    from mrd_env.plants.quarter_car.env import passive_reference

    env = _env(CAR)
    rec = _car_road(NOMINAL_ROAD["duration"], seed=NOMINAL_ROAD["seed"])
    z0, zd0 = rec.data[0]
    ref = passive_reference(env.plant_params, rec, np.array([z0, z0, zd0, zd0]), rec.n_samples, env.dt)
    w = reward_weights(env)
    assert set(w) == {"sprung_acc_wk", "travel", "_tyre_load"}
    np.testing.assert_allclose([w["sprung_acc_wk"], w["travel"], w["_tyre_load"]],
                               [0.5 / ref["comfort"], 0.25 / ref["travel"], 0.25 / ref["tyre"]], rtol=1e-12)
    assert 0.1 < ref["comfort"] / 1.0 < 10.0 and 0.005 < np.sqrt(ref["travel"]) < 0.03  # a class-C road
    w2 = reward_weights(_env(CAR, reward_weights={"comfort": 1.0, "travel": 0.0, "tyre": 0.5}))
    np.testing.assert_allclose([w2["sprung_acc_wk"], w2["travel"], w2["_tyre_load"]],
                               [1.0 / ref["comfort"], 0.0, 0.5 / ref["tyre"]], rtol=1e-12)
    b = _env(BUILDING, damper_floors=(2,))
    wb, rb = reward_weights(b), nominal_reference(b)
    np.testing.assert_allclose(wb["drift"], np.full(3, 0.5 / rb["drift"]))
    np.testing.assert_allclose(wb["abs_acc"], np.full(3, 0.5 / rb["abs_acc"]))
    assert ClippedOptimal(b, weights="reward").design.frame == "absolute"


def _tustin_analog(sos, T):
    """A state-space model of the analog filter whose bilinear transform at T is the digital ``sos``: in each
    section z⁻¹ = (1 − sT/2)/(1 + sT/2) substituted by numpy polynomial algebra, realised by python-control
    (tf2ss, series) — independent of controllers.model_based.continuous_filter."""
    p, m = np.array([T / 2, 1.0]), np.array([-T / 2, 1.0])  # 1 + sT/2, 1 − sT/2

    def sub(c):  # (1 + sT/2)² (c₀ + c₁z⁻¹ + c₂z⁻²)
        return c[0] * np.polymul(p, p) + c[1] * np.polymul(m, p) + c[2] * np.polymul(m, m)

    out = None
    for row in np.atleast_2d(sos):
        num, den = sub(row[:3]), sub(row[3:])
        num = np.where(np.abs(num) < 1e-12 * np.abs(num).max(), 0.0, num)
        num = np.trim_zeros(num, "f")
        sec = control.tf2ss(control.tf(num, den))
        out = sec if out is None else control.series(out, sec)
    return out


def test_reward_weighted_horizon_one_gain_is_the_sampled_lqr_of_the_reward():
    """weights="reward", unconstrained: every horizon's first-step gain is the infinite-horizon sampled-data LQR
    (python-control) of the reward's cost built here by hand — the car in road coordinates [z_s − z_r, z_u − z_r,
    ż_s, ż_u], the analog Wk filter of the reward's sections (control.tf2ss of the substituted polynomials),
    travel and tyre load k_t(z_r − z_u) — in the gain on the car's states and in the closed-loop poles (both
    independent of how the filter is realised)."""
    env = _env(CAR, control_dt=0.01)
    from controllers.model_based import reward_weights

    w = reward_weights(env)
    p = env.plant_params
    A, Bf, _ = env.linear_plant.state_space(inertance=env.damper.inertance())
    Wk = _tustin_analog(env.assembly.filters[0][2], env.dt)
    Aw, Bw, Cw, Dw = (np.asarray(M) for M in (Wk.A, Wk.B, Wk.C, Wk.D))
    assert Aw.shape == (8, 8) and abs(Dw[0, 0]) < 1e-9
    Ca, Da = A[2:3], Bf[2:3]  # sprung acceleration
    m = Aw.shape[0]
    Aa = np.block([[A, np.zeros((4, m))], [Bw @ Ca, Aw]])
    Ba = np.vstack([Bf, Bw @ Da])
    Cz = np.vstack([np.sqrt(w["sprung_acc_wk"]) * np.hstack([np.zeros((1, 4)), Cw]),
                    np.sqrt(w["travel"]) * np.hstack([[[1.0, -1.0, 0.0, 0.0]], np.zeros((1, m))]),
                    np.sqrt(w["_tyre_load"]) * np.hstack([[[0.0, -p.k_t, 0.0, -p.c_t]], np.zeros((1, m))])])
    Q, R, N = Cz.T @ Cz, np.eye(1) / 1000.0 ** 2, np.zeros((4 + m, 1))
    Phi, Gam, Qd, Rd, Nd = sampled_lq(Aa, Ba, Q, R, N, 0.01)
    K_ref, _, poles_ref = control.dlqr(Phi, Gam, Qd, Rd, Nd)
    for H in (1, 5):
        mpc = MPC(env, weights="reward", force_ref=1000.0, horizon=H, f_max=1e7)
        assert mpc.design.frame == "road"
        np.testing.assert_allclose(mpc.K_horizon[:, :4], K_ref[:, :4], rtol=1e-5)
    co = ClippedOptimal(env, weights="reward", force_ref=1000.0, design="sampled")
    np.testing.assert_allclose(co.K[:, :4], K_ref[:, :4], rtol=1e-5)
    np.testing.assert_allclose(np.sort_complex(co.closed_loop_poles), np.sort_complex(poles_ref), rtol=1e-6,
                               atol=1e-9)


def test_road_frame():
    """frame="road": the road enters through its velocity alone, the tyre load and the unsprung acceleration are
    functions of the state (the latter becomes a measurement), the plant settles at 0 under any road height; it
    needs a road input."""
    env = _env(CAR)
    co = ClippedOptimal(env, frame="road")
    d = co.design
    np.testing.assert_array_equal(d.Bw[:, 0], 0.0)
    np.testing.assert_allclose(d.Bw[:, 1], [-1.0, -1.0, 0.0, 0.0])
    for name in ("_tyre_load", "unsprung_acc", "sprung_acc", "travel"):
        np.testing.assert_array_equal(d.signal(name)[2], 0.0)  # c_t = 0 on set A
    assert "unsprung_acc" in co.measurements and "unsprung_acc" not in ClippedOptimal(env).measurements
    # the same dynamics: the absolute design's K is the road frame's for the objective's shift-invariant weights
    np.testing.assert_allclose(co.K, ClippedOptimal(env).K, rtol=1e-9)
    mpc = MPC(_preview_env(control_dt=0.01), weights="reward", horizon=3)
    assert mpc.design.frame == "road" and mpc.preview
    np.testing.assert_array_equal(mpc.steady_state, 0.0)
    with pytest.raises(ValueError, match="road input"):
        ClippedOptimal(_env(BUILDING), frame="road")


def _returns(env, ctrl, seeds):
    out = []
    for s in seeds:
        obs, _ = env.reset(seed=s)
        ctrl.reset()
        total = 0.0
        while True:
            a, _ = ctrl.predict(obs)
            obs, r, term, trunc, _ = env.step(a)
            total += r
            if term or trunc:
                break
        out.append(total)
    return np.array(out)


def test_reward_weights_beat_the_objective_on_validation_episodes():
    """On validation episodes (seeds training never draws): the car with road preview at 10 ms (3 s of four
    roads, force_ref 200 N as tuned) and the building at 10 ms (four records) score better with the reward's own
    cost than with the objective's, in total and on most episodes."""
    from experiments.common.scenarios import validation

    car = validation(profile("quarter_car"))[0]
    env = _preview_env(**{**car.options, "episode_seconds": 3.0}, control_dt=0.01)
    seeds = car.seeds[:4]
    old = _returns(env, MPC(env), seeds)
    new = _returns(env, MPC(env, weights="reward", force_ref=200.0, f_max=1e5), seeds)
    assert new.sum() > old.sum() + 0.5 and np.all(new > old)
    bld = validation(profile("shear_building"))[0]
    env = gym.make(bld.env_id, **bld.options, control_dt=0.01).unwrapped
    seeds = bld.seeds[:4]
    old = _returns(env, MPC(env), seeds)
    new = _returns(env, MPC(env, weights="reward"), seeds)
    assert new.sum() > old.sum() + 0.1 and np.all(new > old)


def test_bad_reward_options_raise_value_errors_naming_them():
    env = _env(CAR)
    with pytest.raises(ValueError, match="weights"):
        ClippedOptimal(env, weights="objective")
    with pytest.raises(ValueError, match="weights"):
        MPC(env, weights=3)
    with pytest.raises(ValueError, match="frame"):
        MPC(env, frame="wheel")
    with pytest.raises(ValueError, match="cannot regulate 'damper_force'"):
        ClippedOptimal(env, weights={"damper_force": 1.0})


@pytest.mark.parametrize("env_id", [CAR, BUILDING])
def test_an_absurd_but_finite_observation_gives_a_command_in_range(env_id):
    """Observations of 1e20 (OSQP stops on such a QP): the command is the clipped unconstrained optimum, finite
    and within [v_min, v_max], not an error."""
    env = _env(env_id)
    obs, _ = env.reset(seed=0)
    ctrl = MPC(env)
    for big in (1e20, -1e20):
        u, _ = ctrl.predict(np.full_like(obs, big))
        assert np.isfinite(u).all() and (u >= ctrl.v_min).all() and (u <= ctrl.v_max).all()
