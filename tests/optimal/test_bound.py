"""The bounds (mrd_env/optimal/bound.py, mrd_env/optimal/dissipative.py).

The active-actuator bound: above every controller's return in the environment, the plant without force at
f_max = 0 (an exact linear simulation), monotone in f_max, its QP cost the problem's own return of its force
history, the stroke limit imposed, the filter realisation against scipy's. The passivity-aware bound: between the
laws (and the best constant command), which lie in its class, and the active bound; the active bound again with an
unlimited store; its energy identity against an independent fine-grid integration; the plant's mechanics recovered
from the problem; a free mass whose optimum with passivity is known in closed form; the car that cannot move before
the bump reaches it."""
import dataclasses
import itertools
import math

import numpy as np
import pytest
import scipy.signal

from controllers import make_controller
from mrd_env.metrics import weighting_sos
from mrd_env.optimal import CostTerm, EpisodeProblem, active_bound, dissipative_bound, episode_problem
from mrd_env.optimal.bound import sos_state_space
from mrd_env.optimal.dissipative import absorbed_energy, free_response, port_storage
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


@pytest.fixture(scope="module")
def runs(problem):
    """Passive-off, passive-on and clipped-optimal re-simulated in the environment, states and forces recorded."""
    p = problem
    return {law: p.replay(p.commands_of(lambda e, n=law: make_controller(n, e)), states=True)
            for law in ("passive_off", "passive_on", "clipped_optimal")}


def test_bound_is_above_the_laws_it_covers(problem, runs):
    """Passive-off, passive-on and clipped-optimal re-simulated in the environment score below the bound whose force
    limit covers them (the largest force of the three, as the yardstick sets it) and below the default bound."""
    p = problem
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


# --- the passivity-aware bound --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def covering(problem, runs):
    """The force limit that covers the three laws, and both bounds with it."""
    p = problem
    f_max = max(float(np.max(np.abs(tr.F - p.F_static))) for tr in runs.values())
    return f_max, active_bound(p, f_max=f_max), dissipative_bound(p, f_max=f_max)


def test_passive_bound_lies_between_the_laws_and_the_active_bound(problem, runs, covering):
    """The laws (and the best constant command, the yardstick's R_p) absorb energy from the first row on — they lie
    in the passive bound's class — and score below it; the passive bound is never above the active bound, and its
    own optimum lies in its class."""
    from experiments.benchmark.yardstick import best_passive

    p = problem
    f_max, act, pas = covering
    assert pas.kind == "passive" and act.kind == "active" and pas.storage == 0.0
    assert pas.bound <= act.bound + 1e-7 * abs(act.bound)
    for law, tr in runs.items():
        assert absorbed_energy(p, tr.F).min() >= -1e-9, law            # in the class (storage 0)
        assert absorbed_energy(p, tr.F, tr.X).min() >= -1e-9, law      # also on the environment's own states
        assert tr.ret < pas.bound, law
    rp, _ = best_passive(p)
    assert rp < pas.bound
    assert pas.absorbed.min() >= -1e-6 * np.max(np.abs(pas.absorbed))
    assert np.max(np.abs(pas.F - p.F_static)) <= f_max * (1 + 1e-6)
    assert pas.primal_return <= pas.bound <= pas.primal_return + 1e-6 * abs(pas.primal_return)


def test_passive_bound_grows_with_the_store_to_the_active_bound(problem, covering):
    """A larger initial store is a larger class (no smaller bound); an unlimited one is the active bound; with no
    force the one history is the static preload, as for the active bound."""
    p = problem
    f_max, act, pas = covering
    small = dissipative_bound(p, f_max=f_max, storage=0.01)
    huge = dissipative_bound(p, f_max=f_max, storage=1e6)
    assert pas.bound <= small.bound + 1e-8 * abs(small.bound) <= huge.bound + 2e-8 * abs(huge.bound)
    assert huge.bound == pytest.approx(act.bound, rel=1e-6)
    assert dissipative_bound(p, f_max=0.0).bound == pytest.approx(active_bound(p, f_max=0.0).bound, rel=1e-6)


def test_energy_identity_against_a_fine_grid(problem, runs):
    """The energy a force history takes from the plant — ∫(F − F_static)·ẋ_d, by Gauss–Legendre on each row — is the
    trapezoidal integral on a 20× finer grid of the same plant (exact response to the same piecewise-linear force),
    and equals the convex form the bound constrains: ∫ΔF·ẋ̄_d − ½eᵀPe − ½∫eᵀQe, e the deviation from the free
    response x̄."""
    p = problem
    F = runs["clipped_optimal"].F
    k = 20
    t, tf = np.arange(p.n_rows), np.arange((p.n_rows - 1) * k + 1) / k
    U = np.hstack([F, p.W])
    Uf = np.column_stack([np.interp(tf, t, U[:, j]) for j in range(U.shape[1])])
    B = np.hstack([p.BF, p.Bw])
    Xf = foh_response(p.A, B, Uf, p.dt / k, x0=p.x0)
    Ub = Uf.copy()
    Ub[:, :p.nd] = p.F_static
    Xb = foh_response(p.A, B, Ub, p.dt / k, x0=p.x0)
    dF = Uf[:, :p.nd] - p.F_static
    h = p.dt / k

    def cumtrapz(y):
        return np.concatenate([[0.0], np.cumsum(0.5 * h * (y[1:] + y[:-1]))])

    fine = cumtrapz(np.sum(dF * (Xf @ p.Cv.T), axis=1))[::k]
    ps = port_storage(p)
    e = Xf - Xb
    form = (cumtrapz(np.sum(dF * (Xb @ p.Cv.T), axis=1)) - 0.5 * np.einsum("ri,ij,rj->r", e, ps.P, e)
            - cumtrapz(0.5 * np.einsum("ri,ij,rj->r", e, ps.Q, e)))[::k]
    rows = absorbed_energy(p, F)
    scale = np.max(np.abs(rows))
    np.testing.assert_allclose(rows, fine, atol=1e-5 * scale)
    np.testing.assert_allclose(form, fine, atol=1e-5 * scale)
    np.testing.assert_allclose(free_response(p), Xb[::k], atol=1e-9 * np.abs(Xb).max())


def test_port_storage_is_the_plants_mechanics(problem):
    """M, K, C recovered from the problem's first-order matrices are the plant's own (the damper's inertance in M)."""
    p = problem
    env = p.make_env()
    plant, damper = env.assembly.linear_plant, env.assembly.damper
    ps = port_storage(p)
    M = plant.M + damper.inertance() * plant.S.T @ plant.S
    np.testing.assert_allclose(ps.M, M, rtol=1e-9, atol=1e-9 * np.abs(M).max())
    np.testing.assert_allclose(ps.K, plant.K, rtol=1e-9, atol=1e-9 * np.abs(plant.K).max())
    np.testing.assert_allclose(ps.C, plant.C, atol=1e-9 * max(np.abs(plant.C).max(), 1.0))


def _free_mass(n_rows=301, m=10.0, v0=1.0, target=2.0):
    """A mass m moving at v0 with a damper to the ground and no disturbance; the cost is its speed's shortfall from
    ``target``, Σ dt (v − target)² over rows 1..N."""
    N = n_rows - 1
    return EpisodeProblem(
        env_id="free mass", options={}, seed=0, dt=1e-3, control_dt=1e-3, n_sub=1, n_steps=N,
        A=np.array([[0.0, 1.0], [0.0, 0.0]]), BF=np.array([[0.0], [-1.0 / m]]), Bw=np.zeros((2, 1)),
        Cx=np.array([[1.0, 0.0]]), Cv=np.array([[0.0, 1.0]]), W=np.ones((n_rows, 1)), x0=np.array([0.0, v0]),
        damper=None, F_static=0.0, terms=(CostTerm("speed", np.array([[0.0, 1.0, 0.0, -target]]),
                                                   np.array([1e-3])),),
        limits=(), penalty=0.0, episode_name="free mass")


def test_free_mass_closed_form():
    """A passive device cannot speed a free mass up (its kinetic energy can only fall, |v| ≤ v0), so with a target
    above v0 the best it can do is nothing: the bound is the free response's return, −N·dt·(v0 − target)², exactly;
    the ideal actuator accelerates the mass and scores more."""
    p = _free_mass()
    exact = -(p.n_rows - 1) * 1e-3 * (1.0 - 2.0) ** 2
    pas = dissipative_bound(p, f_max=50.0)
    act = active_bound(p, f_max=50.0)
    assert pas.bound == pytest.approx(exact, rel=1e-6)
    assert np.max(np.abs(pas.X[:, 1])) <= 1.0 + 1e-6
    assert act.bound > exact + 0.1
    assert np.max(act.X[:, 1]) > 1.5


def test_car_cannot_move_before_the_bump_reaches_it():
    """At rest with an empty store a passive device takes no energy, so it can give none: the passive optimum
    follows the free response exactly until the bump arrives, where the ideal actuator already moves the car; on
    the bump the passive bound is far below the active one and still above every law."""
    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=0, control_dt=0.001, road="bump", episode_seconds=1.0,
                        road_params={"height": 0.05, "length": 0.5, "speed": 10.0})
    free = free_response(p)
    still = int(np.argmax(np.any(np.abs(free - p.x0) > 1e-12, axis=1)))   # first row the road moves the car
    assert still > 50
    f_max = 6000.0
    act, pas = active_bound(p, f_max=f_max), dissipative_bound(p, f_max=f_max)
    scale = np.abs(free).max()
    np.testing.assert_allclose(pas.X[:still], free[:still], atol=1e-7 * scale)
    assert np.max(np.abs(act.X[:still] - free[:still])) > 1e-4 * scale
    assert pas.bound < act.bound - 0.2 * abs(act.bound)
    for law in ("skyhook_continuous", "passive_off", "passive_on"):
        tr = p.replay(p.commands_of(lambda e, n=law: make_controller(n, e)), states=True)
        assert np.max(np.abs(tr.F - p.F_static)) <= f_max
        assert absorbed_energy(p, tr.F).min() >= -1e-9
        assert tr.ret < pas.bound, law


def test_passive_bound_bad_inputs(problem):
    for bad in (-1.0, float("nan"), math.inf, True, "1"):
        with pytest.raises(ValueError, match="storage"):
            dissipative_bound(problem, f_max=100.0, storage=bad)
    with pytest.raises(ValueError, match="f_max"):
        dissipative_bound(problem, f_max=-1.0)
    A = problem.A.copy()
    A[0, 0] = 0.5                         # not x = [q, q̇]
    with pytest.raises(ValueError, match="mechanical"):
        dissipative_bound(dataclasses.replace(problem, A=A), f_max=100.0)
    n = problem.nx // 2
    A = problem.A.copy()
    A[n:, n:] = np.abs(A[n:, n:]).max() + 1.0 + np.abs(A[n:, n:])  # damping that feeds energy in
    with pytest.raises(ValueError, match="storage"):
        port_storage(dataclasses.replace(problem, A=A))
