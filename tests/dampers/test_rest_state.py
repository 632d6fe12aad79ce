"""Each model's rest state at a stroke (``DamperModel.rest_state``): its internal states do not move there with the
stroke held (ṡ = 0 by the model's own equations, at every command); a Spencer–Dyke damper stroked to x and held
comes to rest on the family of rest states its rest state belongs to (solve_ivp)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mrd_env.dampers import available_dampers, make_damper
from mrd_env.dampers.registry import damper_class

CASES = [(m, pre) for m in available_dampers() for pre in damper_class(m).presets]


@pytest.mark.parametrize("model, preset", CASES)
def test_the_internal_states_are_at_rest_at_the_rest_state(model, preset):
    d = make_damper(model, preset=preset)
    p = d.params.as_array()
    for x in np.linspace(-0.05, 0.05, 11):
        for u in np.linspace(d.command.v_min, d.command.v_max, 3):
            s = d.rest_state(x)
            assert s.shape == (d.n_states,)
            ds = np.full(d.n_states, np.nan)
            d.rhs(p, s.copy(), float(x), 0.0, float(u), ds)
            scale = max(1.0, float(np.max(np.abs(s), initial=0.0)))
            np.testing.assert_allclose(ds, 0.0, atol=1e-12 * scale, err_msg=f"x = {x:g} m, u = {u:g}")
    np.testing.assert_array_equal(d.rest_states([0.01, -0.02]),
                                  np.concatenate([d.rest_state(0.01), d.rest_state(-0.02)]))


def test_spencer_dyke_rests_at_y_equal_x_and_its_rest_force_is_the_accumulators():
    d = make_damper("spencer_dyke", preset="automotive")
    np.testing.assert_array_equal(d.rest_state(0.013), [0.013, 0.0])
    for u in (0.0, 2.0):
        assert d.rest_force(0.013, u) - d.rest_force(0.0, u) == pytest.approx(d.params.k1 * 0.013, rel=1e-12)


def test_a_spencer_dyke_damper_stroked_and_held_comes_to_rest_on_the_family_its_rest_state_belongs_to():
    """x ramps to 2 cm over 2 s (smoothly) and is held for 30 s: (y, z) come to rest where α z + k0 (x − y) = 0 —
    the rest states at x form that family (z is left where the stroke's hysteresis put it); ``rest_state`` is its
    member with z = 0."""
    d = make_damper("spencer_dyke", preset="automotive")
    p, X, T = d.params.as_array(), 0.02, 2.0

    def stroke(t):
        r = min(t / T, 1.0)
        return X * (r - np.sin(2 * np.pi * r) / (2 * np.pi)), (X / T) * (1 - np.cos(2 * np.pi * r)) * (t < T)

    def f(t, s):
        x, xd = stroke(t)
        ds = np.zeros(2)
        d.rhs(p, s.copy(), x, xd, 0.0, ds)
        return ds

    sol = solve_ivp(f, (0.0, 32.0), d.initial_state(), method="LSODA", rtol=1e-10, atol=1e-12)
    y, z = sol.y[:, -1]
    k0, alpha = d.params.k0, d.params.alpha_a
    assert abs(z) > 1e-3                                      # the stroke left hysteresis: not the z = 0 member
    assert abs(alpha * z + k0 * (X - y)) < 1e-3 * k0 * X      # but at rest: ẏ = 0
    y0, z0 = d.rest_state(X)
    assert z0 == 0.0 and alpha * z0 + k0 * (X - y0) == 0.0


def test_a_non_symmetric_bouc_wen_damper_held_off_centre_saturates():
    d = make_damper("nonsymmetric_bouc_wen")
    zs = d.saturation()
    assert d.rest_state(0.01)[0] == pytest.approx(-zs) and d.rest_state(-0.01)[0] == pytest.approx(zs)
    assert d.rest_state(0.0)[0] == 0.0


def test_a_stroke_that_is_not_a_number_is_refused():
    with pytest.raises(ValueError, match="x"):
        make_damper("spencer_dyke").rest_state(float("nan"))
