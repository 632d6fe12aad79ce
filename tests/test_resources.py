"""Bounded resources (issue 36, item 5): every option combination is checked against a memory estimate before
work starts; a refusal names the option(s), the estimate and the limit, in well under a second, and changes
nothing. A record is cropped to the episode before it is resampled, with the episode's numbers unchanged."""
from __future__ import annotations

import time
import tracemalloc
import warnings

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env import resources
from mrd_env.disturbances import Record, el_centro, road_from_csv, scale_record
from mrd_env.envs.disturbance import Disturbance
from mrd_env.plants.quarter_car.env import QuarterCarEnv, QuarterCarVectorEnv
from mrd_env.plants.shear_building.env import ShearBuildingEnv
from mrd_env.rig import random_test, sinusoidal_test

SB, QC, HC = "mrd_env/ShearBuilding-v1", "mrd_env/QuarterCar-v1", "mrd_env/HalfCar-v1"


@pytest.fixture(autouse=True)
def default_limit(monkeypatch):
    """The default limit (4 GiB, or half the machine's memory) whatever the shell says."""
    monkeypatch.delenv(resources.ENV_VAR, raising=False)


def _make(env_id, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id, **options)


def _refused(make, *names) -> tuple[str, float]:
    t0 = time.perf_counter()
    with pytest.raises(ValueError) as info:
        make()
    elapsed = time.perf_counter() - t0
    msg = str(info.value)
    for name in names:
        assert name in msg, msg
    assert "needs about" in msg and "the limit is" in msg and resources.ENV_VAR in msg, msg
    return msg, elapsed


# --- the two cases of the issue ----------------------------------------------------------------------------------
def test_a_long_quarter_car_episode_is_refused_in_under_a_second():
    _make(QC, episode_seconds=0.1)  # the kernels loaded: the refusal itself is timed
    msg, elapsed = _refused(lambda: _make(QC, episode_seconds=1e5), "episode_seconds=100000", "100 000 001 samples")
    assert elapsed < 1.0, elapsed
    assert "for the road" in msg


def test_the_building_record_is_cropped_to_a_short_episode_before_it_is_resampled():
    """time_scale=1000 and episode_seconds=0.05 took 108 s and 8.6 GB to reset: now a few samples."""
    _make(SB, episode_seconds=0.1).reset(seed=0)
    t0 = time.perf_counter()
    env = _make(SB, episode_seconds=0.05, ground_motion_params={"time_scale": 1000})
    env.reset(seed=0)
    assert time.perf_counter() - t0 < 1.0
    assert env.unwrapped.record.n_samples < 60
    assert env.spec.max_episode_steps == 5


def test_the_stretched_record_without_episode_seconds_is_refused_in_under_a_second():
    _make(SB, episode_seconds=0.1)
    msg, elapsed = _refused(lambda: _make(SB, ground_motion_params={"time_scale": 1000}), "time_scale=1000")
    assert elapsed < 1.0, elapsed
    assert "53710 s" in msg  # the replayed record's length, the episode's without episode_seconds


def test_the_crop_keeps_the_samples_bit_for_bit():
    raw = el_centro("NS", dt=None)
    for ts, es in ((1000.0, 0.05), (0.2, 3.0), (3.0, 7.3), (1.0, 1e3)):
        full = scale_record(raw, ts, 1.3, 1e-3)
        cut = scale_record(raw, ts, 1.3, 1e-3, duration=es)
        rows = min(full.n_samples, int(round(es / 1e-3)) + 1)
        assert cut.n_samples >= rows and cut.n_samples <= full.n_samples
        np.testing.assert_array_equal(cut.data, full.data[:cut.n_samples])
        assert cut.name == full.name


def test_a_csv_road_is_cropped_to_the_episode_bit_for_bit(tmp_path):
    x = np.linspace(0.0, 200.0, 4001)
    z = 0.01 * np.sin(0.3 * x) + 0.002 * np.cos(2.1 * x)
    path = tmp_path / "road.csv"
    path.write_text("x [m],z [m]\n" + "\n".join(f"{a!r},{b!r}" for a, b in zip(x.tolist(), z.tolist())))
    full = road_from_csv(path, height_column="z", distance_column="x", speed=10.0)
    cut = road_from_csv(path, height_column="z", distance_column="x", speed=10.0, duration=2.0)
    assert cut.n_samples == 2003
    np.testing.assert_array_equal(cut.data[:-1], full.data[:cut.n_samples - 1])  # the one-sided end differs


# --- every option that scales memory ----------------------------------------------------------------------------
@pytest.mark.parametrize("env_id, options, names", [
    (HC, dict(episode_seconds=1e5), ("episode_seconds=100000",)),
    (QC, dict(road="bump", road_params={"speed": 1e-6}), ("speed=1e-06",)),
    (QC, dict(road="sine_sweep", road_params={"duration": 1e6}), ("road_params['duration']=1000000.0",)),
    (QC, dict(road="sine_sweep", episode_seconds=3e4), ("episode_seconds=30000",)),
    (SB, dict(ground_motion="kanai_tajimi", ground_motion_params={"duration": 1e5}), ("'duration']=100000",)),
    (SB, dict(ground_motion={"kind": "peer_records", "names": ["el_centro_1940_180"], "time_scale": 900}),
     ("time_scale=900",)),
    (SB, dict(ground_motion={"kind": "mixture", "sources": [{"kind": "el_centro", "time_scale": 1000}]}),
     ("time_scale=1000",)),
    (SB, dict(ground_motion=el_centro("EW", dt=0.01), ground_motion_params={"time_scale": 1000}),
     ("time_scale=1000",)),
])
def test_each_option_that_scales_memory_is_refused_by_name(env_id, options, names):
    _refused(lambda: _make(env_id, **options), *names)


def test_num_envs_is_refused_by_name():
    msg, elapsed = _refused(lambda: QuarterCarVectorEnv(num_envs=100_000), "num_envs=100000", "× 100000 environments")
    assert elapsed < 1.0


def test_too_many_preview_times_are_refused():
    with pytest.raises(ValueError, match="at most 1000"):
        _make(QC, preview=[k * 1e-3 for k in range(1, 2001)], sensors=("road_preview",))


def test_the_scalar_history_counts(monkeypatch):
    """The scalar environment keeps every row for signal() and rendering: a limit between the vector env's
    estimate and the scalar one's refuses the scalar environment only, naming the history."""
    scalar = QuarterCarEnv(episode_seconds=20.0).core.memory_parts(20_000)
    vector = QuarterCarVectorEnv(num_envs=1, episode_seconds=20.0).core.memory_parts(20_000)
    assert sum(scalar.values()) > sum(vector.values())
    monkeypatch.setenv(resources.ENV_VAR, str(int(sum(vector.values()) + 1)))
    QuarterCarVectorEnv(num_envs=1, episode_seconds=20.0)
    msg, _ = _refused(lambda: QuarterCarEnv(episode_seconds=20.0), "episode_seconds=20")
    assert "history" in msg


@pytest.mark.parametrize("make, steps", [
    (lambda: QuarterCarEnv(episode_seconds=100.0), 100_000),
    (lambda: ShearBuildingEnv(ground_motion_params={"time_scale": 5.0}, control_dt=1e-3), None),
])
def test_the_estimate_covers_what_an_episode_allocates(make, steps):
    """tracemalloc's peak over construction and reset is within the estimate, and the estimate within 2.5× it."""
    make().reset(seed=0)  # kernels and records loaded
    tracemalloc.start()
    try:
        env = make()
        env.reset(seed=0)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    core = env.core
    estimate = sum(core.memory_parts(core.max_episode_steps).values())
    assert peak <= estimate <= 2.5 * peak, (peak, estimate)


def test_a_refused_reset_changes_nothing(monkeypatch):
    """A source of records of a length unknown at construction is checked at reset, before anything changes."""

    class Lengths(Disturbance):
        channels = ("z_r", "zdot_r")
        n = 2001

        def sample(self, rng, dt):
            t = np.arange(self.n) * dt
            return Record(dt, np.column_stack([1e-3 * np.sin(t), 1e-3 * np.cos(t)]), self.channels, ("m", "m/s"))

    source = Lengths()
    env = QuarterCarEnv(road=source)
    assert env.max_episode_steps is None
    obs, _ = env.reset(seed=0)
    env.step(np.zeros(1))
    k, record = env.core.driver.int_state("K")[0], env.record
    monkeypatch.setenv(resources.ENV_VAR, "200M")
    source.n = 2_000_001
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="an episode of 2000 s") as info:
        env.reset(seed=1)
    assert time.perf_counter() - t0 < 1.0
    assert "200 MiB" in str(info.value)
    assert env.core.driver.int_state("K")[0] == k and env.record is record and env.episode.record is record
    env.step(np.zeros(1))  # the episode goes on
    source.n = 3001
    env.reset(seed=2)
    assert env.record.n_samples == 3001


def test_the_rig_checks_its_tests():
    with pytest.raises(ValueError, match="cycles=50000 at frequency=1 Hz.*3 command levels.*the limit is"):
        sinusoidal_test("spencer_dyke", 0.01, 1.0, (0.0, 1.0, 2.0), cycles=5e4)
    with pytest.raises(ValueError, match="duration=50000 s.*the limit is"):
        random_test("spencer_dyke", 0.005, 10.0, 5e4, command=1.0, rng=0)


# --- the limit --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, value", [("2G", 2 * 1024 ** 3), ("512M", 512 * 1024 ** 2), ("2.5GiB", int(2.5 * 1024 ** 3)),
                                         ("1 gb", 1024 ** 3), ("2e9", 2_000_000_000), ("123", 123), ("none", None),
                                         ("OFF", None)])
def test_the_limit_is_read_from_the_environment(monkeypatch, text, value):
    monkeypatch.setenv(resources.ENV_VAR, text)
    assert resources.memory_limit() == value


@pytest.mark.parametrize("text", ["lots", "-1G", "0", "2X", "nan"])
def test_a_bad_limit_is_named(monkeypatch, text):
    monkeypatch.setenv(resources.ENV_VAR, text)
    with pytest.raises(ValueError, match=resources.ENV_VAR):
        resources.memory_limit()


def test_the_default_limit_is_at_most_half_the_memory():
    phys = resources.physical_memory()
    assert resources.memory_limit() == (min(resources.DEFAULT_LIMIT, phys // 2) if phys else resources.DEFAULT_LIMIT)


def test_no_limit_lets_a_large_estimate_through(monkeypatch):
    monkeypatch.setenv(resources.ENV_VAR, "none")
    assert resources.check({"x": 1e15}, "test") == 1e15


# --- issue 48: the number of dampers and a road's low speed -------------------------------------------------------
def _peak_and_estimate(env_id, options):
    """(tracemalloc's peak over construction and reset, the largest estimate a check made meanwhile)."""
    seen = []
    real = resources.check

    def spy(parts, cause):
        seen.append(sum(parts.values()))
        return real(parts, cause)

    _make(env_id, **{**options, "episode_seconds": 0.1}).reset(seed=0)  # kernels and records loaded
    import mrd_env.envs.core as core_module
    tracemalloc.start()
    try:
        resources.check = core_module.check_memory = spy
        env = _make(env_id, **options)
        env.reset(seed=0)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
        resources.check = core_module.check_memory = real
    return peak, max(seen)


@pytest.mark.parametrize("env_id, options, low, high", [
    # the signal map, the step matrices and the Newton scratch grow with the dampers' square (measured 0.98–0.99)
    ("mrd_env/ShearBuildingPhysical-v0", {"damper_floors": [1, 2, 3] * 13 + [1], "episode_seconds": 1.0}, 0.9, 2.5),
    ("mrd_env/ShearBuildingPhysical-v0", {"damper_floors": [1, 2, 3] * 33 + [1], "episode_seconds": 1.0}, 0.9, 2.5),
    # the rear wheels' delay wheelbase/speed on the road's grid (measured 2.0 and 1.64)
    ("mrd_env/FullCar-v1", {"road": "iso8608", "road_params": {"speed": 0.002}, "episode_seconds": 1.0}, 1.0, 2.5),
    ("mrd_env/HalfCar-v1", {"road": "iso8608", "road_params": {"speed": 0.002}, "episode_seconds": 1.0}, 1.0, 2.5),
])
def test_the_estimate_counts_dampers_and_low_speeds(env_id, options, low, high):
    """The new terms of the estimate against tracemalloc's peak (``bench_memory_estimate.py`` prints more sizes)."""
    peak, estimate = _peak_and_estimate(env_id, options)
    assert low * peak <= estimate <= high * peak, (peak, estimate)
