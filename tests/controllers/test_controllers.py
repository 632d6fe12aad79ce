"""Controllers: each law's command on hand-made observations (sign conventions), the designs against
python-control/scipy, clear errors for missing sensors and roles, and batches (one law, many environments)."""

import control
import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from controllers import (CONTROLLERS, ClippedOptimal, Groundhook, Hybrid, KalmanEstimator, LinearDesign, Lyapunov,
                         MaximumEnergyDissipation, ModulatedHomogeneousFriction, PassiveOff, PassiveOn,
                         SkyhookContinuous, SkyhookOnOff, make_controller)
from mrd_env.plants import QuarterCarEnv, ShearBuildingEnv

QC_SENSORS = ("sprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel", "damper_force")
B_SENSORS = ("abs_acc", "damper_force", "ground_acc", "damper_stroke", "damper_velocity", "floor_vel")
SIZES = {"abs_acc": 3, "floor_vel": 3, "drift": 3}


def make_env(sensors, building=False, normalized=False):
    """A real environment (its plant, damper and declarations) with the given sensors; no episode is run."""
    mode = "normalized" if normalized else "physical"
    env = (ShearBuildingEnv if building else QuarterCarEnv)(sensors=sensors, action_mode=mode)
    env.n_obs = env.observation_space.shape[0]
    return env


def obs(env, **values):
    o = np.zeros(env.n_obs)
    layout = {n: sl for n, sl, _ in env.sensor_layout}
    for k, v in values.items():
        o[layout[k]] = v
    return o


def u_of(ctrl, o):
    """The physical command of one observation (the environments here use physical actions)."""
    return ctrl.predict(o)[0][0]


def test_passive_laws_and_action_modes():
    env = make_env(QC_SENSORS)
    assert PassiveOff(env).predict(obs(env))[0] == pytest.approx([0.0])
    assert PassiveOn(env).predict(obs(env))[0] == pytest.approx([2.0])
    envn = make_env(QC_SENSORS, normalized=True)
    assert PassiveOff(envn).predict(obs(envn))[0] == pytest.approx([-1.0])
    assert PassiveOn(envn).predict(obs(envn))[0] == pytest.approx([1.0])
    a, state = PassiveOn(env).predict(obs(env))
    assert a.dtype == np.float32 and a.shape == (1,) and state is None


@pytest.mark.parametrize("zs,vrel,on", [(0.3, 0.1, True), (0.3, -0.1, False), (-0.3, -0.1, True), (-0.3, 0.1, False)])
def test_skyhook_sign_convention(zs, vrel, on):
    """Skyhook: damper force −F on the body; F resists extension v_rel. Full command iff ż_s·v_rel ≥ 0."""
    env = make_env(QC_SENSORS)
    u = SkyhookOnOff(env).predict(obs(env, sprung_vel=zs, travel_rate=vrel))[0][0]
    assert u == pytest.approx(2.0 if on else 0.0)
    uc = u_of(SkyhookContinuous(env, c_sky=2500.0, force_per_command=1000.0), obs(env, sprung_vel=zs, travel_rate=vrel))
    assert uc == pytest.approx(min(2.0, 2500 * abs(zs) / 1000.0) if on else 0.0)


@pytest.mark.parametrize("zu,vrel,on", [(0.3, -0.1, True), (0.3, 0.1, False), (-0.3, 0.1, True)])
def test_groundhook_sign_convention(zu, vrel, on):
    env = make_env(QC_SENSORS)
    u = u_of(Groundhook(env), obs(env, unsprung_vel=zu, travel_rate=vrel))
    assert u == pytest.approx(2.0 if on else 0.0)


def test_hybrid_reduces_to_skyhook_and_groundhook():
    """α = 1 is continuous skyhook with c_sky = G; α = 0 continuous groundhook G|ż_u|/κ where −ż_u·v_rel ≥ 0;
    between, each term is gated on its own condition (Goncalves & Ahmadian 2003)."""
    env = make_env(QC_SENSORS)
    kappa = SkyhookContinuous(env).kappa
    # (ż_s, ż_u, v_rel): |F| (N) of the hybrid at α = 0.6, G = 800 N·s/m, worked out by hand
    cases = {(0.2, -0.5, 0.1): 256.0,  # both terms on: 800·(0.6·0.2 + 0.4·0.5)
             (-0.2, 0.4, 0.3): 0.0,  # both off: ż_s·v < 0 and −ż_u·v < 0
             (0.1, 0.1, -0.2): 32.0,  # groundhook alone: 800·0.4·0.1
             (0.05, -0.02, 0.07): 30.4,  # both on: 800·(0.6·0.05 + 0.4·0.02)
             (0.3, 0.2, 0.1): 144.0}  # skyhook alone: 800·0.6·0.3
    for (zs, zu, v), F in cases.items():
        o = obs(env, sprung_vel=zs, unsprung_vel=zu, travel_rate=v)
        assert u_of(Hybrid(env, alpha=1.0, gain=800.0), o) == pytest.approx(u_of(SkyhookContinuous(env, 800.0), o))
        ground = min(800.0 * abs(zu) / kappa, 2.0) if -zu * v >= 0 else 0.0
        assert u_of(Hybrid(env, alpha=0.0, gain=800.0), o) == pytest.approx(ground)
        assert u_of(Hybrid(env, alpha=0.6, gain=800.0), o) == pytest.approx(min(F / kappa, 2.0))
    assert u_of(Hybrid(env, alpha=0.6, gain=800.0, force_per_command=400.0),
                obs(env, sprung_vel=0.2, unsprung_vel=-0.5, travel_rate=0.1)) == pytest.approx(256.0 / 400.0)


@pytest.mark.parametrize("law", [SkyhookContinuous, Hybrid])
@pytest.mark.parametrize("kappa", [0.0, -500.0])
def test_force_tracking_laws_refuse_a_force_per_command_that_is_not_positive(law, kappa):
    with pytest.raises(ValueError, match="force_per_command must be > 0"):
        law(make_env(QC_SENSORS), force_per_command=kappa)


def test_hybrid_is_not_passive_on_on_a_road():
    """On a class-C road the hybrid at α = 0.5 leaves the maximum command most of the time (the one-switch form
    of the reference page was at u_max on every step at α = 0.5, and on 84 % of them at α = 0.6)."""
    import gymnasium as gym

    env = gym.make("mrd_env/QuarterCarPhysical-v0")
    ctrl = Hybrid(env, alpha=0.5)
    o, _ = env.reset(seed=1)
    u = []
    for _ in range(2000):
        a, _ = ctrl.predict(o)
        u.append(float(a[0]))
        o, *_ = env.step(a)
    u = np.array(u)
    assert np.mean(u >= env.action_space.high[0]) < 0.5 and np.ptp(u) > 0.1  # modulates, mostly below u_max


def test_energy_and_friction_laws():
    env = make_env(B_SENSORS, building=True)
    med = MaximumEnergyDissipation(env)
    f0 = env.F_static  # the laws act on the force beyond the static preload
    assert u_of(med, obs(env, damper_force=f0 + 500.0, damper_velocity=0.1)) == 2.25  # dissipating
    assert u_of(med, obs(env, damper_force=f0 + 500.0, damper_velocity=-0.1)) == 0.0
    mhf = ModulatedHomogeneousFriction(env, gain=1e5)
    u_of(mhf, obs(env, damper_stroke=0.004, damper_velocity=0.01))
    # velocity reverses at 5 mm: the extremum is 5 mm, so g|P| = 500 N
    assert u_of(mhf, obs(env, damper_stroke=0.005, damper_velocity=-0.01, damper_force=f0 + 400.0)) == 2.25
    assert u_of(mhf, obs(env, damper_stroke=0.0045, damper_velocity=-0.01, damper_force=f0 + 600.0)) == 0.0


def test_missing_sensors_raise_clear_error():
    env = make_env(("sprung_acc", "travel", "damper_force"))
    with pytest.raises(ValueError, match=r"SkyhookOnOff needs the sensor\(s\) \['sprung_vel', 'travel_rate'\]"):
        SkyhookOnOff(env)
    with pytest.raises(ValueError, match="unsprung_vel"):
        Groundhook(env)
    with pytest.raises(ValueError, match="damper_force"):
        ClippedOptimal(make_env(("sprung_acc", "travel")))
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("nope", env)
    with pytest.raises(ValueError, match=r"role\(s\) \['wheel_velocity'\]"):  # a building has no wheel
        Groundhook(make_env(B_SENSORS, building=True))


def test_clipped_optimal_lqr_gain_equals_python_control_and_riccati():
    env = make_env(B_SENSORS, building=True)
    co = ClippedOptimal(env)
    d = LinearDesign(env)
    Cz, Dz = d.regulated(co.weights)
    Q, R, N = Cz.T @ Cz, Dz.T @ Dz + np.eye(1) / 3000.0 ** 2, Cz.T @ Dz
    K_ref, _, _ = control.lqr(d.A, d.Bf, Q, R, N)
    assert np.allclose(co.K, K_ref, rtol=1e-9)
    # and python-control agrees with the algebraic Riccati equation solved by scipy
    P = solve_continuous_are(d.A, d.Bf, Q, R, s=N)
    assert np.allclose(co.K, np.linalg.solve(R, d.Bf.T @ P + N.T), rtol=1e-6)
    assert np.all(np.real(np.linalg.eigvals(d.A - d.Bf @ co.K)) < 0)


def test_clipped_on_off_law():
    env = make_env(B_SENSORS, building=True)
    co = ClippedOptimal(env)
    co.desired_force = lambda x: np.full((x.shape[0], 1), 800.0)
    f0 = env.F_static
    assert u_of(co, obs(env, damper_force=f0 + 500.0)) == 2.25      # (f_c − f) f > 0: more force wanted
    assert u_of(co, obs(env, damper_force=f0 + 900.0)) == 0.0       # |f| already above f_c
    assert u_of(co, obs(env, damper_force=f0 - 500.0)) == 0.0      # wrong direction


def test_kalman_estimate_converges_on_the_linear_plant():
    """Simulate the discretised linear building with process and measurement noise from a wrong initial
    state: the filter's error settles far below the state's spread and far below the error of the same
    model run open loop (no measurement correction)."""
    env = make_env(B_SENSORS, building=True)
    d = LinearDesign(env)
    C, D = d.output("abs_acc")
    kf = KalmanEstimator(d, C, D, 1e-3, process_noise=1.0, measurement_noise=np.full(3, 0.05 ** 2))
    rng = np.random.default_rng(0)
    x = rng.normal(0, 1e-3, d.n)  # the filter starts at 0, the plant elsewhere
    x_open = np.zeros(d.n)
    errs, errs_open, xs = [], [], []
    for k in range(4000):
        f = np.array([200.0 * np.sin(2 * np.pi * 3 * k * 1e-3)])
        w = rng.normal(0, 1.0, 1)
        y = C @ x + D @ f + rng.normal(0, 0.05, 3)
        xh = kf.update(y[None], f[None])[0]
        errs.append(np.linalg.norm(xh - x))
        errs_open.append(np.linalg.norm(x_open - x))
        xs.append(np.linalg.norm(x))
        x_open = kf.Phi @ x_open + kf.Gf @ f
        x = kf.Phi @ x + kf.Gf @ f + kf.Gw @ w
    assert np.mean(errs[-1000:]) < 0.1 * np.mean(xs[-1000:])
    assert np.mean(errs[-1000:]) < 0.1 * np.mean(errs_open[-1000:])
    assert np.all(np.abs(kf.poles) < 1)


def test_lyapunov_law_sign():
    env = make_env(B_SENSORS, building=True)
    ly = Lyapunov(env)
    d = ly.design
    x = np.zeros(d.n)
    x[3] = 0.1  # floor 1 moving up (relative): V decreases if the damper pushes against it
    ly.estimate = lambda o: (x[None], np.array([[300.0]]))
    # −xᵀ P B_f f = −(P B_f)[3]·0.1·300; B_f = −M⁻¹Sᵀ pushes floor 1 down for f > 0 → V decreases → on
    assert u_of(ly, obs(env)) == 2.25


def test_registry_lists_every_law():
    assert {"passive_off", "passive_on", "skyhook_on_off", "skyhook_continuous", "groundhook", "hybrid",
            "clipped_optimal", "lyapunov", "max_energy_dissipation", "modulated_friction"} <= set(CONTROLLERS)


def test_random_baseline_is_seeded_and_in_range():
    env = make_env(QC_SENSORS)
    obs = np.zeros((5, env.n_obs))
    a = [make_controller("random", env, seed=s).predict(obs)[0] for s in (1, 1, 2)]
    np.testing.assert_array_equal(a[0], a[1])
    assert not np.array_equal(a[0], a[2])
    assert np.all(a[0] >= env.command_spec.v_min) and np.all(a[0] <= env.command_spec.v_max)


# (the random baseline draws every row from one generator: a batch is not its rows one by one)
@pytest.mark.parametrize("name", sorted(set(CONTROLLERS) - {"random"}))
def test_a_batch_gives_each_row_what_it_alone_would_get(name):
    """predict on a batch (N, n_obs) equals predict row by row with separate controllers, memory included;
    episode_start clears the memory of the rows that start again."""
    building = name in ("lyapunov", "max_energy_dissipation", "modulated_friction", "decentralized_bang_bang")
    sensors = B_SENSORS if building else QC_SENSORS + ("unsprung_vel",) if "unsprung_vel" not in QC_SENSORS \
        else QC_SENSORS
    env = make_env(sensors, building=building)
    rng = np.random.default_rng(0)
    batch = make_controller(name, env)
    singles = [make_controller(name, env) for _ in range(3)]
    for k in range(20):
        O = rng.normal(0, 1, (3, env.n_obs)) * np.where(np.arange(env.n_obs) % 2, 1.0, 100.0)
        start = np.array([k == 10, False, False])
        a, _ = batch.predict(O, episode_start=start)
        for i, c in enumerate(singles):
            if start[i]:
                c.reset()
            np.testing.assert_array_equal(a[i], c.predict(O[i])[0])


def test_skyhook_refuses_the_building_whose_floor_velocities_are_relative():
    """Skyhook needs an absolute body velocity; the building's floor velocities are relative to the ground, so it
    declares no body_velocity role and skyhook and hybrid refuse it by name (a relative one is not skyhook)."""
    env = ShearBuildingEnv(sensors=("damper_force", "damper_velocity", "upper_floor_vel"))
    assert "body_velocity" not in env.roles
    for law in ("skyhook_on_off", "skyhook_continuous", "hybrid"):
        with pytest.raises(ValueError, match="body_velocity"):
            make_controller(law, env)
