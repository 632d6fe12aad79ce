"""The yardstick's episode data (mrd_env.optimal.problem) against the environment it is taken from."""
import numpy as np
import pytest

from mrd_env.optimal import episode_problem

CAR = dict(road="iso8608", road_params={"road_class": "C", "speed": 20.0}, episode_seconds=1.0)
BUILDING = dict(damper_floors=(2,), ground_motion="el_centro", ground_motion_params={"time_scale": 0.2},
                episode_seconds=1.0)
CASES = [("mrd_env/QuarterCarPhysical-v0", CAR), ("mrd_env/ShearBuildingPhysical-v0", BUILDING)]


@pytest.mark.parametrize("env_id, options", CASES)
def test_quadratic_terms_reproduce_the_environment_return(env_id, options):
    """The reward's quadratic terms (Wk filter included) on the re-simulated states and forces give the return the
    environment paid, to rounding: the cost every solver optimises is the environment's own."""
    p = episode_problem(env_id, seed=1_000_000, control_dt=0.01, **options)
    U = np.random.default_rng(0).uniform(p.v_min, p.v_max, (p.n_steps, p.nd))
    tr = p.replay(U, states=True)
    assert not tr.terminated and np.all(np.isfinite(tr.X))
    assert p.linear_return(tr.X, tr.F) == pytest.approx(tr.ret, rel=1e-10)
    # the same commands at the problem's control step: the same physics, the return to integration tolerance
    assert p.replay(U).ret == pytest.approx(tr.ret, rel=1e-4)


def test_disturbance_and_state_match_the_environment():
    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1_000_003, control_dt=0.01, **CAR)
    assert p.n_rows == p.n_steps * p.n_sub + 1 == 1001
    assert np.all(p.W[:, -1] == 1.0)                       # the preload channel
    np.testing.assert_array_equal(p.x0, [p.W[0, 0], p.W[0, 0], p.W[0, 1], p.W[0, 1]])  # at rest on the road
    # the dynamics: A x + B_F F + B_w w = 0 at rest with the static force
    F0 = np.array([p.F_static])
    assert np.allclose(p.A @ np.zeros(4) + p.BF @ F0 + p.Bw @ np.array([0.0, 0.0, 1.0]), 0.0, atol=1e-9)


def test_commands_of_a_law_and_bad_commands():
    from controllers import make_controller

    p = episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1_000_000, control_dt=0.01, **CAR)
    on = p.commands_of(lambda e: make_controller("passive_on", e))
    assert on.shape == (p.n_steps, 1) and np.all(on == p.v_max)
    # a law at a coarser rate: its commands are held over the problem's steps
    sky = p.commands_of(lambda e: make_controller("skyhook_on_off", e), control_dt=0.05)
    assert np.all(sky.reshape(-1, 5) == sky.reshape(-1, 5)[:, :1])
    with pytest.raises(ValueError, match="multiple"):
        p.commands_of(lambda e: make_controller("passive_on", e), control_dt=0.015)
    with pytest.raises(ValueError, match="shape"):
        p.replay(np.zeros((3, 1)))
    with pytest.raises(ValueError, match=r"lie in"):
        p.replay(np.full((p.n_steps, 1), p.v_max + 1.0))
    with pytest.raises(ValueError, match="finite"):
        p.replay(np.full((p.n_steps, 1), np.nan))
    with pytest.raises(ValueError, match="force"):
        episode_problem("mrd_env/QuarterCarPhysical-v0", seed=0, action_mode="force")
    with pytest.raises(ValueError, match="seed"):
        episode_problem("mrd_env/QuarterCarPhysical-v0", seed=1.5)
