"""Plants coupled to dampers: 1 kHz coupled integration against tight-tolerance references (LSODA; Radau too in
the slow tier), and the linear limits against
python-control (issue: plants and environments)."""
import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mrd_env import make_damper
from mrd_env.disturbances import el_centro, iso8608_road
from mrd_env.plants import CoupledPlant
from mrd_env.plants.quarter_car import quarter_car
from mrd_env.plants.shear_building import shear_building

from tests.reference_models import REFERENCE_METHODS, bouc_wen_zdot, nrmse

DT = 1e-3


def run_plant(plant_params, damper, w, V):
    """Simulate from rest over the whole input record w (n + 1, n_inputs) with constant command V."""
    n = w.shape[0] - 1
    cp = CoupledPlant(plant_params.plant(), damper, N=1, n_steps=n, dt=DT)
    F, Y = cp.step(np.full((1, n, cp.plant.n_dampers), V), w[None])
    W = cp.inputs(w[None])[:, 1:]
    return F[0].copy(), Y[0].copy(), cp.accelerations(Y, F, W)[0]


def sd_terms(p, u, x, xd, y, z):
    """Spencer–Dyke (review eq. 12): ẏ, ż and the force, written independently of the library."""
    c0, c1, al = p.c0a + p.c0b * u, p.c1a + p.c1b * u, p.alpha_a + p.alpha_b * u
    yd = (al * z + c0 * xd + p.k0 * (x - y)) / (c0 + c1)
    return yd, bouc_wen_zdot(z, xd - yd, p.A, p.beta, p.gamma, p.n), c1 * yd + p.k1 * (x - p.x0)


@pytest.mark.parametrize("method", REFERENCE_METHODS)
def test_quarter_car_with_spencer_dyke_matches_the_tight_reference_on_class_c_road(method):
    qc = quarter_car("set_a")
    d = make_damper("spencer_dyke", "automotive")
    p, V = d.params, 1.0
    T = 3.0
    road = iso8608_road("C", speed=20.0, duration=T, dt=DT, rng=11)
    w = road.data
    F, Y, acc = run_plant(qc, d, w, V)
    F_static = -p.k1 * p.x0  # balanced at rest (coordinates from static equilibrium)
    t_grid = road.t

    # the effective command starts at v_min = 0 and lags towards V: u̇ = −η(u − V)
    eta = d.command.eta

    def full(t, s):
        u = s[6]
        zs, zu, vs, vu, y, z = s[:6]
        zr, vr = np.interp(t, t_grid, w[:, 0]), np.interp(t, t_grid, w[:, 1])
        yd, zd, Fd = sd_terms(p, u, zs - zu, vs - vu, y, z)
        as_ = (-qc.k_s * (zs - zu) - (Fd - F_static)) / qc.m_s
        au = (qc.k_s * (zs - zu) + (Fd - F_static) - qc.k_t * (zu - zr) - qc.c_t * (vu - vr)) / qc.m_u
        return [vs, vu, as_, au, yd, zd, -eta * (u - V)]

    sol = solve_ivp(full, (0, T), np.zeros(7), method=method, rtol=1e-9, atol=1e-12, t_eval=t_grid[1:],
                    max_step=DT)
    assert sol.success
    zs, zu, vs, vu, y, z, u = sol.y
    _, _, F_ref = sd_terms(p, u, zs - zu, vs - vu, y, z)
    acc_ref = (-qc.k_s * (zs - zu) - (F_ref - F_static)) / qc.m_s
    assert nrmse(acc[:, 0], acc_ref) <= 0.01
    assert nrmse(F[:, 0], F_ref) <= 0.01
    assert nrmse(Y[:, 0] - Y[:, 1], zs - zu) <= 0.01


@pytest.mark.parametrize("method", REFERENCE_METHODS)
def test_three_storey_building_with_spencer_dyke_matches_the_tight_reference_on_el_centro(method):
    b = shear_building("three_storey")
    d = make_damper("spencer_dyke", "spencer1997")
    p, V = d.params, 1.0
    rec = el_centro("NS", time_scale=0.2, dt=DT)
    T = 4.0
    w = rec.data[: int(T / DT) + 1]
    F, Y, _ = run_plant(b, d, w, V)
    M = np.diag([98.3] * 3)
    K = 1e5 * np.array([[12.0, -6.84, 0], [-6.84, 13.7, -6.84], [0, -6.84, 6.84]])
    C = np.array([[175.0, -50, 0], [-50, 100, -50], [0, -50, 50]])
    Minv = np.linalg.inv(M)
    G = np.array([-1.0, 0, 0])  # damper location vector Γ (reference page)
    F_static = -p.k1 * p.x0
    eta = d.command.eta
    t_grid = np.arange(len(w)) * DT

    def full(t, s):
        x, v, y, z, u = s[:3], s[3:6], s[6], s[7], s[8]
        ag = np.interp(t, t_grid, w[:, 0])
        yd, zd, Fd = sd_terms(p, u, x[0], v[0], y, z)
        a = Minv @ (-C @ v - K @ x + G * (Fd - F_static)) - ag
        return np.concatenate([v, a, [yd, zd, -eta * (u - V)]])

    sol = solve_ivp(full, (0, T), np.zeros(9), method=method, rtol=1e-9, atol=1e-12, t_eval=t_grid[1:],
                    max_step=DT)
    assert sol.success
    x = sol.y[:3]
    drift_ref = np.vstack([x[0], x[1] - x[0], x[2] - x[1]])
    drift = np.stack([Y[:, 0], Y[:, 1] - Y[:, 0], Y[:, 2] - Y[:, 1]])
    for i in range(3):
        assert nrmse(drift[i], drift_ref[i]) <= 0.01, f"drift {i + 1}"
    _, _, F_ref = sd_terms(p, sol.y[8], x[0], sol.y[3], sol.y[6], sol.y[7])
    assert nrmse(F[:, 0], F_ref) <= 0.01


def linear_dashpot(c):
    """A Bingham damper with no friction and no offset is the linear dashpot F = c ẋ."""
    return make_damper("bingham", fc_a=0.0, fc_b=0.0, c0a=c, c0b=0.0, f0=0.0)


@pytest.mark.parametrize("f", [1.0, 3.0, 11.0, 20.0])
def test_quarter_car_with_dashpot_matches_python_control_frequency_response(f):
    qc = quarter_car("set_a")
    c = 1500.0
    ms, mu, ks, kt = 320.0, 40.0, 22000.0, 190000.0  # reference page set A
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-ks / ms, ks / ms, -c / ms, c / ms],
                  [ks / mu, -(ks + kt) / mu, c / mu, -c / mu]])
    B = np.array([[0], [0], [0], [kt / mu]])
    Cz = np.array([[-ks / ms, ks / ms, -c / ms, c / ms]])  # sprung acceleration
    H = control.frequency_response(control.ss(A, B, Cz, 0), [2 * np.pi * f])
    gain, phase = float(np.abs(H.complex[0])), float(np.angle(H.complex[0]))
    # steady-state sinusoidal response of the 1 kHz coupled plant
    n_cycles_settle = int(np.ceil(4.0 * f)) + 5
    T = n_cycles_settle / f + 2.0 / f
    t = np.arange(int(round(T / DT)) + 1) * DT
    X = 0.01
    w = np.stack([X * np.sin(2 * np.pi * f * t), X * 2 * np.pi * f * np.cos(2 * np.pi * f * t)], axis=1)
    _, _, acc = run_plant(qc, linear_dashpot(c), w, 0.0)
    tt = t[1:]
    last = tt > T - 2.0 / f
    basis = np.stack([np.sin(2 * np.pi * f * tt[last]), np.cos(2 * np.pi * f * tt[last])], axis=1)
    a, b = np.linalg.lstsq(basis, acc[last, 0], rcond=None)[0]
    assert np.hypot(a, b) / X == pytest.approx(gain, rel=0.01)
    assert np.angle(complex(a, b)) == pytest.approx(phase, abs=0.01)


def test_uncontrolled_building_matches_python_control_forced_response_on_el_centro():
    b = shear_building("three_storey")
    rec = el_centro("NS", time_scale=0.2, dt=DT)
    w = rec.data[: 6001]
    _, Y, _ = run_plant(b, linear_dashpot(0.0), w, 0.0)
    M = np.diag([98.3] * 3)
    K = 1e5 * np.array([[12.0, -6.84, 0], [-6.84, 13.7, -6.84], [0, -6.84, 6.84]])
    C = np.array([[175.0, -50, 0], [-50, 100, -50], [0, -50, 50]])
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Minv @ K, -Minv @ C]])
    B = np.vstack([np.zeros((3, 1)), -np.ones((3, 1))])
    sys_c = control.ss(A, B, np.eye(6), 0)
    t = np.arange(len(w)) * DT
    # forced_response on the same linearly interpolated input: first-order hold discretisation
    resp = control.forced_response(control.c2d(sys_c, DT, method="foh"), T=t, U=w[:, 0])
    x_ref = resp.outputs[:3, 1:]
    for i in range(3):
        assert nrmse(Y[:, i], x_ref[i]) <= 0.01, f"floor {i + 1}"


def test_plant_validation_errors():
    with pytest.raises(ValueError, match="m_s"):
        quarter_car("set_a", m_s=-1.0)
    with pytest.raises(ValueError, match="unknown quarter-car preset"):
        quarter_car("set_z")
    with pytest.raises(ValueError, match="masses must all be > 0"):
        shear_building("three_storey", masses=(98.3, -1.0, 98.3))
    with pytest.raises(ValueError, match="damper_floors"):
        shear_building("three_storey", damper_floors=(4,))
    with pytest.raises(ValueError, match="whole floor numbers"):
        shear_building("three_storey", damper_floors=(1.5,))
    with pytest.raises(ValueError, match="damper_floors"):
        shear_building("three_storey", damper_floors=("ab",))


def test_plant_at_rest_stays_at_rest_despite_damper_preload():
    d = make_damper("spencer_dyke", "automotive")
    F, Y, acc = run_plant(quarter_car("set_b"), d, np.zeros((501, 2)), 0.0)
    assert np.max(np.abs(Y[:, :4])) < 1e-12
    assert np.allclose(F, -d.params.k1 * d.params.x0)
