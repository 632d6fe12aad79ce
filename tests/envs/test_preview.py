"""The quarter car's road preview sensor (``preview=...``, sensor ``road_preview``): what it reads, that the
plant ignores it, scalar = vector, and bad options."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.disturbances import Record, bump
from mrd_env.plants.quarter_car.env import DEFAULT_SENSORS

QC = "mrd_env/QuarterCarPhysical-v0"
WITH_PREVIEW = (*DEFAULT_SENSORS, "road_preview")


def _preview_columns(env) -> slice:
    return {name: sl for name, sl, _ in env.unwrapped.sensor_layout}["road_preview"]


@pytest.mark.parametrize("control_dt", [1e-3, 0.01])
def test_preview_reads_the_road_tau_ahead_and_holds_the_last_height(control_dt):
    # a bump 0.4 s long: the episode runs past the record's end, so the hold is exercised too
    rec = bump(0.05, 1.0, 10.0, t_start=0.1, duration=0.4, dt=1e-3)
    taus = (0.002, 0.05, 0.2)
    env = gym.make(QC, road=rec, preview=taus, sensors=WITH_PREVIEW, control_dt=control_dt)
    assert env.unwrapped.preview_times == taus
    assert env.unwrapped.observation_space.shape == (8 + 3,)
    z = rec.channel("z_r")
    n_sub = int(round(control_dt / 1e-3))
    obs, _ = env.reset(seed=0)
    cols = _preview_columns(env)
    rows = [obs[cols]]
    while True:
        obs, _, term, trunc, _ = env.step([1.0])
        rows.append(obs[cols])
        if term or trunc:
            break
    got = np.array(rows)
    k = np.arange(got.shape[0])[:, None] * n_sub + np.round(np.array(taus) / 1e-3).astype(int)[None, :]
    expected = z[np.minimum(k, z.size - 1)].astype(np.float32)
    np.testing.assert_array_equal(got, expected)
    assert np.any(k >= z.size)  # some readings were beyond the record's end
    # the signal history agrees: the road now, shifted by τ
    road = env.unwrapped.signal("road")[:, 0]
    preview = env.unwrapped.signal("road_preview")
    np.testing.assert_array_equal(preview[:-50, 1], road[50:])


def test_preview_does_not_change_the_dynamics_bit_for_bit():
    kw = dict(episode_seconds=0.3, sensor_noise={"travel": 1e-3})
    plain = gym.make(QC, **kw).unwrapped
    seeing = gym.make(QC, preview=(0.05, 0.1), sensors=WITH_PREVIEW, **kw).unwrapped
    o0, _ = plain.reset(seed=3)
    o1, _ = seeing.reset(seed=3)
    np.testing.assert_array_equal(o0, o1[:8])
    actions = np.random.default_rng(0).uniform(0.0, 2.25, (400, 1))
    for a in actions:
        s0, s1 = plain.step(a), seeing.step(a)
        np.testing.assert_array_equal(s0[0], s1[0][:8])
        assert s0[1:4] == s1[1:4]
        if s0[2] or s0[3]:
            break
    assert s0[4]["episode_metrics"] == s1[4]["episode_metrics"]
    np.testing.assert_array_equal(plain.signal("_z"), seeing.signal("_z"))
    np.testing.assert_array_equal(plain.signal("damper_force"), seeing.signal("damper_force"))
    # the plant's input map: the preview channels are inputs the plant ignores
    lp = seeing.linear_plant
    assert lp.input_names == ("z_r", "zdot_r", "z_r(t+0.05s)", "z_r(t+0.1s)")
    np.testing.assert_array_equal(lp.E[:, 2:], 0.0)
    np.testing.assert_array_equal(lp.E[:, :2], plain.linear_plant.E)
    m = seeing.signal_matrices("road_preview")
    np.testing.assert_array_equal(m["D_w"], [[0, 0, 1, 0], [0, 0, 0, 1]])


def test_preview_with_noise_delay_and_history_vector_equals_scalar():
    kw = dict(episode_seconds=0.1, control_dt=0.005, preview=(0.01, 0.03), sensors=("travel", "road_preview"),
              sensor_noise={"road_preview": 1e-3}, sensor_delay=1, history=2)
    N = 3
    venv = gym.make_vec(QC, num_envs=N, vectorization_mode="vector_entry_point", **kw)
    assert venv.unwrapped.preview_times == (0.01, 0.03)
    assert venv.single_observation_space.shape == (2 * 3,)
    acts = np.random.default_rng(1).uniform(0.0, 2.25, (20, N, 1))
    vobs = [venv.reset(seed=5)[0]]
    vobs += [venv.step(a)[0] for a in acts]
    for i in range(N):
        env = gym.make(QC, **kw)
        sobs = [env.reset(seed=5 + i)[0]]
        sobs += [env.step(a[i])[0] for a in acts]
        np.testing.assert_array_equal(np.array(vobs)[:, i], np.array(sobs))


def test_without_preview_nothing_changes():
    env = gym.make(QC, episode_seconds=0.1).unwrapped
    assert env.preview_times == ()
    assert env.linear_plant.input_names == ("z_r", "zdot_r")
    assert "road_preview" not in env.assembly.signals


@pytest.mark.parametrize("kwargs, match", [
    (dict(sensors=WITH_PREVIEW), "needs the preview option"),
    (dict(preview=-0.1), "preview"),
    (dict(preview=0.0), "preview"),
    (dict(preview=float("nan")), "preview"),
    (dict(preview=float("inf")), "preview"),
    (dict(preview="0.1"), "preview"),
    (dict(preview=True), "preview"),
    (dict(preview={"t": 0.1}), "preview"),
    (dict(preview=[]), "preview"),
    (dict(preview=(0.1, None)), "preview"),
    (dict(preview=(0.1, 1j)), "preview"),
    (dict(preview=0.0005), r"preview times must be multiples of dt"),
    (dict(preview=0.0105), r"preview times must be multiples of dt"),
    (dict(preview=(0.1, 0.1)), "preview times must be increasing"),
    (dict(preview=(0.1, 0.05)), "preview times must be increasing"),
    (dict(preview=11.0), "preview"),
])
def test_bad_preview_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(QC, episode_seconds=0.1, **kwargs)


def test_preview_of_a_record_ending_before_the_episode_window():
    """A record exactly as long as the episode: the last preview samples hold the last height."""
    z = np.linspace(0.0, 0.01, 101)
    rec = Record(1e-3, np.column_stack([z, np.full(101, 0.1)]), ("z_r", "zdot_r"), ("m", "m/s"), "ramp")
    env = gym.make(QC, road=rec, preview=0.05, sensors=("road", "road_preview"))
    obs, _ = env.reset(seed=0)
    last = None
    while True:
        obs, _, term, trunc, _ = env.step([0.0])
        if term or trunc:
            last = obs
            break
    assert last[1] == np.float32(z[-1]) and last[0] == np.float32(z[-1])
