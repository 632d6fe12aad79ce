"""Linear MPC (controllers/mpc.py) and the sampled-data design of clipped-optimal control: against python-control's
LQR designs, numerical quadrature of the continuous cost, a brute-force bounded minimisation, the environment's own
road, and the clipped-optimal law it reduces to."""
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

CAR = "mrd_env/QuarterCar-v0"
BUILDING = "mrd_env/ShearBuilding-v0"


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
    from mrd_env.envs.quarter_car import DEFAULT_SENSORS

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
    returns = []
    for ctrl in (seen, blind):
        obs, _ = env.reset(seed=0)
        ctrl.reset()
        total = 0.0
        while True:
            a, _ = ctrl.predict(obs)
            obs, r, term, trunc, _ = env.step(a)
            total += r
            if term or trunc:
                break
        returns.append(total)
    assert returns[0] > returns[1]
