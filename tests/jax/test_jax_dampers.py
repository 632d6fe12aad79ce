"""The JAX twins of every damper model (:mod:`mrd_env.jax.dampers`, issue 41) against the numba functions they mirror:
rhs, force, project and the Jacobian on random states, inputs and commands at each model's default preset; the
Jacobian against calculus (``jax.jacfwd``); a quarter car's record through the exact scheme against the numba kernel;
the quarter car's JAX environment with each model. The record runs and rollouts of all models but one are
``slow`` (one compilation each)."""
from __future__ import annotations

import functools

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import jax.numpy as jnp  # noqa: E402

import mrd_env.jax  # noqa: E402,F401  (float64)
from mrd_env.dampers.registry import available_dampers, damper_class  # noqa: E402
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.envs import options as opt  # noqa: E402
from mrd_env.jax.dampers import MODELS, jax_damper  # noqa: E402
from mrd_env.jax.simulate import run as jax_run  # noqa: E402
from mrd_env.mechanics import CoupledPlant  # noqa: E402
from mrd_env.plants.quarter_car import jax_twin as qc  # noqa: E402
from mrd_env.plants.quarter_car.physics import quarter_car  # noqa: E402
from mrd_env.stepping import run as numba_run  # noqa: E402
from mrd_env.stepping.codegen import kernel_module  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
NAMES = available_dampers()
N = 300  # random samples per model
ZEROS = 12  # of which the first have exact zeros (x, ẋ, the hysteretic state): the branches' edges
EPS = np.finfo(float).eps
#: the model whose record and rollout run in the default selection (one compilation each): two states, the kernel's
#: forward-difference Jacobian, the branch switched between steps from ẋ; Spencer–Dyke's is in test_jax_twin.py
FAST = "sigmoid"
#: the models whose Jacobian is checked against the kernel's in the default selection (the kernel's forward
#: differences compile in about a second per model): the analytic ones and forward differences with 0, 1, 2 states
KERNEL_FD = ("bingham", "dahl", "sigmoid", "spencer_dyke", "bouc_wen")


def _state_scales(d) -> tuple:
    """The size of each internal state at the preset (the draws go 20 % beyond it, past any saturation)."""
    if d.name == "spencer_dyke":
        return 0.05, d.saturation()  # y (m) follows the stroke
    if d.name == "gamota_filisko":
        return 2000.0, 2000.0  # spring forces (N), across the Bingham element's dead zone ±f_c
    if d.name in ("sigmoid", "hysteretic_bi_viscous"):
        return 0.5, 1.0  # filtered velocity (m/s), branch σ
    return (d.saturation(),) * d.n_states  # the hysteresis variable within its saturation


@functools.lru_cache(maxsize=None)
def _case(name):
    """A model's numba and JAX values on N random (s, x, ẋ, ẍ, u)."""
    cls = damper_class(name)
    d = cls()
    ns = d.n_states
    rng = np.random.default_rng(sum(map(ord, name)))
    S = np.stack([rng.uniform(-1.2 * s, 1.2 * s, N) for s in _state_scales(d)], -1) if ns else np.zeros((N, 0))
    x, xd, xdd = rng.uniform(-0.05, 0.05, N), rng.uniform(-0.5, 0.5, N), rng.uniform(-20.0, 20.0, N)
    u = rng.uniform(d.command.v_min, d.command.v_max, N)
    x[:ZEROS:2] = 0.0
    xd[:ZEROS // 2] = 0.0
    S[1:ZEROS:3] = 0.0
    p = d.params.as_array()
    ref = {"rhs": np.zeros((N, ns)), "force": np.zeros(N), "project": np.zeros((N, ns))}
    for i in range(N):
        s = S[i].copy()
        cls.rhs(p, s, x[i], xd[i], u[i], ref["rhs"][i])
        ref["force"][i] = cls.force_law(p, s, x[i], xd[i], xdd[i], u[i])
        cls.project(p, s, x[i], xd[i], u[i])
        ref["project"][i] = s
    m = jax_damper(name)
    pj, sj = jnp.asarray(p), tuple(jnp.asarray(S[:, k]) for k in range(ns))

    def cols(values):
        return np.stack([np.broadcast_to(np.asarray(v), (N,)) for v in values], -1) if len(values) else np.zeros((N, 0))

    got = {"rhs": cols(m.rhs(pj, sj, x, xd, u)), "force": np.asarray(m.force(pj, sj, x, xd, xdd, u)),
           "project": cols(m.project(pj, sj, x, xd, u)),
           "partials": np.stack([cols(row) for row in m.partials(pj, sj, x, xd, xdd, u)], 1)}
    return cls, m, (S, x, xd, xdd, u), ref, got


def _relative(a, b):
    """max |a − b| over the samples, per component relative to that component's largest |b|."""
    a, b = np.asarray(a), np.asarray(b)
    if b.size == 0:
        return 0.0
    scale = np.abs(b).max(axis=0)
    return float(np.max(np.abs(a - b) / np.where(scale > 0, scale, 1.0)))


def test_every_model_of_the_registry_has_a_twin():
    assert sorted(MODELS) == NAMES
    for name in NAMES:
        assert jax_damper(name).name == name and jax_damper(name).ns == len(damper_class(name).state_names)
    with pytest.raises(ValueError, match="no JAX twin.*spencer_dyke"):
        jax_damper("no_such_model")


@pytest.mark.parametrize("name", NAMES)
def test_rhs_force_project_match_numba(name):
    _, m, _, ref, got = _case(name)
    for key in ("rhs", "force", "project"):
        assert got[key].shape == ref[key].shape, key
        assert _relative(got[key], ref[key]) <= 1e-12, key


@pytest.mark.parametrize("name", [n if n in KERNEL_FD else pytest.param(n, marks=pytest.mark.slow) for n in NAMES])
def test_partials_match_the_kernels(name):
    """Analytic derivatives to rounding; the kernel's forward differences to the rounding of the two evaluations
    over the step (XLA's tanh and exp may differ from libm's by an ulp: divided by a step of 1e-7·|value|)."""
    cls, m, (S, x, xd, xdd, u), ref, got = _case(name)
    ns = S.shape[1]
    # the Jacobian the kernel uses: the model's analytic one, else the kernel's own forward differences
    partials = cls.partials if cls.partials is not None else kernel_module(cls, compiled=True).partials
    p = damper_class(name)().params.as_array()
    J_ref = np.zeros((N, ns + 1, ns + 2))
    for i in range(N):
        partials(p, S[i].copy(), x[i], xd[i], xdd[i], u[i], J_ref[i], np.zeros(2 * ns + 2))
    J = got["partials"]
    assert J.shape == J_ref.shape
    if cls.partials is not None:
        assert _relative(J, J_ref) <= 1e-12
        return
    steps = 1e-7 * np.maximum(np.abs(np.column_stack([S, x, xd])), 1e-3)  # (N, ns + 2): the kernel's steps
    rows = np.abs(np.column_stack([ref["rhs"], ref["force"]])).max(axis=0)  # (ns + 1,): the values' sizes
    bound = 64 * EPS * rows[None, :, None] / steps[:, None, :] + 1e-12 * np.abs(J_ref).max(axis=0)
    assert np.all(np.abs(J - J_ref) <= bound), np.max(np.abs(J - J_ref) / bound)


@pytest.mark.parametrize("name", ["spencer_dyke", "bouc_wen"])
def test_exact_jacobian_is_the_analytic_one(name):
    """The option ``jacobian="exact"`` (``jax.jacfwd`` of the equations) against the numba model's hand-derived
    partials, on the same random states (away from the kinks: the samples without exact zeros)."""
    cls, _, (S, x, xd, xdd, u), _, _ = _case(name)
    ns = S.shape[1]
    p = damper_class(name)().params.as_array()
    m = jax_damper(name, "exact")
    keep = np.arange(ZEROS, N)
    J_ref = np.zeros((len(keep), ns + 1, ns + 2))
    for k, i in enumerate(keep):
        cls.partials(p, S[i].copy(), x[i], xd[i], xdd[i], u[i], J_ref[k], np.zeros(2 * ns + 2))
    J = np.asarray(jax.vmap(lambda s, *a: jnp.asarray(m.partials(jnp.asarray(p), tuple(s), *a)))(
        jnp.asarray(S[keep]), *(jnp.asarray(v[keep]) for v in (x, xd, xdd, u))))
    assert _relative(J, J_ref) <= 1e-12
    with pytest.raises(ValueError, match="jacobian"):
        jax_damper(name, "numerical")


@pytest.mark.parametrize("name", NAMES)
def test_partials_match_calculus(name):
    """J against ``jax.jacfwd`` of (rhs, force), away from the kinks (the samples without exact zeros): analytic
    ones to rounding, forward differences to their truncation (1e-5 of each entry's size)."""
    cls, m, (S, x, xd, xdd, u), _, got = _case(name)
    ns = S.shape[1]
    p = jnp.asarray(damper_class(m.name)().params.as_array())

    def jac(v, a, c):
        def f(w):
            s = tuple(w[k] for k in range(ns))
            return jnp.stack([*m.rhs(p, s, w[ns], w[ns + 1], c), m.force(p, s, w[ns], w[ns + 1], a, c)])
        return jax.jacfwd(f)(v)

    V = np.column_stack([S, x, xd])[ZEROS:]
    J_ad = np.asarray(jax.jit(jax.vmap(jac))(jnp.asarray(V), xdd[ZEROS:], u[ZEROS:]))
    assert np.all(np.isfinite(J_ad))
    assert _relative(got["partials"][ZEROS:], J_ad) <= (1e-12 if cls.partials is not None else 1e-5)


@pytest.mark.parametrize("name", NAMES)
def test_derivatives_are_finite_at_rest(name):
    """At rest (ẋ = 0, states 0: every reset), jax.grad of the force, ṡ, the Jacobian and the projection through the
    twin is finite (no NaN from an unselected branch of a jnp.where)."""
    m, d = jax_damper(name), damper_class(name)()
    p = jnp.asarray(d.params.as_array())

    def total(v):
        s = tuple(v[k] for k in range(m.ns))
        x, xd, u = v[m.ns], v[m.ns + 1], v[m.ns + 2]
        J = m.partials(p, s, x, xd, 0.0, u)
        return (m.force(p, s, x, xd, 0.0, u) + sum(m.rhs(p, s, x, xd, u), 0.0) + sum(sum(row) for row in J)
                + sum(m.project(p, s, x, xd, u), 0.0))

    g = jax.jit(jax.grad(total))(jnp.zeros(m.ns + 3).at[-1].set(d.command.v_max))
    assert np.all(np.isfinite(np.asarray(g)))


def _record(name, road_class="C", steps=300):
    """A quarter car with the model (its automotive preset where it has one, as the environments) on an ISO 8608
    road, commands switched every 10 ms, from rest."""
    d = opt.make_env_damper(name, None, None, "automotive")
    system = CoupledPlant(quarter_car("set_a").plant(), d).system
    road = iso8608_road(road_class, 20.0, steps * 1e-3, 1e-3, rng=11, method="fft").data[:steps + 1]
    W = np.hstack([road, np.ones((steps + 1, 1))])
    V = np.repeat(np.random.default_rng(5).uniform(d.command.v_min, d.command.v_max, steps // 10), 10)[:, None]
    q0 = np.array([road[0, 0], road[0, 0], road[0, 1], road[0, 1]])
    Y0 = np.concatenate([q0, d.rest_states(system.C[0] @ q0 + system.D[0] @ W[0])])
    return d, system, Y0, np.full(1, d.command.v_min), V, W


def _difference(Y, F, Y_ref, F_ref):
    return max(float(np.max(np.abs(Y - Y_ref) / np.abs(Y_ref).max(axis=0))),
               float(np.max(np.abs(F - F_ref)) / np.abs(F_ref).max()))


@pytest.mark.parametrize("name", [n if n == FAST else pytest.param(n, marks=pytest.mark.slow) for n in NAMES])
def test_record_matches_the_numba_kernel(name):
    """The exact scheme's record against the kernel's: within 1e-12, or within 100× the kernel's own response to a
    rounding-level change, whichever is larger: 1 ulp of one initial plant coordinate, or of every input sample.
    (Newton stops at 1 % of the tolerance and the sub-steps are chosen by comparisons: a rounding-level difference
    flips a decision somewhere in a stiff model's record, and the kernel then differs from itself by as much as
    from its twin. The twin's rounding differs from the kernel's at every step, not only at the start: XLA's tanh,
    exp and arctanh differ from libm's by an ulp for 57 %, 15 % and 34 % of arguments; for the Dominguez model,
    all transcendental, only the perturbation at every step shows the kernel's own spread, 1.8e-12 against 2.2e-14
    from an initial coordinate. See docs/jax.md.)"""
    d, system, Y0, U0, V, W = _record(name)
    F, Y, status, _ = jax_run(d, system, Y0, U0, V, W, 1e-3)
    assert np.all(np.asarray(status) == 0)
    n = Y0.size

    def kernel(y0, w):
        F_n, Y_n, _ = numba_run(d, system, y0[None].copy(), U0[None].copy(), V[None], w[None], 1e-3)
        return Y_n[0, :, :n], F_n[0, :, 0]

    Y_n, F_n = kernel(Y0, W)
    spread = 0.0
    for i in range(4):
        y1 = Y0.copy()
        y1[i] = np.nextafter(y1[i], np.inf)
        spread = max(spread, _difference(*kernel(y1, W), Y_n, F_n))
    w1 = W.copy()
    w1[:, :-1] = np.nextafter(w1[:, :-1], np.inf)  # every road sample (not the constant channel)
    spread = max(spread, _difference(*kernel(Y0, w1), Y_n, F_n))
    diff = _difference(np.asarray(Y), np.asarray(F[:, 0]), Y_n, F_n)
    print(f"{name}: JAX vs numba {diff:.1e}, numba vs itself after 1 ulp {spread:.1e}")
    assert diff <= max(1e-12, 100 * spread)


def test_quarter_car_env_with_every_model():
    """make_params takes every model (its automotive preset where it has one) and the twin steps from its reset."""
    for name in NAMES:
        params = qc.make_params(damper=name, n_roads=1, episode_seconds=0.05)
        assert params.model == name and params.P.shape[2] == len(damper_class(name).Params.names())


@pytest.mark.parametrize("name", [n if n == FAST else pytest.param(n, marks=pytest.mark.slow) for n in NAMES])
def test_quarter_car_rollout_is_finite(name):
    params = qc.make_params(damper=name, n_roads=1, episode_seconds=0.05, scheme="differentiable")
    _, state = qc.reset(None, params, record=0)
    actions = jnp.asarray(np.random.default_rng(2).uniform(-1.0, 1.0, (params.n_steps, 1)))
    final, obs, reward, terminated, truncated = jax.jit(qc.rollout)(params, state, actions)
    assert np.all(np.isfinite(np.asarray(obs))) and np.all(np.isfinite(np.asarray(reward)))
    assert int(final.status) == 0 and not np.any(np.asarray(terminated))
