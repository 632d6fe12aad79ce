"""The half car's compiled 1 kHz step against a tight-tolerance Radau reference (rtol 1e-10) of the pitch-plane
equations written here from the published parameters, independently of :mod:`mrd_env.plants.half_car` (the
quarter car's and the building's counterparts are in ``test_plants.py``)."""
import math

import numpy as np
from scipy.integrate import solve_ivp

from mrd_env import make_damper
from mrd_env.plants import CoupledPlant
from mrd_env.plants.half_car import half_car

from tests.reference_models import nrmse

DT = 1e-3
T = 1.5
SPEED = 20.0
V = (0.5, 2.0)  # front, rear commands (V): different, so that swapped dampers would show


def test_half_car_with_bingham_dampers_matches_radau():
    hc = half_car("sedan")
    # the sedan preset: m_s 690 kg, I_y 1222 kg·m², m_uf 40 kg, m_ur 45 kg, k_sf 18 kN/m, k_sr 22 kN/m,
    # k_tf = k_tr = 192 kN/m, a = 1.3 m, b = 1.5 m; no passive dashpots, no tyre damping
    ms, Iy, muf, mur, ksf, ksr, ktf, ktr, a, b = 690.0, 1222.0, 40.0, 45.0, 18e3, 22e3, 192e3, 192e3, 1.3, 1.5
    assert (hc.m_s, hc.I_y, hc.m_uf, hc.m_ur, hc.k_sf, hc.k_sr, hc.k_tf, hc.k_tr, hc.a, hc.b, hc.c_pf, hc.c_pr) == \
        (ms, Iy, muf, mur, ksf, ksr, ktf, ktr, a, b, 0.0, 0.0)
    # Bingham (review eq. 2) without offset: F = (f_ca + f_cb u) tanh(ẋ/v_s) + (c0a + c0b u) ẋ; the command lags
    # from v_min = 0 towards V: u̇ = −η (u − V)
    d = make_damper("bingham", f0=0.0, v_s=0.1)
    p, eta = d.params, d.command.eta
    fca, fcb, c0a, c0b, vs_ = p.fc_a, p.fc_b, p.c0a, p.c0b, p.v_s

    # A smooth wavy road (body heave and pitch, wheel hop); the rear wheel meets the front wheel's road
    # (a + b)/speed later. The plant gets it sampled at 1 kHz, the reference reads it exactly (a smooth input: the
    # hold between samples differs from it by O(dt²), and Radau is not held back by kinks every sample).
    n = int(round(T / DT))
    t_grid = np.arange(n + 1) * DT
    delay = (a + b) / SPEED

    def road(t: float) -> float:
        if t <= 0.0:
            return 0.0
        waves = sum(A * math.sin(2 * math.pi * f * t) for A, f in ((0.02, 1.1), (0.008, 3.7), (0.002, 11.0)))
        return (1.0 - math.exp(-(t / 0.05) ** 2)) * waves

    zf = np.array([road(t) for t in t_grid])
    zr = np.array([road(t - delay) for t in t_grid])
    w = np.column_stack([zf, np.gradient(zf, DT), zr, np.gradient(zr, DT)])  # z_rf, ż_rf, z_rr, ż_rr

    cp = CoupledPlant(hc.plant(), d, N=1, n_steps=n, dt=DT)
    F, Y = cp.step(np.broadcast_to(np.array(V), (1, n, 2)).copy(), w[None])
    F, Y = F[0].copy(), Y[0].copy()

    def rhs(t, s):
        zs, th, zuf, zur, vs, om, vuf, vur, uf, ur = s.tolist()
        zrf, zrr = road(t), road(t - delay)
        xf, xr = zs - a * th - zuf, zs + b * th - zur  # strokes, extension positive
        xdf, xdr = vs - a * om - vuf, vs + b * om - vur
        ff = ksf * xf + (fca + fcb * uf) * math.tanh(xdf / vs_) + (c0a + c0b * uf) * xdf  # suspension forces
        fr = ksr * xr + (fca + fcb * ur) * math.tanh(xdr / vs_) + (c0a + c0b * ur) * xdr
        return [vs, om, vuf, vur, -(ff + fr) / ms, (a * ff - b * fr) / Iy, (ff - ktf * (zuf - zrf)) / muf,
                (fr - ktr * (zur - zrr)) / mur, -eta * (uf - V[0]), -eta * (ur - V[1])]

    S = np.array([[1.0, -a, -1.0, 0.0], [1.0, b, 0.0, -1.0]])  # strokes x = S q
    Minv = np.diag([1 / ms, 1 / Iy, 1 / muf, 1 / mur])
    Kq = S.T @ np.diag([ksf, ksr]) @ S + np.diag([0.0, 0.0, ktf, ktr])

    def jac(t, s):
        xd, u = S @ s[4:8], s[8:10]
        tanh = np.tanh(xd / vs_)
        J = np.zeros((10, 10))
        J[:4, 4:8] = np.eye(4)
        J[4:8, :4] = -Minv @ Kq
        J[4:8, 4:8] = -Minv @ S.T @ np.diag((fca + fcb * u) * (1 - tanh ** 2) / vs_ + c0a + c0b * u) @ S
        J[4:8, 8:10] = -Minv @ S.T @ np.diag(fcb * tanh + c0b * xd)
        J[8:10, 8:10] = -eta * np.eye(2)
        return J

    sol = solve_ivp(rhs, (0.0, T), np.zeros(10), method="Radau", rtol=1e-10, atol=1e-12, t_eval=t_grid[1:],
                    jac=jac)
    assert sol.success
    zs, th, zuf, zur, vs, om, vuf, vur, uf, ur = sol.y
    xdf, xdr = vs - a * om - vuf, vs + b * om - vur
    F_ref = np.column_stack([(fca + fcb * uf) * np.tanh(xdf / vs_) + (c0a + c0b * uf) * xdf,
                             (fca + fcb * ur) * np.tanh(xdr / vs_) + (c0a + c0b * ur) * xdr])
    q_ref = sol.y[:4].T
    # heave, pitch, front and rear wheels, and both damper forces, within 0.1 %
    # (measured: at most 0.007 % on the motions, 0.03 % on the forces)
    for j in range(4):
        assert nrmse(Y[:, j], q_ref[:, j]) <= 1e-3, j
    for j in range(2):
        assert nrmse(F[:, j], F_ref[:, j]) <= 1e-3, j
    # the pitch is excited (the rear wheel's delayed road), and the commands made the dampers differ
    assert np.sqrt(np.mean(q_ref[:, 1] ** 2)) > 1e-3
    assert abs(np.sqrt(np.mean(F_ref[:, 1] ** 2)) / np.sqrt(np.mean(F_ref[:, 0] ** 2)) - 1.0) > 0.1


def test_half_car_episode_starts_in_static_equilibrium_on_the_road():
    """Both suspension strokes and both tyre deflections are zero at reset, on a road that starts away from zero
    (until 2026-11-25 the body started at zero heave and pitch: a 430 N spring step at the first instant), and the
    strokes stay small over the first steps at a constant command."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    env = gym.make("mrd_env/HalfCarPhysical-v0")
    env.reset(seed=3)
    base = env.unwrapped
    zs, th, zf, zr = base.plant_state[:4]
    road = base.record.data[0]
    p = base.assembly.plant_params
    assert abs(road[0]) > 1e-3 and abs(road[2]) > 1e-3  # the case the old start got wrong
    assert (zf, zr) == (road[0], road[2])  # tyres undeflected
    np.testing.assert_allclose([zs - p.a * th - zf, zs + p.b * th - zr], 0.0, atol=1e-15)  # strokes zero
    for _ in range(5):
        env.step(env.action_space.low)
    assert np.max(np.abs(base.signal("travel"))) < 1e-4
