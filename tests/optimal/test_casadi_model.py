"""The CasADi damper models (mrd_env.optimal.casadi_model) against the project's own model functions and the rig."""
import numpy as np
import pytest

ca = pytest.importorskip("casadi")

from mrd_env import make_damper
from mrd_env.command_lag import lag_value
from mrd_env.optimal.casadi_model import SUPPORTED_MODELS, CoupledModel, symbolic_damper
from mrd_env.rig import simulate

CASES = [("spencer_dyke", "automotive"), ("spencer_dyke", "spencer1997"), ("bouc_wen", "automotive"),
         ("bouc_wen", "spencer1997")]
EXACT = {"eps_v": 0.0, "eps_z": 0.0, "eps_u": 0.0}


def _random_points(d, sd, rng, n=50, v_min=0.0):
    """(s, x, ẋ, u) at random: z within ±z_s, y and x within ±5 cm, |ẋ| in [v_min, 1] m/s, u in the command range."""
    for _ in range(n):
        s = np.empty(d.n_states)
        s[-1] = rng.uniform(-1.0, 1.0) * sd.z_s
        if d.n_states == 2:
            s[0] = rng.uniform(-0.05, 0.05)
        v = rng.choice([-1.0, 1.0]) * rng.uniform(v_min, 1.0)
        yield s, rng.uniform(-0.05, 0.05), v, rng.uniform(d.command.v_min, d.command.v_max)


def _project_functions(d, s, x, xd, u):
    p = d.params.as_array()
    ds = np.zeros(d.n_states)
    d.rhs(p, s.copy(), x, xd, u, ds)
    F = d.force_law(p, s.copy(), x, xd, 0.0, u)
    J = np.zeros((d.n_states + 1, d.n_states + 2))
    d.partials(p, s.copy(), x, xd, 0.0, u, J, np.zeros(2 * d.n_states + 2))
    return ds, F, J


def _symbolic_functions(sd):
    s, x, xd, u = ca.SX.sym("s", sd.ns), ca.SX.sym("x"), ca.SX.sym("xd"), ca.SX.sym("u")
    g = ca.vertcat(sd.rhs(s, x, xd, u), sd.force(s, x, xd, u))
    J = ca.jacobian(g, ca.vertcat(s, x, xd))
    return ca.Function("f", [s, x, xd, u], [g, J])


@pytest.mark.parametrize("name,preset", CASES)
def test_symbolic_model_equals_the_projects_functions(name, preset):
    """Without smoothing: ṡ, F and their Jacobian in (s, x, ẋ) equal rhs/force_law/partials to rounding."""
    d = make_damper(name, preset=preset)
    sd = symbolic_damper(d, **EXACT)
    f = _symbolic_functions(sd)
    rng = np.random.default_rng(1)
    for s, x, xd, u in _random_points(d, sd, rng, v_min=1e-3):
        ds, F, J = _project_functions(d, s, x, xd, u)
        g, Js = (np.asarray(a) for a in f(s, x, xd, u))
        ref = np.append(ds, F)
        assert np.allclose(g.ravel(), ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
        assert np.allclose(Js, J, rtol=1e-10, atol=1e-10 * np.abs(J).max())


@pytest.mark.parametrize("name,preset", CASES)
def test_default_smoothing_is_inactive_away_from_the_kinks(name, preset):
    """With the default ε: ṡ and F within 1e-6 relative where the velocity across the hysteretic element is >= 1000 ε_v.
    (|z| is smoothed as sqrt(z² + ε_z²), ε_z = 1e-3 z_s; with n = 2 only z|z| is, and its error ε_z²/2 is below 1e-6
    of the term A·|ẋ − ẏ| at every z: ż is compared on that scale.)"""
    d = make_damper(name, preset=preset)
    sd = symbolic_damper(d)
    f = _symbolic_functions(sd)
    rng = np.random.default_rng(2)
    checked = 0
    for s, x, xd, u in _random_points(d, sd, rng, n=200, v_min=0.1):
        ds, F, _ = _project_functions(d, s, x, xd, u)
        rel = xd - ds[0] if d.n_states == 2 else xd  # the velocity across the hysteretic element
        if abs(rel) < 1000 * sd.smoothing.eps_v:
            continue
        g = np.asarray(f(s, x, xd, u)[0]).ravel()
        ref = np.append(ds, F)
        scale = np.abs(ref)
        scale[d.n_states - 1] += sd.p["A"] * abs(rel)
        assert np.all(np.abs(g - ref) <= 1e-6 * scale), (g, ref)
        checked += 1
    assert checked > 20


def test_command_lag_is_the_stepping_routines():
    """The closed-form lag with a delayed switch inside the step, asymmetric rates: lag_value."""
    d = make_damper("spencer_dyke", command={"eta": 300.0, "eta_fall": 125.0, "delay": 3e-4})
    sd = symbolic_damper(d, **EXACT)
    rng = np.random.default_rng(3)
    for _ in range(100):
        u0, va, vb = rng.uniform(0, 2.25, 3)
        ts, tau = rng.uniform(0, 1e-3, 2)
        got = float(sd.lag(u0, va, vb, ts, tau))
        assert got == pytest.approx(lag_value(u0, va, vb, ts, 300.0, 125.0, tau), rel=1e-13, abs=1e-15)


def _sine_record(n=1000, dt=1e-3, X=0.02, f=2.5):
    t = np.arange(n + 1) * dt
    w = 2 * np.pi * f
    x, v, a = X * np.sin(w * t), X * w * np.cos(w * t), -X * w * w * np.sin(w * t)
    cmd = np.where((t % 0.2) < 0.1, 1.5, 0.3)  # switching: the lag's rise and fall both act
    return t, x, v, a, cmd


@pytest.mark.parametrize("name,preset,command", [
    ("spencer_dyke", "automotive", {"eta": 190.0, "eta_fall": 80.0, "delay": 2.5e-3}),
    ("bouc_wen", "spencer1997", {"eta": 190.0, "eta_fall": 80.0, "delay": 3e-4}),
])
def test_discretised_model_is_the_rigs_stepping_routine(name, preset, command):
    """The SDIRK2 residuals of CoupledModel, solved step by step, reproduce the rig's forces (its stepping routine
    without sub-steps, tight Newton tolerance): the optimiser's model is the environment's discretisation."""
    d = make_damper(name, preset=preset, command=command)
    dt = 1e-3
    t, x, v, a, cmd = _sine_record()
    # tight on both tolerances: Newton stops at 1 % of them, and a state error of that size moves the force by
    # α·Δz (atol 1e-5 m would allow about 0.01 N)
    rig = simulate(d, x, cmd, dt, v=v, a=a, rtol=1e-6, atol=1e-10, max_substeps=1)[0]
    sd = symbolic_damper(d, eps_v=1e-9, eps_z=1e-9, eps_u=1e-9)
    m = CoupledModel.rig(sd)
    Va, Vb, ts = sd.delayed(cmd[:-1], dt, cmd[0])
    Y, _, U, F = m.simulate(m.initial_state(), np.c_[x, v], [cmd[0]], Va, Vb, dt, ts)
    assert np.max(np.abs(U[:, 0] - rig.u)) < 1e-9
    assert np.max(np.abs(F[:, 0] - rig.force)) < 1e-5 * np.max(np.abs(rig.force))


@pytest.mark.parametrize("name,preset", [("spencer_dyke", "automotive"), ("bouc_wen", "spencer1997")])
def test_continuous_model_with_a_casadi_integrator_matches_the_rig(name, preset):
    """The continuous symbolic model (damper states and lag) integrated by CVODES at tight tolerance against the
    rig at its default tolerance: force NRMSE well within the rig's documented accuracy (< 0.5 %)."""
    d = make_damper(name, preset=preset, command={"eta": 190.0, "eta_fall": 80.0})
    dt = 1e-3
    t, x, v, a, cmd = _sine_record()
    rig = simulate(d, x, cmd, dt, v=v, a=a)[0]
    sd = symbolic_damper(d)
    X, w = 0.02, 2 * np.pi * 2.5
    # the time is a state (θ̇ = 1), so that one integrator over a step serves every step
    s, u, th, vc = ca.SX.sym("s", sd.ns), ca.SX.sym("u"), ca.SX.sym("theta"), ca.SX.sym("v")
    xs, vs = X * ca.sin(w * th), X * w * ca.cos(w * th)
    ode = ca.vertcat(sd.rhs(s, xs, vs, u), sd.lag_rate(u, vc), 1.0)
    integ = ca.integrator("I", "cvodes", {"x": ca.vertcat(s, u, th), "p": vc, "ode": ode}, 0.0, dt,
                          {"abstol": 1e-12, "reltol": 1e-10})
    Ff = ca.Function("F", [s, th, u], [sd.force(s, xs, vs, u)])
    state = np.concatenate([d.initial_state(), [cmd[0], 0.0]])
    F = [float(Ff(state[:sd.ns], 0.0, cmd[0]))]
    for k in range(len(t) - 1):
        state = np.asarray(integ(x0=state, p=cmd[k])["xf"]).ravel()
        F.append(float(Ff(state[:sd.ns], state[-1], state[sd.ns])))
    F = np.asarray(F)
    nrmse = np.sqrt(np.mean((F - rig.force) ** 2)) / np.sqrt(np.mean(rig.force ** 2))
    assert nrmse < 5e-3


def test_unsupported_damper_raises_naming_the_supported_models():
    with pytest.raises(ValueError, match="spencer_dyke.*bouc_wen"):
        symbolic_damper(make_damper("bingham"))
    assert SUPPORTED_MODELS == ("spencer_dyke", "bouc_wen")


def test_smoothing_options_are_checked():
    with pytest.raises(ValueError, match="eps_v"):
        symbolic_damper(make_damper("spencer_dyke"), eps_v=-1.0)


@pytest.mark.parametrize("name,preset", [("spencer_dyke", "automotive"), ("bouc_wen", "spencer1997")])
def test_unrolled_newton_step_is_the_converged_step(name, preset):
    """newton_step (plant eliminated, 4 Newton iterations, exact projection) reproduces simulate's converged stages on
    the rig within 1e-8 of the force scale, and the smooth projection (the optimisers') within 0.5 %."""
    d = make_damper(name, preset=preset, command={"eta": 190.0, "eta_fall": 80.0})
    dt = 1e-3
    t, x, v, a, cmd = _sine_record(n=400)
    sd = symbolic_damper(d)
    m = CoupledModel.rig(sd)
    W = np.c_[x, v]
    Y, _, U, F = m.simulate(m.initial_state(), W, [cmd[0]], cmd[:-1], cmd[:-1], dt)
    for project, tol in (("exact", 1e-8), ("smooth", 5e-3)):
        step = m.newton_step(dt, 0.0, 4, project)
        y, f, u = m.initial_state(), F[0], np.array([cmd[0]])
        Fs = [f[0]]
        for k in range(len(t) - 1):
            y, f, u = (np.asarray(o).ravel() for o in step(y, f, W[k], W[k + 1], u, cmd[k], cmd[k]))
            Fs.append(f[0])
        assert np.max(np.abs(np.asarray(Fs) - F[:, 0])) < tol * np.max(np.abs(F))
