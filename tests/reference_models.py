"""Independent reference implementations (plain numpy, written from the review's equations) integrated
with scipy's ``solve_ivp`` at tight tolerance: what the library's fixed-step results are checked against."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

#: The integrators of the tight-tolerance references, for ``pytest.mark.parametrize("method", ...)``: LSODA
#: (ODEPACK's, compiled) in every run, Radau (scipy's, in Python) in the slow tier as well, at the same
#: tolerances. On the quarter car's 3 s of class C road they agree to 2e-7 of each state's range (6e-6 for the
#: Bouc–Wen z) and LSODA takes 3 s where Radau takes 24 (its 66 000 steps each cost a Python Newton iteration).
#: Every reference run with them caps the step at the sample step (``max_step``): without it LSODA's Adams steps grew past a
#: velocity reversal of the Bouc–Wen sine test unnoticed (the force 85 % off mid-record); with it the two methods
#: agree to 1e-7 of the peak force on every damper case of ``tests/stepping/test_integrator_accuracy.py``.
REFERENCE_METHODS = ("LSODA", pytest.param("Radau", marks=pytest.mark.slow))


def bouc_wen_zdot(z, v, A, beta, gamma, n):
    # review eq. (8)
    return -gamma * abs(v) * z * abs(z) ** (n - 1) - beta * v * abs(z) ** n + A * v


def spencer_dyke_reference(p, eta, X, f, V, T, dt, method):
    """Review eq. (12) with the 1997 conventions; states (y, z, u); u̇ = −η(u − V)."""
    w = 2 * np.pi * f

    def coeffs(u):
        return p.c0a + p.c0b * u, p.c1a + p.c1b * u, p.alpha_a + p.alpha_b * u

    def ydot(x, xd, y, z, u):
        c0, c1, al = coeffs(u)
        return (al * z + c0 * xd + p.k0 * (x - y)) / (c0 + c1)

    def rhs(t, s):
        y, z, u = s
        x, xd = X * np.sin(w * t), X * w * np.cos(w * t)
        yd = ydot(x, xd, y, z, u)
        return [yd, bouc_wen_zdot(z, xd - yd, p.A, p.beta, p.gamma, p.n), -eta * (u - V)]

    t = np.arange(1, int(round(T / dt)) + 1) * dt
    sol = solve_ivp(rhs, (0, T), [0.0, 0.0, 0.0], method=method, rtol=1e-9, atol=1e-12, t_eval=t, max_step=dt)
    assert sol.success
    y, z, u = sol.y
    x, xd = X * np.sin(w * t), X * w * np.cos(w * t)
    c0, c1, _ = coeffs(u)
    return t, c1 * ydot(x, xd, y, z, u) + p.k1 * (x - p.x0)


def bouc_wen_reference(p, eta, X, f, V, T, dt, method):
    """Review eqs. (7)–(9); states (z, u)."""
    w = 2 * np.pi * f

    def rhs(t, s):
        z, u = s
        xd = X * w * np.cos(w * t)
        return [bouc_wen_zdot(z, xd, p.A, p.beta, p.gamma, p.n), -eta * (u - V)]

    t = np.arange(1, int(round(T / dt)) + 1) * dt
    sol = solve_ivp(rhs, (0, T), [0.0, 0.0], method=method, rtol=1e-9, atol=1e-12, t_eval=t, max_step=dt)
    assert sol.success
    z, u = sol.y
    x, xd = X * np.sin(w * t), X * w * np.cos(w * t)
    return t, ((p.c0a + p.c0b * u) * xd + (p.k0a + p.k0b * u) * (x - p.x0) + (p.alpha_a + p.alpha_b * u) * z)


def nrmse(F, F_ref):
    return float(np.sqrt(np.mean((F - F_ref) ** 2)) / np.sqrt(np.mean(F_ref ** 2)))
