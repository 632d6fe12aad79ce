"""The JAX twin of the physics (:mod:`mrd_env.jax`, issue 41): the exact scheme against the numba kernel, the
differentiable one against the exact one, its gradient against finite differences, the environment's shapes
under jit and vmap, seeds, bad input. Kept short (compilation dominates: one small episode per function)."""
from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import jax.numpy as jnp  # noqa: E402

import mrd_env.jax  # noqa: E402,F401  (float64)
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.envs import options as opt  # noqa: E402
from mrd_env.plants.quarter_car import jax_twin as qc  # noqa: E402
from mrd_env.jax.simulate import run as jax_run  # noqa: E402
from mrd_env.mechanics import CoupledPlant  # noqa: E402
from mrd_env.plants.quarter_car.physics import quarter_car  # noqa: E402
from mrd_env.stepping import run as numba_run  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")  # one worker compiles them: the jitted functions are shared
DT = 1e-3
STEPS = 300
N = 4  # environments in the vmapped tests (one shape: one compilation)


@pytest.fixture(scope="module")
def car():
    """The quarter car's system with the default damper, a class-D road (rough: the adaptive step sub-steps) and
    commands switched every 10 ms."""
    d = opt.make_env_damper("spencer_dyke", None, None, "automotive")
    system = CoupledPlant(quarter_car("set_a").plant(), d).system
    road = iso8608_road("D", 20.0, STEPS * DT, DT, rng=11, method="fft").data[:STEPS + 1]
    W = np.hstack([road, np.ones((STEPS + 1, 1))])
    V = np.repeat(np.random.default_rng(5).uniform(0.0, 2.0, STEPS // 10), 10)[:, None]
    Y0 = np.array([road[0, 0], road[0, 0], road[0, 1], road[0, 1], 0.0, 0.0])
    return d, system, Y0, V, W


@pytest.fixture(scope="module")
def exact(car):
    d, system, Y0, V, W = car
    F, Y, status, used = jax_run(d, system, Y0, np.zeros(1), V, W, DT)
    assert np.all(np.asarray(status) == 0)
    return np.asarray(F[:, 0]), np.asarray(Y), np.asarray(used)


def test_exact_scheme_matches_the_numba_kernel(car, exact):
    d, system, Y0, V, W = car
    F_n, Y_n, _ = numba_run(d, system, Y0[None].copy(), np.zeros((1, 1)), V[None], W[None], DT)
    F, Y, used = exact
    Y_n = Y_n[0, :, :Y.shape[1]]  # (the history's last column is the command)
    assert used.max() > 1  # the episode exercises the sub-steps
    assert np.max(np.abs(Y - Y_n) / np.abs(Y_n).max(axis=0)) < 1e-12
    assert np.max(np.abs(F - F_n[0, :, 0])) < 1e-12 * np.abs(F_n).max()


def test_differentiable_scheme_within_its_accuracy_of_the_exact_one(car, exact):
    d, system, Y0, V, W = car
    F = np.asarray(jax_run(d, system, Y0, np.zeros(1), V, W, DT, scheme="differentiable")[0][:, 0])
    F_exact = exact[0]
    nrmse = np.sqrt(np.mean((F - F_exact) ** 2) / np.mean(F_exact ** 2))
    assert 1e-6 < nrmse < 0.005  # not the same scheme, and within the accuracy the kernel is held to


def test_gradient_of_an_episode_cost_matches_finite_differences(car):
    """d/dV of Σ F² through the differentiable scheme, against fourth-order central differences."""
    from mrd_env.jax.simulate import plant_arrays, simulate

    d, system, Y0, V, W = car
    plant = plant_arrays(system, DT)
    P, lag = jnp.asarray(d.params.as_array()[None]), jnp.asarray(d.command.lag_vector()[None])

    def cost(v):
        F = simulate(plant, P, lag, jnp.asarray(Y0), jnp.zeros(1), v[:, None], jnp.asarray(W), DT,
                     model=d.name, scheme="differentiable")[0]
        return jnp.mean(F ** 2) * 1e-6

    v = jnp.asarray(V[:, 0])
    value_and_grad = jax.jit(jax.value_and_grad(cost))  # one compilation for both
    g = np.asarray(value_and_grad(v)[1])

    def c(x):
        return float(value_and_grad(x)[0])

    h = 1e-4
    for i in (3, 150, 296):
        e = np.zeros(STEPS)
        e[i] = h
        f = [c(v + k * e) for k in (-2, -1, 1, 2)]
        fd = (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h)
        assert g[i] == pytest.approx(fd, rel=1e-6), i
    assert np.all(g[:-1] != 0.0)  # every command but the last (whose effect starts after the record) matters


def _plant_ids():
    from mrd_env.plants import plants

    return [f"mrd_env/{spec.id_name}-v1" for spec in plants().values()]


@pytest.mark.parametrize("env_id", _plant_ids())
def test_force_system_needs_no_pivoting(env_id):
    """Both schemes solve the dampers' force system by elimination without pivoting (mrd_env.jax.scheme): on
    every plant, at every sub-step level, over the dampers' range of internal states, strokes of ±10 cm, stroke
    rates of ±2 m/s and commands, partial pivoting would keep the diagonal at every step (so the elimination is
    the kernel's own), and no entry grows past twice the matrix's largest."""
    from mrd_env.jax import env as je, scheme as sc
    from mrd_env.jax.dampers import jax_damper
    from mrd_env.stepping.scheme import GAMMA

    params = je.make_params(env_id, seeds=[0], scheme="differentiable")
    model, P, nd = jax_damper(params.model), params.P[0], params.nd
    if nd == 1:
        pytest.skip("one damper: the force system is a division")
    rng = np.random.default_rng(0)
    M = 4000
    x, v = rng.uniform(-0.1, 0.1, (M, nd)), rng.uniform(-2.0, 2.0, (M, nd))
    u = rng.uniform(params.v_min, params.v_max, (M, nd))
    S = rng.uniform(-1.0, 1.0, (M, nd, model.ns)) * np.r_[0.1, 1.0][:model.ns]  # the models' own range: projected
    S = jax.vmap(jax.vmap(lambda p, s, x, v, u: jnp.stack(model.project(p, tuple(s), x, v, u)),
                          in_axes=(0, 0, 0, 0, 0)), in_axes=(None, 0, 0, 0, 0))(P, S, x, v, u)

    def system(S, x, v, u, hg, PP):
        *_, alpha, beta = sc._state_blocks(sc._jacobian(model, P, S, x, v, jnp.zeros(nd), u), hg)
        return sc.force_system(alpha, beta, PP[0], PP[1])

    systems = jax.jit(jax.vmap(system, in_axes=(0, 0, 0, 0, None, None)))
    for level in range(params.plant.PP.shape[1]):
        F = np.array(systems(S, x, v, u, params.dt / 2 ** level * GAMMA, params.plant.PP[0, level]))
        A, big = F.copy(), np.abs(F).max(axis=(1, 2))
        for k in range(nd):
            assert np.all(np.argmax(np.abs(A[:, k:, k]), axis=1) == 0), (level, k)  # the diagonal: no row swap
            A[:, k + 1:] -= (A[:, k + 1:, k] / A[:, k, k, None])[:, :, None] * A[:, k, None, :]
            assert np.all(np.abs(A).max(axis=(1, 2)) <= 2.0 * big), (level, k)


@pytest.fixture(scope="module")
def env():
    params = qc.make_params(n_roads=3, episode_seconds=0.05, scheme="differentiable", damper="bouc_wen")
    reset = jax.jit(jax.vmap(qc.reset, in_axes=(0, None)))
    step = jax.jit(jax.vmap(qc.step_autoreset, in_axes=(0, 0, 0, None)))
    return params, reset, step


def test_jit_and_vmap_shapes(env):
    params, reset, step = env
    keys = jax.random.split(jax.random.PRNGKey(0), N)
    obs, state = reset(keys, params)
    assert obs.shape == (N, len(qc.SENSORS)) and obs.dtype == jnp.float64
    assert state.Y.shape == (N, 5)
    obs, state, reward, terminated, truncated, info = step(keys, state, jnp.zeros((N, 1)), params)
    assert obs.shape == (N, len(qc.SENSORS))
    assert reward.shape == terminated.shape == truncated.shape == (N,)
    assert np.all(np.asarray(reward) < 0) and np.all(np.isfinite(np.asarray(obs)))
    assert np.all(np.asarray(state.k) == 1)


def test_seeds_are_reproducible(env):
    params, reset, step = env

    def episode(seed):
        keys = jax.random.split(jax.random.PRNGKey(seed), N)
        obs, state = reset(keys, params)
        out = [np.asarray(obs)]
        for k in range(params.n_steps + 1):  # past the end: the autoreset draws a new road from the key
            action = jnp.full((N, 1), 0.5, jnp.float64)  # a strong dtype, as above: no second compilation
            obs, state, r, *_ = step(jax.random.split(keys[k % N], N), state, action, params)
            out += [np.asarray(obs), np.asarray(r)]
        return out, np.asarray(state.record)

    a, roads_a = episode(1)
    b, roads_b = episode(1)
    assert all(np.array_equal(x, y) for x, y in zip(a, b)) and np.array_equal(roads_a, roads_b)
    c, _ = episode(2)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


@pytest.mark.parametrize("option,value,match", [
    ("scheme", "rk4", "scheme"), ("substeps", 3, "substeps"), ("newton_iterations", 0, "newton_iterations"),
    ("damper", "no_such_model", "damper"), ("action_mode", "force", "action_mode"), ("stroke_limit", -1.0, "stroke_limit"),
    ("roads", [np.zeros((5, 2))], r"roads\[0\]"), ("n_roads", 0, "n_roads"), ("control_dt", 0.0105, "control_dt"),
])
def test_bad_input_names_the_parameter(option, value, match):
    with pytest.raises(ValueError, match=match):
        qc.make_params(**{option: value}, episode_seconds=0.1)
