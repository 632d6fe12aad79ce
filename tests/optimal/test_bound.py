"""The active-actuator bound (mrd_env/optimal/bound.py): above every controller's return in the environment, the
plant without force at f_max = 0 (an exact linear simulation), monotone in f_max, its QP cost the problem's own
return of its force history, the stroke limit imposed, the filter realisation against scipy's."""
import itertools
import math

import numpy as np
import pytest
import scipy.signal

from controllers import make_controller
from mrd_env.metrics import weighting_sos
from mrd_env.optimal import active_bound, episode_problem
from mrd_env.optimal.bound import sos_state_space
from mrd_env.mechanics.response import foh_response

CASES = {"car": ("mrd_env/QuarterCarPhysical-v0", {}), "shear_building": ("mrd_env/ShearBuildingPhysical-v0", {"damper_floors": (2,)})}


@pytest.fixture(scope="module", params=sorted(CASES))
def problem(request):
    env_id, options = CASES[request.param]
    return episode_problem(env_id, seed=1000000, control_dt=0.001, episode_seconds=2.0, **options)


def _free_response(p):
    """States of the plant with the damper force held at its static preload, by the exact first-order-hold
    response of the plant's own matrices (plants.response)."""
    u = np.hstack([np.full((p.n_rows, p.nd), p.F_static), p.W])
    return foh_response(p.A, np.hstack([p.BF, p.Bw]), u, p.dt, x0=p.x0)


def test_bound_is_above_the_laws_it_covers(problem):
    """Passive-off, passive-on and clipped-optimal re-simulated in the environment score below the bound whose force
    limit covers them (the largest force of the three, as the yardstick sets it) and below the default bound."""
    p = problem
    runs = {law: p.replay(p.commands_of(lambda e, n=law: make_controller(n, e)), states=True)
            for law in ("passive_off", "passive_on", "clipped_optimal")}
    f_max = max(float(np.max(np.abs(tr.F - p.F_static))) for tr in runs.values())
    b = active_bound(p, f_max=f_max)
    default = active_bound(p)
    assert default.f_max <= f_max
    for law, tr in runs.items():
        assert not tr.terminated
        assert b.covers(tr.F, p.F_static)
        assert tr.ret < b.bound, law
        assert tr.ret < default.bound, law
    assert b.bound >= default.bound - 1e-9  # more force, no less return


def test_zero_force_is_the_plant_without_a_damper_force(problem):
    """f_max = 0: the one feasible force history is the static preload; the bound is that plant's return."""
    p = problem
    X = _free_response(p)
    ref = p.linear_return(X, np.full((p.n_rows, p.nd), p.F_static))
    b = active_bound(p, f_max=0.0)
    assert b.bound == pytest.approx(ref, rel=1e-6)
    np.testing.assert_allclose(b.X, X, atol=1e-6 * np.abs(X).max())


def test_bound_grows_with_the_force_limit(problem):
    """More force, no less return — to the solver's duality gap (1e-8 absolute and relative) once f_max stops
    binding."""
    bounds = [active_bound(problem, f_max=f).bound for f in (0.0, 100.0, 400.0, 1500.0, 5000.0)]
    assert all(a <= b + 2e-8 * max(1.0, abs(b)) for a, b in itertools.pairwise(bounds))
    assert bounds[-1] > bounds[0]


def test_qp_solution_is_a_force_history_and_its_return(problem):
    """The optimum is a force history within f_max whose states follow the plant (an independent exact simulation
    of the plant with that force, linear between rows), whose return by the problem's own reward is the QP's
    primal cost, and whose certified bound lies within the duality gap above it."""
    p = problem
    f_max = 300.0
    b = active_bound(p, f_max=f_max)
    assert b.solver == "clarabel" and b.iterations > 0
    assert np.max(np.abs(b.F - p.F_static)) <= f_max * (1 + 1e-6)
    X = foh_response(p.A, np.hstack([p.BF, p.Bw]), np.hstack([b.F, p.W]), p.dt, x0=p.x0)
    np.testing.assert_allclose(b.X, X, atol=1e-6 * np.abs(X).max())
    assert p.linear_return(b.X, b.F) == pytest.approx(b.primal_return, rel=1e-6)
    assert b.primal_return <= b.bound <= b.primal_return + 1e-6 * abs(b.primal_return)


def test_the_linear_plant_with_first_order_hold_forces_is_the_environment(problem):
    """The bound's model of a force history — the plant with the force linear between rows — reproduces a law's
    return in the environment from its measured forces (the relaxation is of the environment, not another model)."""
    p = problem
    tr = p.replay(p.commands_of(lambda e: make_controller("clipped_optimal", e)), states=True)
    X = foh_response(p.A, np.hstack([p.BF, p.Bw]), np.hstack([tr.F, p.W]), p.dt, x0=p.x0)
    assert p.linear_return(X, tr.F) == pytest.approx(tr.ret, rel=5e-3)


def test_stroke_limit_is_imposed_and_infeasibility_is_an_error():
    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1000000, control_dt=0.001, episode_seconds=2.0,
                        road_params={"road_class": "D", "speed": 20.0}, stroke_limit=0.02)
    free = _free_response(p)
    travel = free[:, 0] - free[:, 1]
    assert np.max(np.abs(travel)) > 0.02  # without force the car would hit the limit
    b = active_bound(p, f_max=5000.0)
    assert b.limit_active
    assert np.max(np.abs(b.X[:, 0] - b.X[:, 1])) <= 0.02 * (1 + 1e-6)
    free_bound = active_bound(p, f_max=5000.0, limits=False)
    assert free_bound.bound > b.bound
    for f_max in (0.0, 2000.0):  # no force, or too little, to hold the travel within 2 cm on this road
        with pytest.raises(RuntimeError, match="infeasible"):
            active_bound(p, f_max=f_max)


def test_filter_realisation_is_scipys_sosfilt():
    sos = weighting_sos("Wk", 1e-3)
    A, B, C, D = sos_state_space(sos)
    u = np.random.default_rng(0).normal(size=3000)
    x, y = np.zeros(A.shape[0]), np.empty_like(u)
    for k, uk in enumerate(u):
        y[k] = (C @ x)[0] + D[0, 0] * uk
        x = A @ x + B[:, 0] * uk
    np.testing.assert_allclose(y, scipy.signal.sosfilt(sos, u), atol=1e-10 * np.abs(y).max())


def test_bad_inputs_raise_value_errors(problem):
    for bad in (-1.0, float("nan"), math.inf, True, "100"):
        with pytest.raises(ValueError, match="f_max"):
            active_bound(problem, f_max=bad)
    with pytest.raises(ValueError, match="solver"):
        active_bound(problem, solver="osqp")
    with pytest.raises(ValueError, match="tol"):
        active_bound(problem, tol=0.5)
    with pytest.raises(ValueError, match="EpisodeProblem"):
        active_bound("mrd_env/QuarterCarPhysical-v0")
