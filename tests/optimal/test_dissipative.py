"""The passivity-aware bound on non-zero initial strokes and per-damper static forces (issue 51, item 5).

The full car starts at rest on the road's initial heights: its strokes are off zero and each damper holds its own
static force. The bound refers each damper's port to that force: the environment's dampers at reset hold exactly
those forces, its runs lie in the class (they absorb energy from the first row on) and score below the bound; the
damper locked at its static forces is in the class, and outside the old one referred to F_static; two masses held
off their springs' rest by their dampers cannot be moved by a passive device (closed form); on plants whose strokes
start at zero the bound is the one before the generalisation; the stored clairvoyant of suite episodes of every
plant lies below it. The damper's viscous floor (min_damping): its energy against a fine-grid integration, the
environment's runs in its class, a tighter bound, no force history with f_max = 0."""
import math

import numpy as np
import pytest

from controllers import make_controller
from mrd_env.mechanics.response import foh_response
from mrd_env.optimal import CostTerm, EpisodeProblem, active_bound, dissipative_bound, episode_problem
from mrd_env.optimal.dissipative import absorbed_energy, free_response, static_forces, viscous_floor

ROAD = {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}}


@pytest.fixture(scope="module")
def full_car():
    """0.3 s of the full car on a class C road, from its warped start (the strokes off zero)."""
    return episode_problem("mrd_env/FullCarPhysical-v0", seed=1000000, control_dt=1e-3, episode_seconds=0.3, **ROAD)


@pytest.fixture(scope="module")
def full_car_runs(full_car):
    p = full_car
    return {law: p.replay(p.commands_of(lambda e, n=law: make_controller(n, e)), states=True)
            for law in ("passive_off", "passive_on", "skyhook_continuous")}


def test_static_forces_are_the_dampers_forces_at_reset(full_car):
    """Each damper's static force is the environment's damper force after reset (at rest at its initial stroke),
    F_static + k1·x_d(0) for the Spencer–Dyke accumulator; where the strokes start at 0 it is F_static exactly."""
    p = full_car
    env = p.make_env()
    env.reset(seed=p.seed)
    Fs = static_forces(p)
    xd0 = p.Cx @ p.x0
    assert np.min(np.abs(xd0)) > 1e-4                                  # a warped start: every stroke off zero
    np.testing.assert_allclose(Fs, env.damper_force, rtol=0, atol=1e-9)
    np.testing.assert_allclose(Fs - p.F_static, p.damper.params.k1 * xd0, rtol=1e-9)
    for env_id, opts in (("mrd_env/QuarterCarPhysical-v0", {}), ("mrd_env/ShearBuildingPhysical-v0", {})):
        q = episode_problem(env_id, seed=1000000, control_dt=1e-3, episode_seconds=0.05, **opts)
        assert np.all(static_forces(q) == q.F_static)


def test_locked_damper_lies_in_the_class_only_referred_to_its_static_forces(full_car):
    """The damper locked at its static forces (F ≡ F_s) takes no energy from the plant referred to F_s — it is in
    the class — but referred to F_static (the accounting before issue 51) it has given energy back: the old class
    left it out. With f_max = 0 the one force history, F ≡ F_static, is not a passive device's on this start: no
    bound, an error."""
    p = full_car
    Fs = static_forces(p)
    locked = np.tile(Fs, (p.n_rows, 1))
    mine = absorbed_energy(p, locked)
    assert np.max(np.abs(mine)) <= 1e-12
    assert absorbed_energy(p, locked, static_forces=p.F_static).min() < -1e-3
    with pytest.raises(RuntimeError, match="infeasible"):
        dissipative_bound(p, f_max=0.0)


def test_full_car_bound_lies_between_its_runs_and_the_active_bound(full_car, full_car_runs):
    """On the warped start the bound solves (it was infeasible before issue 51), the environment's runs absorb
    energy from the first row on (on their own forces and states) and score below it, and it is not above the
    active bound of the same force limit."""
    p = full_car
    f_max = max(float(np.max(np.abs(tr.F - p.F_static))) for tr in full_car_runs.values())
    pas = dissipative_bound(p, f_max=f_max, tol=1e-6)
    act = active_bound(p, f_max=f_max, tol=1e-6)
    assert pas.bound <= act.bound + 1e-6 * abs(act.bound)
    np.testing.assert_array_equal(pas.static_forces, static_forces(p))
    for law, tr in full_car_runs.items():
        assert not tr.terminated, law
        assert absorbed_energy(p, tr.F, tr.X).min() >= -1e-9, law
        assert tr.ret < pas.bound, law
    assert pas.absorbed.min() >= -1e-5 * np.max(np.abs(pas.absorbed))   # its own optimum lies in the class


def _held_masses(static=-20.0, k=(1000.0, 2000.0), m=(5.0, 8.0), q0=(0.01, -0.02), n_rows=201):
    """Two masses on their springs, each with a damper to the ground, held off the springs' rest at q0 by their
    dampers' static forces F_s = F_static − k·q0; the cost is the distance from the springs' rest,
    Σ |q|² over rows 1..N."""
    Mi, K = np.diag(1.0 / np.asarray(m)), np.diag(k)
    Z, I2 = np.zeros((2, 2)), np.eye(2)
    G = np.zeros((2, 7))
    G[0, 0] = G[1, 1] = 1.0
    return EpisodeProblem(
        env_id="held masses", options={}, seed=0, dt=1e-3, control_dt=1e-3, n_sub=1, n_steps=n_rows - 1,
        A=np.block([[Z, I2], [-Mi @ K, Z]]), BF=np.vstack([Z, -Mi]),
        Bw=np.concatenate([np.zeros(2), Mi @ np.full(2, static)])[:, None], Cx=np.hstack([I2, Z]),
        Cv=np.hstack([Z, I2]), W=np.ones((n_rows, 1)), x0=np.array([*q0, 0.0, 0.0]), damper=None,
        F_static=static, terms=(CostTerm("q", G, np.array([1.0, 1.0])),), limits=(), penalty=0.0,
        episode_name="held masses")


def test_held_masses_closed_form():
    """Masses held at rest off their springs' rest by their dampers (a different static force each): a passive
    device at rest with an empty store can give nothing, so the masses stay where they are, and the bound is that
    return, −N·|q0|², exactly; the ideal actuator pulls them back and scores more. Referred to F_static instead,
    the "passive" class lets the dampers let go of their static forces and the springs pull the masses back."""
    p = _held_masses()
    Fs = p.F_static - np.array([1000.0 * 0.01, 2000.0 * -0.02])
    exact = -(p.n_rows - 1) * (0.01 ** 2 + 0.02 ** 2)
    pas = dissipative_bound(p, f_max=100.0, static_forces=Fs)
    assert pas.bound == pytest.approx(exact, rel=1e-6)
    np.testing.assert_allclose(pas.X, np.tile(p.x0, (p.n_rows, 1)), atol=1e-9)
    np.testing.assert_allclose(free_response(p, Fs), np.tile(p.x0, (p.n_rows, 1)), atol=1e-12)
    assert active_bound(p, f_max=100.0).bound > exact + 0.3 * abs(exact)
    assert dissipative_bound(p, f_max=100.0, static_forces=p.F_static).bound > exact + 0.3 * abs(exact)
    with pytest.raises(ValueError, match="static_forces"):
        static_forces(p)                                            # no damper model to give them


def test_the_quarter_car_bound_is_the_one_before_the_generalisation():
    """Where the strokes start at zero nothing changed: car-comfort-v1's bump with its stored f_max gives the
    bound the code before issue 51 gave (docs/yardstick.md, "the bracket on every suite episode": −2.4246)."""
    from mrd_env.suites import suites

    s = suites()["car-comfort-v1"]
    sc, seed = next((sc, seed) for sc, seed in s.episodes() if sc.name == "bump 5 cm")
    p = episode_problem(s.env_id, seed=int(seed), control_dt=1e-3, **s.reference_options(sc, seed))
    ref = s.reference(sc.label(seed))
    d = dissipative_bound(p, f_max=ref.f_max)
    assert d.bound == pytest.approx(-2.424599986972971, rel=1e-7)
    assert ref.clairvoyant <= d.bound <= ref.bound
    assert ref.passive < d.bound


# the stored references of one episode of each plant's suites: R_c ≤ R_d ≤ R_b, R_p ≤ R_d; bounds before issue 51
# where known (docs/yardstick.md's tables)
SUITE_EPISODES = [("car-comfort-v1", "ISO-C 20 m/s s1000000", -1.4992394547457533),
                  ("car-comfort-robust-v1", "bump 5 cm", -2.4187552776466066),
                  ("building-seismic-v1", "El Centro NS (×0.2 time)", -0.07313655475541958),
                  ("building-six-storey-v1", "Kanai–Tajimi s1000001", None),
                  ("car-full-v3", "ISO-C 20 m/s s1000000", None),
                  ("car-full-v3", "bump 5 cm left", None)]


@pytest.mark.slow
@pytest.mark.parametrize("suite_id,label,before", SUITE_EPISODES, ids=[f"{a}:{b}" for a, b, _ in SUITE_EPISODES])
def test_bound_is_above_the_stored_clairvoyant_on_suite_episodes(suite_id, label, before):
    """On a suite episode of every plant (the full car's warped start and its bump included), with the suite's
    stored f_max: the stored clairvoyant R_c and best constant command R_p lie below R_d, R_d below the stored R_b;
    with the damper's viscous floor the bound is no larger and still above R_c. Where the strokes start at zero,
    R_d is the bound before issue 51."""
    from mrd_env.suites import suites

    s = suites()[suite_id]
    sc, seed = next((sc, seed) for sc, seed in s.episodes() if sc.label(seed) == label)
    ref = s.reference(label)
    p = episode_problem(s.env_id, seed=int(seed), control_dt=1e-3, **s.reference_options(sc, seed))
    tol = 1e-6 if p.nd > 1 else 1e-8   # four dampers: Clarabel stalls short of 1e-8 on some episodes
    d = dissipative_bound(p, f_max=ref.f_max, tol=tol)
    assert ref.passive < ref.clairvoyant <= d.bound <= ref.bound + 1e-6 * abs(ref.bound)
    if before is not None:
        assert d.bound == pytest.approx(before, rel=1e-7)
    dc = dissipative_bound(p, f_max=ref.f_max, tol=tol, min_damping=viscous_floor(p.damper))
    assert ref.clairvoyant <= dc.bound <= d.bound + 1e-6 * abs(d.bound)


def test_min_damping_energy_against_a_fine_grid(full_car, full_car_runs):
    """The energy beyond a dashpot c_min, ∫(F − F_s)·ẋ_d − c_min·ẋ_d², per damper c_min, by Gauss–Legendre on each
    row, is the trapezoidal integral on a 20× finer grid of the same plant."""
    p = full_car
    F = full_car_runs["skyhook_continuous"].F
    c = np.array([744.0, 500.0, 0.0, 100.0])
    k = 20
    t, tf = np.arange(p.n_rows), np.arange((p.n_rows - 1) * k + 1) / k
    U = np.hstack([F, p.W])
    Uf = np.column_stack([np.interp(tf, t, U[:, j]) for j in range(U.shape[1])])
    V = foh_response(p.A, np.hstack([p.BF, p.Bw]), Uf, p.dt / k, x0=p.x0) @ p.Cv.T
    y = np.sum((Uf[:, :p.nd] - static_forces(p)) * V - c * V ** 2, axis=1)
    fine = np.concatenate([[0.0], np.cumsum(0.5 * p.dt / k * (y[1:] + y[:-1]))])[::k]
    rows = absorbed_energy(p, F, min_damping=c)
    np.testing.assert_allclose(rows, fine, atol=1e-5 * np.max(np.abs(rows)))
    assert rows[-1] < absorbed_energy(p, F)[-1]


def test_viscous_floor_narrows_the_class_and_the_bound():
    """The Spencer–Dyke damper's viscous floor (c0, c1 in series at the minimum command, 744 N·s/m for the
    automotive preset): the environment's runs absorb at least its energy from the first row on and score below the
    tighter bound; more floor, no larger bound; with f_max = 0 no force history (F ≡ F_static absorbs nothing while
    the stroke moves) belongs to the class."""
    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1000000, control_dt=1e-3, episode_seconds=1.0, **ROAD)
    q = p.damper.params
    c = viscous_floor(p.damper)
    assert c == pytest.approx(q.c0a * q.c1a / (q.c0a + q.c1a))
    assert c == pytest.approx(744.17, abs=0.01)
    runs = {law: p.replay(p.commands_of(lambda e, n=law: make_controller(n, e)), states=True)
            for law in ("passive_off", "passive_on", "skyhook_continuous", "clipped_optimal")}
    f_max = max(float(np.max(np.abs(tr.F - p.F_static))) for tr in runs.values())
    plain = dissipative_bound(p, f_max=f_max)
    floor = dissipative_bound(p, f_max=f_max, min_damping=c)
    more = dissipative_bound(p, f_max=f_max, min_damping=2 * c)
    assert more.bound <= floor.bound + 1e-7 * abs(floor.bound) <= plain.bound + 2e-7 * abs(plain.bound)
    assert floor.bound < plain.bound - 1e-3 * abs(plain.bound)           # it tightens, measurably
    for law, tr in runs.items():
        assert absorbed_energy(p, tr.F, tr.X, min_damping=c).min() >= -1e-9, law
        assert tr.ret < floor.bound, law
    assert floor.absorbed.min() >= -1e-5 * np.max(np.abs(floor.absorbed))
    with pytest.raises(RuntimeError, match="infeasible"):
        dissipative_bound(p, f_max=0.0, min_damping=c)


def test_small_force_limit_tends_to_the_free_response():
    """f_max → 0 on the quarter car (strokes from zero, F_s = F_static): the bound falls to the free response's
    return (the one force history at f_max = 0) from above, at a finite rate (a tenth of the force, about a tenth of
    the gain; the solver's constant part of the cost is good to ~1e-6 of it, which limits how small a gain can be
    told apart)."""
    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1000000, control_dt=1e-3, episode_seconds=1.0, **ROAD)
    free = p.linear_return(free_response(p), np.full((p.n_rows, p.nd), p.F_static))
    r0, r1, r2, r3 = (dissipative_bound(p, f_max=f) for f in (0.0, 0.01, 0.1, 10.0))
    assert r0.bound == pytest.approx(free, rel=1e-6)
    g1, g2, g3 = r1.bound - free, r2.bound - free, r3.bound - free
    assert 0.0 < g1 < g2 < g3
    assert 0.05 * g2 <= g1 <= 0.2 * g2


def test_bad_generalisation_inputs(full_car):
    p = full_car
    for bad in (np.ones(3), [1.0, math.nan, 0.0, 0.0], "x", True):
        with pytest.raises(ValueError, match="static_forces"):
            dissipative_bound(p, f_max=100.0, static_forces=bad)
    for bad in (-1.0, [1.0, 2.0], math.inf, True):
        with pytest.raises(ValueError, match="min_damping"):
            dissipative_bound(p, f_max=100.0, min_damping=bad)
    with pytest.raises(ValueError, match="min_damping"):
        absorbed_energy(p, np.zeros((p.n_rows, p.nd)), min_damping=-5.0)
    with pytest.raises(ValueError, match="Spencer–Dyke"):
        viscous_floor(None)
