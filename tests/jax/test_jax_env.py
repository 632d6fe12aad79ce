"""Every plant's JAX twin (:mod:`mrd_env.jax.env`) against the native environment of the same id and options, on
the same record and actions: rewards, observations, flags and constraint costs; the sensors' delay, history and
noise; the gradient of an episode's cost against central finite differences."""
import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import mrd_env  # noqa: E402, F401
from mrd_env.jax import env as je  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
SEED = 7


def run_both(env_id, options, n_steps, seed=SEED, key=None, actions=None):
    """(native, twin) lists of (obs, reward, terminated, truncated, cost, cost_terms) under the same random
    actions (float32 values, as the native Box holds them), stopping at the native episode's end."""
    env = gym.make(env_id, **options)
    params = je.make_params(env_id, seeds=[seed], **options)
    obs_n, _ = env.reset(seed=seed)
    obs_j, state = je.reset(key, params, record=0)
    rng = np.random.default_rng(1)
    step = jax.jit(je.step)
    native, twin = [(obs_n, 0.0, False, False, 0.0, None)], [(np.asarray(obs_j), 0.0, False, False, 0.0, None)]
    for k in range(n_steps):
        a = (rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32) if actions is None
             else np.asarray(actions[k], np.float32))
        o, r, te, tr, info = env.step(a)
        native.append((o, r, te, tr, info["cost"], np.array(list(info["cost_terms"].values()))))
        kk = None if key is None else jax.random.fold_in(key, k)
        o, state, r, te, tr, info = step(kk, state, jnp.asarray(a, jnp.float64), params)
        twin.append((np.asarray(o), float(r), bool(te), bool(tr), float(info["cost"]), np.asarray(info["cost_terms"])))
        if native[-1][2] or native[-1][3]:
            break
    env.close()
    return native, twin, params


def assert_same(native, twin, reward_rtol=1e-10):
    assert len(native) == len(twin)
    scale = max(abs(n[1]) for n in native) or 1.0
    for k, (n, t) in enumerate(zip(native, twin)):
        np.testing.assert_allclose(t[0].astype(np.float32), n[0], rtol=2e-6, atol=1e-9, err_msg=f"obs at step {k}")
        assert abs(t[1] - n[1]) <= reward_rtol * scale, (k, t[1], n[1])
        assert (t[2], t[3]) == (n[2], n[3]), k
        assert t[4] == pytest.approx(n[4], abs=1e-12), k
        if n[5] is not None:
            np.testing.assert_allclose(t[5], n[5], atol=1e-12)


@pytest.mark.parametrize("env_id,options", [
    ("mrd_env/ShearBuilding-v1", {"episode_seconds": 1.0, "drift_limit": 0.002}),
    ("mrd_env/Isolator-v1", {"episode_seconds": 1.0, "soft_stroke_limit": 0.0004}),
    ("mrd_env/HalfCar-v1", {"episode_seconds": 0.5, "soft_stroke_limit": 0.003}),
    ("mrd_env/QuarterCar-v1", {"episode_seconds": 0.5, "soft_stroke_limit": 0.002, "sensors": ["travel", "damper_force"],
                               "sensor_delay": 2, "history": 3}),
])
def test_twin_is_the_native_environment(env_id, options):
    """The exact scheme reproduces the native environment to rounding: rewards to 1e-10 of their scale,
    observations to float32's rounding, the same flags and the same constraint costs (the soft limits are set so
    that costs occur), through the sensors' delay and history."""
    native, twin, params = run_both(env_id, options, 100)
    assert_same(native, twin)
    assert native[-1][3] or len(native) == 101
    if params.cost_names:
        assert sum(n[4] for n in native) > 0.0  # the case tests a non-zero cost


def test_stroke_limit_ends_the_episode_as_native():
    """A stroke limit the car hits: terminated at the same step, with the same penalty."""
    native, twin, _ = run_both("mrd_env/QuarterCar-v1", {"episode_seconds": 2.0, "stroke_limit": 0.004,
                                                          "road_params": {"road_class": "E"}}, 200)
    assert native[-1][2] and len(native) < 201
    assert_same(native, twin)


def test_sensor_noise_has_its_standard_deviation():
    """Noise on a sensor adds a zero-mean error of the given standard deviation (from the step's key); the
    physics it observes is the noiseless twin's."""
    opts = {"episode_seconds": 2.0, "sensors": ["travel", "damper_force"], "sensor_noise": {"damper_force": 5.0}}
    n_steps = 200
    a = np.full((n_steps, 1), 0.3)
    _, noisy, _ = run_both("mrd_env/QuarterCar-v1", opts, n_steps, key=jax.random.PRNGKey(3), actions=a)
    _, clean, _ = run_both("mrd_env/QuarterCar-v1", {**opts, "sensor_noise": None}, n_steps, actions=a)
    err = np.array([t[0] - c[0] for t, c in zip(noisy, clean)])
    assert np.all(err[:, 0] == 0.0)
    assert np.std(err[:, 1]) == pytest.approx(5.0, rel=0.15) and abs(np.mean(err[:, 1])) < 1.5
    assert [t[1] for t in noisy] == [c[1] for c in clean]  # rewards see the true signals


def test_gradient_of_a_building_episode_matches_finite_differences():
    """jax.grad of the differentiable scheme's episode return with respect to the commands, against central
    finite differences of the same function: within 1e-6 of each component, or of the largest for a component a
    thousand times smaller (whose difference quotient is rounding)."""
    params = je.make_params("mrd_env/ShearBuilding-v1", seeds=[0], scheme="differentiable", episode_seconds=0.3,
                            ground_motion="kanai_tajimi")
    _, s0 = je.reset(None, params, record=0)
    f = jax.jit(lambda a: je.episode_return(a, (params, s0)))
    a = jnp.asarray(np.random.default_rng(0).uniform(-0.5, 0.5, (params.n_steps, 1)))
    g = np.asarray(jax.grad(f)(a))
    h = 1e-4
    for i in (0, 7, 19, 25):
        e = jnp.zeros_like(a).at[i, 0].set(h)
        fd = (float(f(a + e)) - float(f(a - e))) / (2 * h)
        assert g[i, 0] == pytest.approx(fd, rel=1e-6, abs=1e-6 * np.max(np.abs(g)))
    assert np.max(np.abs(g)) > 0


@pytest.mark.parametrize("call,match", [
    (lambda: je.make_params("CartPole-v1"), "env_id"),
    (lambda: je.make_params("mrd_env/NoSuchPlant-v1"), "env_id"),
    (lambda: je.make_params("mrd_env/QuarterCar-v1", action_mode="force"), "action_mode"),
    (lambda: je.make_params("mrd_env/QuarterCar-v1", reward=lambda period: 0.0), "reward"),
    (lambda: je.make_params("mrd_env/QuarterCar-v1", seeds=[]), "seeds"),
    (lambda: je.make_params("mrd_env/QuarterCar-v1", scheme="rk4"), "scheme"),
    (lambda: je.make_params("mrd_env/ShearBuilding-v1", records=[np.zeros((100, 1))]), r"records\[0\]"),
    (lambda: je.make_params("mrd_env/QuarterCar-v1", no_such_option=1), "no_such_option"),
])
def test_bad_input_names_the_parameter(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("plant", ["quarter_car", "shear_building"])
def test_randomised_bank_is_the_native_robustness_draws(plant):
    """``randomise=`` the robustness twin's bands (damper, command lag and delay, masses and stiffnesses, sensor
    noise and delay): each episode is the native environment built with its draw (rewards to 1e-10 — the noise does
    not enter them), the plants differ between episodes, and one compiled step runs them all."""
    from mrd_env.plants import plant as plant_spec
    from mrd_env.suites import draw_episode, nominal_values

    spec = plant_spec(plant)
    bands = next(d.randomise for d in spec.profile.suites if d.randomise)  # the plant's robustness twin's
    env_id, options = spec.rl_id, {"episode_seconds": 0.3}
    seeds = [11, 12]
    params = je.make_params(env_id, seeds=seeds, randomise=bands, **options)
    assert params.drawn and params.plant.Ainv.shape[0] == 2 and params.noisy
    assert not np.allclose(np.asarray(params.plant.Ainv[0]), np.asarray(params.plant.Ainv[1]))
    nominal = nominal_values(env_id, options)
    step = jax.jit(lambda *args: je.step(*args))  # its own cache (jit's cache is per function)
    for b, s in enumerate(seeds):
        env = gym.make(env_id, **options, **draw_episode(bands, nominal, 0, s))
        env.reset(seed=s)
        _, state = je.reset(jax.random.PRNGKey(0), params, record=b)
        rng = np.random.default_rng(b)
        for k in range(params.steps[b]):
            a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            _, r, te, tr, _ = env.step(a)
            _, state, r2, te2, tr2, _ = step(jax.random.PRNGKey(k), state, jnp.asarray(a, jnp.float64), params)
            assert float(r2) == pytest.approx(r, rel=1e-10, abs=1e-13) and (bool(te2), bool(tr2)) == (te, tr)
        env.close()
    assert step._cache_size() == 1
