"""Physics of the Bingham-family and Dominguez models: bi-viscous (review eqs. 5–6), hysteretic bi-viscous
(Wereley, Pang & Kamath 1998), Gamota–Filisko (eq. 4) and Dominguez (eqs. 14–20).

Each model is checked for what defines it, against expressions written here from the equations (not against
its own kernel), and, where it has internal-state ODEs, against an independent Radau solution."""
import functools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mrd_env import available_dampers, make_damper
from mrd_env.stepping import SystemMatrices, run
from mrd_env.rig import sinusoidal_test

from tests.reference_models import nrmse

MODELS = ["bi_viscous", "hysteretic_bi_viscous", "gamota_filisko", "dominguez"]
X, FREQ = 0.015, 2.5  # the prototype test: 1.5 cm at 2.5 Hz
W = 2 * math.pi * FREQ


@functools.lru_cache(maxsize=None)
def four_levels(model):
    d = make_damper(model)
    levels = np.linspace(d.command.v_min, d.command.v_max, 4)
    return d, sinusoidal_test(d, X, FREQ, levels, cycles=2)


# ---------------------------------------------------------------- common physics


@pytest.mark.parametrize("model", MODELS)
def test_selectable_runs_dissipates_and_is_monotone_in_command(model):
    assert model in available_dampers()
    d, rs = four_levels(model)
    assert type(d).name == model and d.presets[d.default_preset].verified is False  # derived presets
    energies, peaks, troughs = [], [], []
    for r in rs:
        sl = r.steady_cycles(FREQ)
        assert np.all(np.isfinite(r.force))
        energies.append(r.dissipated_energy(sl))
        peaks.append(r.force[sl].max())
        troughs.append(r.force[sl].min())
    assert all(e > 0 for e in energies)
    assert np.all(np.diff(energies) > 0) and np.all(np.diff(peaks) > 0) and np.all(np.diff(troughs) < 0)
    # force levels comparable to the Spencer–Dyke prototype at this test (478 ... 1691 N)
    assert 400 < peaks[0] < 700 and 1400 < peaks[-1] < 1800


# ---------------------------------------------------------------- bad parameters


@pytest.mark.parametrize("model,field,value", [
    ("bi_viscous", "fy_a", -1.0), ("bi_viscous", "c_pre_a", 0.0), ("bi_viscous", "c_ps_b", float("nan")),
    ("hysteretic_bi_viscous", "v0_0", -1e-3), ("hysteretic_bi_viscous", "tau", 0.0),
    ("hysteretic_bi_viscous", "c_pre_0", float("inf")), ("hysteretic_bi_viscous", "a_s", -1.0),
    ("gamota_filisko", "c0a", 0.0), ("gamota_filisko", "c1", -5.0), ("gamota_filisko", "k2a", 0.0),
    ("gamota_filisko", "fc_b", -1.0),
    ("dominguez", "i_c", 0.0), ("dominguez", "omega", -1.0), ("dominguez", "x_max", 0.0),
    ("dominguez", "gamma1", 0.0), ("dominguez", "alpha4", float("nan")),
])
def test_bad_parameter_names_the_field(model, field, value):
    cls = type(make_damper(model)).Params.__name__
    with pytest.raises(ValueError, match=rf"{cls}\.{field}"):
        make_damper(model, **{field: value})


@pytest.mark.parametrize("model,overrides,match", [
    ("bi_viscous", {"c_pre_a": 1000.0}, r"c_pre_a = 1000 must be > c_ps_a"),
    ("bi_viscous", {"c_pre_b": -20000.0}, r"c_pre .* must be > c_ps .* over the command range \[0, 2.25\] V"),
    ("hysteretic_bi_viscous", {"v0_1": -1.0}, r"v0 polynomial .* over the command range"),
    ("hysteretic_bi_viscous", {"c_pre_1": 0.0, "c_pre_2": 0.0}, r"c_pre polynomial"),
    ("dominguez", {"gamma2": 4000.0}, r"gamma\(I\) = gamma1 − gamma2·I must be > 0 over the command range"),
    ("dominguez", {"fz04": 2000.0}, r"F_z0\(I\) \(fz01..fz04\) must stay below"),
])
def test_constraints_over_the_command_range(model, overrides, match):
    with pytest.raises(ValueError, match=match):
        make_damper(model, **overrides)


# ---------------------------------------------------------------- bi-viscous, eqs. (5)–(6)


def eq5(v, c_pre, c_ps, fy):
    vy = fy / (c_pre - c_ps)  # eq. (6)
    return np.where(v >= vy, c_ps * v + fy, np.where(v <= -vy, c_ps * v - fy, c_pre * v))


def test_bi_viscous_continuous_at_yield_velocity_with_slopes_c_pre_and_c_ps():
    d = make_damper("bi_viscous")
    force = type(d).force_law
    p, s0 = d.params.as_array(), np.zeros(0)
    F = lambda v, u: force(p, s0, 0.0, v, 0.0, u) - d.params.f0  # noqa: E731
    for u in (0.0, 1.0, 2.25):
        fy, cps, cpre = d.coefficients(u)
        vy = d.yield_velocity(u)
        assert vy == pytest.approx(fy / (cpre - cps))
        for sgn in (1.0, -1.0):
            v = sgn * vy
            eps = 1e-6 * vy
            # continuity: both formulas of eq. (5) give the same force at ±v_yield
            assert F(v, u) == pytest.approx(cpre * v, rel=1e-9)
            assert F(v, u) == pytest.approx(cps * v + sgn * fy, rel=1e-9)
            assert abs(F(v + eps, u) - F(v - eps, u)) <= 2 * eps * cpre * (1 + 1e-6)
            inner, outer = v - sgn * 10 * eps, v + sgn * 10 * eps
            # slope c_pre inside, c_ps outside
            assert (F(v - sgn * eps, u) - F(inner, u)) / (sgn * 9 * eps) == pytest.approx(cpre, rel=1e-5)
            assert (F(outer, u) - F(v + sgn * eps, u)) / (sgn * 9 * eps) == pytest.approx(cps, rel=1e-5)


def test_bi_viscous_rig_force_lies_on_eq5():
    d, rs = four_levels("bi_viscous")
    for r in rs:
        fy, cps, cpre = d.coefficients(r.command[0])
        np.testing.assert_allclose(r.force, eq5(r.v, cpre, cps, fy) + d.params.f0, rtol=0, atol=1e-9)


# ---------------------------------------------------------------- hysteretic bi-viscous


def crossings(y, v):
    """Interpolated values of v where y changes sign, with the direction of v there (+1 increasing)."""
    i = np.flatnonzero(np.diff(np.sign(y)) != 0)
    at = v[i] - y[i] * (v[i + 1] - v[i]) / (y[i + 1] - y[i])
    return at, np.sign(v[i + 1] - v[i])


def test_hysteretic_bi_viscous_zero_force_at_plus_minus_v0_and_loop_opening():
    d, rs = four_levels("hysteretic_bi_viscous")
    for r in rs[1:]:  # the 0 V level never reaches post-yield on its loading branch at this velocity
        fy, cps, cpre, v0 = d.coefficients(r.command[0])
        sl = r.steady_cycles(FREQ)
        Fh, v, x = r.force[sl] - d.params.f0, r.v[sl], r.x[sl]
        at, direction = crossings(Fh, v)
        # velocity increasing (ẍ > 0): F = 0 at +v0; decreasing: at −v0
        assert len(at) == 2
        for a, s in zip(at, direction):
            assert a == pytest.approx(s * v0, rel=0.01)
        # at zero velocity the branches are c_pre(0 ∓ v0): the loop is open by 2 c_pre v0 (< 2 F_yield here)
        assert cpre * v0 < fy
        at_x, _ = crossings(v, x)  # the displacement where ẋ = 0 tells which end of the stroke
        i0 = np.flatnonzero(np.diff(np.sign(v)) != 0)
        F_at_v0 = Fh[i0] - v[i0] * (Fh[i0 + 1] - Fh[i0]) / (v[i0 + 1] - v[i0])
        for F0, xe in zip(F_at_v0, at_x):
            assert F0 == pytest.approx(np.sign(xe) * cpre * v0, rel=0.01)  # lags: positive at the top
        assert abs(F_at_v0[0] - F_at_v0[1]) == pytest.approx(2 * cpre * v0, rel=0.01)


def test_hysteretic_bi_viscous_without_opening_is_the_bi_viscous_curve():
    d = make_damper("hysteretic_bi_viscous", v0_0=0.0, v0_1=0.0, v0_2=0.0)
    for r in sinusoidal_test(d, X, FREQ, [1.0, 2.25], cycles=1):
        fy, cps, cpre, _ = d.coefficients(r.command[0])
        np.testing.assert_allclose(r.force, eq5(r.v, cpre, cps, fy) + d.params.f0, rtol=0, atol=1e-9)


def test_hysteretic_bi_viscous_branch_does_not_need_the_acceleration_input():
    """Coupled to a plant the force law gets ẍ = 0: the branch comes from the filtered-velocity state."""
    d, rs = four_levels("hysteretic_bi_viscous")
    r = rs[-1]
    assert r.command[0] == 2.25
    n = len(r.t) - 1
    Wx = np.stack([r.x, r.v, np.zeros_like(r.x)], axis=1)[None]  # no acceleration
    F, _, _ = run(d, SystemMatrices.displacement_driven(), d.initial_state()[None].copy(), np.full((1, 1), 2.25),
                  np.full((1, n, 1), 2.25), Wx, r.dt)
    np.testing.assert_allclose(F[0, :, 0], r.force[1:], rtol=0, atol=1e-9)


def hysteretic_reference(d, V, T):
    """Wereley et al. (1998) branches with the exact sign of the estimated acceleration; state q (Radau)."""
    p = d.params
    fy, cps, cpre, v0 = (float(c) for c in d.coefficients(V))
    v1, v2 = (fy - cpre * v0) / (cpre - cps), (fy + cpre * v0) / (cpre - cps)

    def branches(v, acc):
        if acc >= 0:
            return cps * v - fy if v <= -v1 else (cpre * (v - v0) if v <= v2 else cps * v + fy)
        return cps * v + fy if v >= v1 else (cpre * (v + v0) if v >= -v2 else cps * v - fy)

    t = np.arange(int(round(T * 1000)) + 1) * 1e-3
    sol = solve_ivp(lambda tt, q: [(X * W * math.cos(W * tt) - q[0]) / p.tau], (0, T), [0.0], method="Radau",
                    rtol=1e-8, atol=1e-12, t_eval=t)
    assert sol.success
    v = X * W * np.cos(W * t)
    return np.array([branches(vk, (vk - qk) / p.tau) for vk, qk in zip(v, sol.y[0])]) + p.f0


def test_hysteretic_bi_viscous_against_radau():
    d = make_damper("hysteretic_bi_viscous", a_s=0.0)
    for r in sinusoidal_test(d, X, FREQ, [1.5, 2.25], cycles=2):
        assert nrmse(r.force, hysteretic_reference(d, r.command[0], r.t[-1])) <= 0.01


# ---------------------------------------------------------------- Gamota–Filisko, eq. (4)


def gamota_filisko_reference(p, V, T, dt=1e-3):
    """Eq. (4) in the displacements (x1, x2): stick (ẋ1 = 0) while |F − f0| ≤ f_c, else
    c0 ẋ1 + f_c sgn ẋ1 = F − f0 (the library integrates the spring forces instead)."""
    fc, c0 = p.fc_a + p.fc_b * V, p.c0a + p.c0b * V
    k1, k2 = p.k1a + p.k1b * V, p.k2a + p.k2b * V

    def rhs(t, s):
        x1, x2 = s
        P = k2 * (X * math.sin(W * t) - x2)
        x1d = (P - fc * math.copysign(1.0, P)) / c0 if abs(P) > fc else 0.0
        return [x1d, x1d + (P - k1 * (x2 - x1)) / p.c1]

    t = np.arange(int(round(T / dt)) + 1) * dt
    sol = solve_ivp(rhs, (0, T), [0.0, 0.0], method="Radau", rtol=1e-8, atol=1e-13, t_eval=t)
    assert sol.success
    return k2 * (X * np.sin(W * t) - sol.y[1]) + p.f0


def test_gamota_filisko_against_radau():
    d, rs = four_levels("gamota_filisko")
    r = rs[2]
    assert r.command[0] == 1.5
    assert nrmse(r.force, gamota_filisko_reference(d.params, 1.5, r.t[-1])) <= 0.01


def test_gamota_filisko_reduces_to_bingham_for_stiff_springs():
    """k1, k2 → ∞: the viscoelastic solid becomes rigid and F → f_c sgn(ẋ) + c0 ẋ + f0 (review eq. (2)); only
    the stick phases after each velocity reversal (length ∝ 1/√k) still differ."""
    outliers = []
    for k in (1e7, 1e8):
        d = make_damper("gamota_filisko", k1a=k, k2a=k, k2b=0.0)
        p = d.params
        n_out = 0
        for r in sinusoidal_test(d, X, FREQ, [0.0, 1.0, 2.25], cycles=1.5):
            u = r.command[0]
            bingham = (p.fc_a + p.fc_b * u) * np.sign(r.v) + (p.c0a + p.c0b * u) * r.v + p.f0
            err = np.abs(r.force - bingham)[r.t > 0.05] / np.max(np.abs(bingham))  # after the start-up
            n_out += int(np.sum(err > 0.01))
            if k == 1e8:
                away = np.abs(r.v[r.t > 0.05]) > 0.03  # outside the stick phases
                assert np.max(err[away]) <= 0.01
        outliers.append(n_out)
    assert outliers[1] < 0.5 * outliers[0]


def test_gamota_filisko_bingham_element_sticks_below_fc():
    d, rs = four_levels("gamota_filisko")
    p, r = d.params, rs[2]
    n = len(r.t) - 1
    Wx = np.stack([r.x, r.v, np.zeros_like(r.x)], axis=1)[None]
    F, Y, _ = run(d, SystemMatrices.displacement_driven(), d.initial_state()[None].copy(), np.full((1, 1), 1.5),
                  np.full((1, n, 1), 1.5), Wx, r.dt)
    k1, k2 = p.k1a + p.k1b * 1.5, p.k2a + p.k2b * 1.5
    f1, f2 = Y[0, :, d.state_names.index("f1")], Y[0, :, d.state_names.index("f2")]
    x1 = r.x[1:] - f2 / k2 - f1 / k1  # x2 = x − f2/k2, x1 = x2 − f1/k1
    fc = p.fc_a + p.fc_b * 1.5
    stuck = np.abs(F[0, 1:, 0] - p.f0) < 0.99 * fc
    stuck &= np.abs(F[0, :-1, 0] - p.f0) < 0.99 * fc  # whole step inside the stick band
    assert stuck.sum() > 10
    # the Bingham element does not move (up to the quadrature of the velocity input over a step, ~5e-9 m)
    assert np.max(np.abs(np.diff(x1)[stuck])) < 1e-8
    assert np.max(np.abs(np.diff(x1)[~stuck])) > 1e-4  # and slides outside


def test_gamota_filisko_preset_matches_the_prototype_check_values():
    """Reference page: Spencer–Dyke prototype peaks at 1.5 cm / 2.5 Hz (Radau), N."""
    published = [(478, -622), (840, -984), (1197, -1340), (1548, -1691)]
    _, rs = four_levels("gamota_filisko")
    for r, (fmax, fmin) in zip(rs, published):
        sl = r.steady_cycles(FREQ)
        assert r.force[sl].max() == pytest.approx(fmax, abs=10)
        assert r.force[sl].min() == pytest.approx(fmin, abs=10)


# ---------------------------------------------------------------- Dominguez, eqs. (14)–(20)


def dominguez_reference(p, x, v, I):
    """Eqs. (14)–(20) (continuous current laws, force lagging velocity), written with numpy."""
    def law(a1, a2, a3, a4):
        return np.where(I > p.i_c, a1 + a2 * (1 - np.exp(-a3 * (I - p.i_c))), a4 + (a1 - a4) * I / p.i_c)

    c0, alpha, fz0 = law(p.c1, p.c2, p.c3, p.c4), law(p.alpha1, p.alpha2, p.alpha3, p.alpha4), \
        law(p.fz01, p.fz02, p.fz03, p.fz04)
    k0, gamma = p.k1 + p.k2 * I, p.gamma1 - p.gamma2 * I
    b = np.tanh(x / p.x_s)
    z = np.tanh(np.sqrt(gamma) * v + b * np.arctanh(np.sqrt(gamma) * fz0 / alpha)) / np.sqrt(gamma)
    return (p.d1 * p.omega ** p.d2) * (p.d3 * p.x_max ** p.d4) * (c0 * v + k0 * x + alpha * z)


def test_dominguez_rig_force_is_eqs_14_to_20():
    d, rs = four_levels("dominguez")
    for r in rs:
        np.testing.assert_allclose(r.force, dominguez_reference(d.params, r.x, r.v, r.command[0]), rtol=1e-12,
                                   atol=1e-9)


def test_dominguez_frequency_and_amplitude_scaling_law():
    """Doubling ω (or x_max) scales the force by 2^d2 (2^d4) at the same state (x, ẋ, I)."""
    d2, d4 = 0.3, -0.2
    base = make_damper("dominguez", d2=d2, d4=d4)
    p = base.params
    levels = [0.25, 0.75]
    F = np.array([r.force for r in sinusoidal_test(base, X, FREQ, levels, cycles=1)])
    F_w = np.array([r.force for r in sinusoidal_test(base.with_params(omega=2 * p.omega), X, FREQ, levels, cycles=1)])
    F_x = np.array([r.force for r in sinusoidal_test(base.with_params(x_max=2 * p.x_max), X, FREQ, levels, cycles=1)])
    np.testing.assert_allclose(F_w, 2 ** d2 * F, rtol=1e-12)
    np.testing.assert_allclose(F_x, 2 ** d4 * F, rtol=1e-12)
    assert base.scaling() == pytest.approx(p.d1 * p.omega ** d2 * p.d3 * p.x_max ** d4)


def test_dominguez_characteristic_forces_and_current_laws():
    d = make_damper("dominguez")
    p = d.params
    force, s0 = type(d).force_law, np.zeros(0)
    pa = p.as_array()
    for I in (0.0, 0.2, p.i_c, 0.6, 1.0):
        c0, k0, alpha, gamma, fz0 = (float(c[0]) for c in d.coefficients(I))
        # at zero velocity the hysteretic force is ±F_z0: positive at the top of the stroke (force lags)
        xe = 10 * p.x_s
        assert force(pa, s0, xe, 0.0, 0.0, I) - k0 * xe == pytest.approx(fz0, rel=1e-6)
        assert force(pa, s0, -xe, 0.0, 0.0, I) + k0 * xe == pytest.approx(-fz0, rel=1e-6)
        # at large velocity it saturates at α/√γ on top of the viscous part c0 ẋ
        v = 50 / math.sqrt(gamma)
        assert force(pa, s0, xe, v, 0.0, I) - c0 * v - k0 * xe == pytest.approx(alpha / math.sqrt(gamma), rel=1e-9)
    # eqs. (15)–(17) continuous at the critical current; eq. (18), (19) linear
    lo, hi = d.coefficients(p.i_c * (1 - 1e-9)), d.coefficients(p.i_c * (1 + 1e-9))
    for a, b in zip(lo, hi):
        assert float(a[0]) == pytest.approx(float(b[0]), rel=1e-6)
    c0, _, alpha, _, fz0 = d.coefficients([0.0, p.i_c])
    assert (c0[0], alpha[0], fz0[0]) == (p.c4, p.alpha4, p.fz04)
    assert (c0[1], alpha[1], fz0[1]) == pytest.approx((p.c1, p.alpha1, p.fz01))
