"""Error measures (review eqs. 3, 25, 26), the Table 8 RSS budget and the Monte-Carlo helper."""
import csv
import io
import math

import numpy as np
from scipy.integrate import trapezoid
import pytest

from mrd_env.identification import (TABLE8_DEFAULTS, Contribution, error_displacement, error_measures, error_time,
                                    error_velocity, j1, j2, monte_carlo, rss_budget, table8_contributions)


def sine_case(n=2001, A=100.0, f=1.0, t=None):
    t = np.linspace(0.0, 1.0 / f, n) if t is None else t
    return t, A * np.sin(2 * np.pi * f * t), 0.01 * np.sin(2 * np.pi * f * t)


def nonuniform_grid(n, T=1.0, seed=0):
    steps = np.random.default_rng(seed).uniform(0.2, 1.8, n - 1)
    return np.concatenate([[0.0], np.cumsum(steps)]) * T / steps.sum()


# --- E_t, E_x, E_v, J1, J2 ----------------------------------------------------------------------------------------

def test_identical_forces_give_zero():
    t, F, x = sine_case()
    m = error_measures(F, F.copy(), t, x)
    assert m == {"E_t": 0.0, "E_x": 0.0, "E_v": 0.0, "J1": 0.0, "J2": 0.0}


@pytest.mark.parametrize("grid", ["uniform", "nonuniform"])
def test_mean_force_gives_unit_time_error(grid):
    t = np.linspace(0, 1, 501) if grid == "uniform" else nonuniform_grid(501)
    F_exp = 50 + 300 * np.sin(2 * np.pi * 1.3 * t) ** 3
    mean = trapezoid(F_exp, t) / (t[-1] - t[0])
    assert error_time(F_exp, np.full_like(t, mean), t) == pytest.approx(1.0, abs=1e-12)


def test_constant_offset_gives_analytic_time_error():
    # F_exp = A sin over whole periods: time RMS deviation A/√2, so E_t = c·√2/A for an offset c
    t, F_exp, _ = sine_case(n=1001, A=200.0)
    c = 7.0
    assert error_time(F_exp, F_exp + c, t) == pytest.approx(c * math.sqrt(2) / 200.0, rel=1e-9)


def test_constant_offset_on_nonuniform_grid():
    t = nonuniform_grid(4001, seed=3)
    F_exp = 200.0 * np.sin(2 * np.pi * t)
    assert error_time(F_exp, F_exp + 7.0, t) == pytest.approx(7.0 * math.sqrt(2) / 200.0, rel=1e-4)


def test_j1_j2_of_known_error():
    F_exp = np.array([10.0, 20.0, 30.0, 40.0])
    F = F_exp + np.array([1.0, -2.0, 2.0, 0.0])
    assert j1(F_exp, F) == 9.0
    assert j2(F_exp, F) == 1.5


def test_displacement_weighting_ignores_errors_where_velocity_is_zero():
    # stroke held still on [0, 1] s, then a ramp: dx/dt (central differences) is exactly 0 inside the hold
    t = np.linspace(0.0, 2.0, 201)
    x = np.where(t <= 1.0, 0.0, 0.02 * (t - 1.0))
    F_exp = 100 * np.sin(3 * t) + 40 * t
    F = F_exp.copy()
    hold = (t > 0.05) & (t < 0.95)
    F[hold] += 25.0
    assert error_displacement(F_exp, F, t, x) == 0.0
    assert error_time(F_exp, F, t) > 0.1


def test_velocity_weighting_ignores_errors_where_acceleration_is_zero():
    # constant velocity on [0, 1] s (zero acceleration), then a parabola
    t = np.linspace(0.0, 2.0, 201)
    v = np.where(t <= 1.0, 0.1, 0.1 + 0.3 * (t - 1.0))
    F_exp = 100 * np.sin(3 * t) + 40 * t
    F = F_exp.copy()
    F[(t > 0.05) & (t < 0.95)] -= 10.0
    assert error_velocity(F_exp, F, t, v=v) == 0.0
    assert error_displacement(F_exp, F, t, v=v) > 0.05


def test_derivatives_use_the_nonuniform_grid():
    t = nonuniform_grid(3001, seed=1)
    w = 2 * np.pi * 2.0
    x = 0.01 * np.sin(w * t)
    v_exact = 0.01 * w * np.cos(w * t)
    F_exp = 500 * np.tanh(v_exact / 0.02)
    F = F_exp + 20 * np.sin(7 * t)
    assert error_displacement(F_exp, F, t, x) == pytest.approx(error_displacement(F_exp, F, t, v=v_exact), rel=1e-3)
    assert error_velocity(F_exp, F, t, x) == pytest.approx(error_velocity(F_exp, F, t, v=v_exact), rel=1e-3)
    # the same measures on a fine uniform grid agree (trapezoidal + second-order differences converge)
    tu = np.linspace(0.0, 1.0, 20001)
    xu = 0.01 * np.sin(w * tu)
    Fe_u = 500 * np.tanh(0.01 * w * np.cos(w * tu) / 0.02)
    mu = error_measures(Fe_u, Fe_u + 20 * np.sin(7 * tu), tu, xu)
    m = error_measures(F_exp, F, t, x)
    for key in ("E_t", "E_x", "E_v"):
        assert m[key] == pytest.approx(mu[key], rel=2e-3)


def test_error_measures_keys_and_consistency():
    t, F_exp, x = sine_case()
    F = 0.9 * F_exp + 3
    m = error_measures(F_exp, F, t, x)
    assert set(m) == {"E_t", "E_x", "E_v", "J1", "J2"}
    assert m["E_t"] == error_time(F_exp, F, t)
    assert m["E_x"] == error_displacement(F_exp, F, t, x)
    assert m["E_v"] == error_velocity(F_exp, F, t, x)
    assert m["J2"] == pytest.approx(math.sqrt(m["J1"] / len(t)))


@pytest.mark.parametrize("call, match", [
    (lambda t, F, x: error_time(F, F[:-1], t), "F has 2000 samples, expected 2001"),
    (lambda t, F, x: error_time(F, F, t[::-1]), "t is not strictly increasing at index 1"),
    (lambda t, F, x: error_time(np.where(t > 0.5, np.nan, F), F, t), "F_exp has a non-finite value"),
    (lambda t, F, x: error_time(np.ones_like(t), F, t), "E_t is undefined"),
    (lambda t, F, x: error_displacement(F, F, t), "give the displacement x"),
    (lambda t, F, x: error_velocity(F, F, t, x[:10]), "x has 10 samples"),
    (lambda t, F, x: j1(F, F[:3]), "F has 3 samples"),
])
def test_bad_inputs_are_named(call, match):
    t, F, x = sine_case()
    with pytest.raises(ValueError, match=match):
        call(t, F, x)


# --- RSS budget (Table 8) ---------------------------------------------------------------------------------------

def test_rss_of_known_contributions():
    b = rss_budget([("a", 3.0, "normal", 1.0), ("b", 4.0, "normal", 1.0)])
    assert b.combined == pytest.approx(5.0)
    assert b.expanded == pytest.approx(10.0)
    assert b.absolute(2000.0) == pytest.approx(200.0)
    assert rss_budget([("a", 3.0, "normal", 1.0)], k=3).expanded == pytest.approx(9.0)


@pytest.mark.parametrize("dist, divisor", [("rectangular", math.sqrt(3)), ("triangular", math.sqrt(6)),
                                           ("normal", 2.0)])
def test_standard_uncertainty_by_distribution(dist, divisor):
    assert Contribution("x", 0.6, dist).standard_uncertainty == pytest.approx(0.6 / divisor)


def test_table8_defaults_and_case_dependent_rows():
    u = [0.04, 0.1, 0.5, 0.1, 0.01, 0.1]
    expected = math.sqrt(sum((a / math.sqrt(3)) ** 2 for a in u) + (0.5 / 2) ** 2 + (1.0 / math.sqrt(3)) ** 2)
    assert rss_budget(TABLE8_DEFAULTS).combined == pytest.approx(expected)
    rows = table8_contributions(test_speed=0.2, stability=0.3)
    assert [c.name for c in rows][-1] == "Stability"
    assert next(c for c in rows if c.name == "Test speed").value == 0.2
    with pytest.raises(ValueError, match="test_speed"):
        table8_contributions(test_speed=20)
    with pytest.raises(ValueError, match="distribution"):
        Contribution("x", 1.0, "uniform")


def test_budget_writers(tmp_path):
    b = rss_budget()
    md = b.to_markdown()
    assert md.startswith("| Source | Value (% R)")
    assert "| Expanded uncertainty U (k = 2) |" in md
    text = b.to_csv(tmp_path / "budget.csv")
    rows = list(csv.reader(io.StringIO((tmp_path / "budget.csv").read_text())))
    assert text == (tmp_path / "budget.csv").read_text()
    assert len(rows) == 1 + len(TABLE8_DEFAULTS) + 2
    assert float(rows[-1][-1]) == pytest.approx(b.expanded, rel=1e-3)


# --- Monte Carlo --------------------------------------------------------------------------------------------------

def test_monte_carlo_recovers_known_distribution():
    res = monte_carlo(lambda g: {"m": g.normal(3.0, 2.0), "u": g.uniform(0, 1)}, 2000, 42)
    assert res.ci_low["m"] < 3.0 < res.ci_high["m"]
    assert abs(res.mean["m"] - 3.0) < 4 * res.sem["m"]
    assert res.std["m"] == pytest.approx(2.0, rel=0.1)
    # 95 % central interval of N(3, 2): 3 ± 1.96·2
    assert res.ci_low["m"] == pytest.approx(3 - 3.92, abs=0.3)
    assert res.ci_high["u"] == pytest.approx(0.975, abs=0.02)
    assert set(res.summary()["u"]) == {"mean", "std", "sem", "ci_low", "ci_high"}


def test_monte_carlo_is_reproducible_and_draws_are_stable():
    f = lambda g: float(g.standard_normal())  # noqa: E731
    a = monte_carlo(f, 50, 7).samples["value"]
    b = monte_carlo(f, 50, np.random.default_rng(7)).samples["value"]
    c = monte_carlo(f, 10, 7).samples["value"]
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a[:10], c)  # draw i does not depend on the number of draws
    assert len(np.unique(a)) == 50


def test_monte_carlo_errors_and_skips():
    def flaky(g):
        if g.random() < 0.3:
            raise RuntimeError("diverged")
        return {"q": 1.0}

    res = monte_carlo(flaky, 40, 1, on_error="skip")
    assert res.n_failed > 0 and res.samples["q"].size == 40 - res.n_failed
    with pytest.raises(RuntimeError):
        monte_carlo(flaky, 40, 1)
    with pytest.raises(ValueError, match="rng"):
        monte_carlo(lambda g: 1.0, 10, "seed")
    assert monte_carlo(lambda g: 1.0, 10, None).samples["value"].size == 10  # None: fresh entropy, as everywhere
    with pytest.raises(ValueError, match="n_draws"):
        monte_carlo(lambda g: 1.0, 1, 0)
    with pytest.raises(ValueError, match="keys"):
        monte_carlo(lambda g: {"a": 1.0} if g.random() < 0.5 else {"b": 1.0}, 20, 0)


def test_a_masked_span_is_neither_scored_nor_bridged():
    """Measures with a mask equal those of the scored stretches alone, each integrated on its own (review eq. 3
    integrates over scored time): the two samples beside an excluded span do not carry its length."""
    from mrd_env.identification.measures import error_measures, scored_intervals

    t = np.arange(3001) * 1e-3
    x = 0.01 * np.sin(2 * np.pi * 1.5 * t)
    v = 0.01 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)
    F_exp = 900.0 * np.tanh(v / 0.02) + 3000.0 * x
    F = F_exp + 40.0 * np.sin(2 * np.pi * 7.0 * t)
    F_exp[1000:1600] = 5000.0  # a clipped load cell, excluded
    mask = np.ones(t.size, bool)
    mask[1000:1600] = False
    h = scored_intervals(t, mask)
    assert h.sum() == pytest.approx(3.0 - 0.601)  # the steps into and out of the span are not scored either
    em = error_measures(F_exp, F, t, v=v, mask=mask)
    # by hand: the trapezoid on each scored stretch, the time mean over both
    runs = [slice(0, 1000), slice(1600, 3001)]
    def integral(g):
        return sum(np.trapezoid(g[r], t[r]) for r in runs)
    T = sum(t[r][-1] - t[r][0] for r in runs)
    mean = integral(F_exp) / T
    for name, w in (("E_t", np.ones_like(t)), ("E_x", np.abs(v))):
        want = np.sqrt(integral((F_exp - F) ** 2 * w) / integral((F_exp - mean) ** 2 * w))
        assert em[name] == pytest.approx(want, rel=1e-12), name
    assert em["J2"] == pytest.approx(np.sqrt(np.mean((F_exp - F)[mask] ** 2)), rel=1e-12)
    # a mask that keeps everything gives the measures without one
    full = error_measures(F_exp, F, t, v=v, mask=np.ones(t.size, bool))
    assert full == pytest.approx(error_measures(F_exp, F, t, v=v), rel=1e-12)
