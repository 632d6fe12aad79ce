"""Hostile environment options (issue 48, items 2, 3, 5a and 9): sizes that scale time or memory beyond the estimate
(dampers, storeys, a road's low speed), parameter values that make the physics meaningless, and files named by an
option that are no regular file of a bounded size. Each is refused at once, naming the option and the valid range,
and never quoting a file's content; an episode whose values stop being finite ends with a reason."""
from __future__ import annotations

import os
import threading
import time
import warnings

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env import resources
from mrd_env.disturbances import Record, read_at2, read_two_column, road_from_csv
from mrd_env.plants import ShearBuildingParams
from mrd_env.plants.quarter_car.env import QuarterCarEnv, QuarterCarVectorEnv
from mrd_env.plants.shear_building.env import ShearBuildingEnv
from mrd_env.plants.shear_building.physics import MAX_DAMPERS, MAX_STOREYS
from mrd_env.plants.shear_building.profile import PROFILE as BUILDING
from mrd_env.records import DamperRecord

pytestmark = pytest.mark.hostile
PASSWD_LINE = ":x:"  # what every line of /etc/passwd holds


@pytest.fixture(autouse=True)
def default_limit(monkeypatch):
    monkeypatch.delenv(resources.ENV_VAR, raising=False)


def _make(env_id, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id, **options)


def _quick(fn, match: str, seconds: float = 1.0) -> str:
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=match) as info:
        fn()
    assert time.perf_counter() - t0 < seconds
    return str(info.value)


# --- item 2: the number of dampers and storeys --------------------------------------------------------------------
@pytest.mark.parametrize("count", [MAX_DAMPERS + 1, 2_000, 5_000, 20_000])
def test_too_many_dampers_are_refused_at_once(count):
    """5 000 dampers were a MemoryError, 2 000 ran over 200 s, 20 000 took 23.7 GB: now refused in well under a
    second, before any matrix is built, naming the option and the maximum."""
    msg = _quick(lambda: ShearBuildingEnv(damper_floors=[1, 2, 3] * (count // 3) + [1] * (count % 3)),
                 rf"damper_floors: more than {MAX_DAMPERS} dampers, at most {MAX_DAMPERS}")
    assert len(msg) < 300
    _quick(lambda: _make("mrd_env/ShearBuilding-v1", damper_floors=range(10 ** 9)), "at most")
    _quick(lambda: ShearBuildingParams.uniform(6, 200.0, 1e6, damper_floors=[1] * count), "at most")


def test_the_most_dampers_run():
    env = ShearBuildingEnv(damper_floors=[1, 2, 3] * (MAX_DAMPERS // 3) + [1] * (MAX_DAMPERS % 3),
                           episode_seconds=0.02)
    env.reset(seed=0)
    assert np.all(np.isfinite(env.step(env.action_space.sample())[0]))


def test_the_command_line_option_is_refused_by_name():
    with pytest.raises(ValueError, match=rf"--damper-storeys: more than {MAX_DAMPERS} dampers") as info:
        BUILDING.apply_plant_options({}, {"damper-storeys": ",".join(["1"] * 5000)})
    assert len(str(info.value)) < 300


def test_an_agents_damper_count_is_refused_by_the_environment():
    from controllers.agents import check_env_kwargs

    with pytest.raises(ValueError, match="env_kwargs are refused.*at most"):
        check_env_kwargs("mrd_env/ShearBuilding-v1", {"damper_floors": [1] * 5000}, "a")


@pytest.mark.parametrize("n", [MAX_STOREYS + 1, 5_000])
def test_too_many_storeys_are_refused(n):
    _quick(lambda: ShearBuildingParams.uniform(n, 1e5, 1e8), rf"in 1\.\.{MAX_STOREYS}")
    masses = [100.0] * n
    _quick(lambda: ShearBuildingEnv(plant_params={"masses": masses, "K": np.eye(2), "C": np.eye(2)}),
           rf"{n} floors, at most {MAX_STOREYS}")


# --- item 5a: a road's length that grows with 1/speed -------------------------------------------------------------
@pytest.mark.parametrize("env_id", ["mrd_env/FullCar-v1", "mrd_env/HalfCar-v1"])
def test_a_slow_road_is_refused_by_its_speed(env_id):
    """A full car at 2·10⁻⁵ m/s took 3.5 GB for a 1 s episode (the rear wheels' delay wheelbase/speed on the
    road's grid): now refused at once, naming the speed, the estimate and the limit."""
    _make(env_id, episode_seconds=0.1)
    msg = _quick(lambda: _make(env_id, episode_seconds=1.0, road="iso8608", road_params={"speed": 2e-5}),
                 r"road_params\['speed'\]=2e-05 m/s")
    assert "needs about" in msg and "the limit is" in msg and "wheelbase/speed" in msg
    _make(env_id, episode_seconds=1.0, road="iso8608", road_params={"speed": 0.5})  # a slow car, still fine


# --- item 9: physically meaningless parameters, non-finite values ------------------------------------------------
@pytest.mark.parametrize("env_id, params, name", [
    ("mrd_env/QuarterCar-v1", {"m_s": 1e-300}, "m_s"),
    ("mrd_env/QuarterCar-v1", {"m_u": 1e-6}, "m_u"),
    ("mrd_env/QuarterCar-v1", {"k_t": 1e300}, "m_u"),
    ("mrd_env/QuarterCar-v1", {"c_p": 1e9}, "m_u"),
    ("mrd_env/HalfCar-v1", {"m_uf": 1e-300}, "m_uf"),
    ("mrd_env/HalfCar-v1", {"I_y": 1e-300}, "I_y"),
    ("mrd_env/FullCar-v1", {"m_s": 1e-300}, "m_s"),
    ("mrd_env/Isolator-v1", {"m": 1e-300}, "m"),
    ("mrd_env/ShearBuilding-v1", {"masses": (1e-300, 98.3, 98.3)}, r"masses\[0\]"),
])
def test_a_plant_faster_than_the_step_is_refused_naming_the_parameter(env_id, params, name):
    """A mass of 1e-300 gave infinite and NaN observations and rewards: it is refused, naming the parameter, its
    value, the physical reason (a frequency or damping rate the 1 ms step cannot resolve) and the valid bound."""
    msg = _quick(lambda: _make(env_id, plant_params=params), rf"plant_params: {name} = ", seconds=5.0)
    assert ("500 Hz" in msg or "2π/dt" in msg) and "must be at least" in msg, msg


def test_a_smaller_step_resolves_a_stiffer_plant():
    """The bound is the step's: a tyre ten thousand times stiffer is refused at 1 ms, accepted at 10 µs."""
    with pytest.raises(ValueError, match="m_u"):
        QuarterCarEnv(plant_params={"k_t": 2e9})
    QuarterCarEnv(plant_params={"k_t": 2e9}, dt=1e-5, control_dt=1e-3, episode_seconds=0.01)


def _huge_road(n=2001, z=1e60):
    return Record(1e-3, np.column_stack([np.full(n, z), np.zeros(n)]), ("z_r", "zdot_r"), ("m", "m/s"), "huge")


def test_a_non_finite_observation_ends_the_episode():
    """A road of 1e60 m makes the states overflow the float32 observation: the episode ends (terminated, a reason,
    the divergence's penalty as its reward) instead of handing infinities on."""
    env = QuarterCarEnv(road=_huge_road(), damper="bingham")
    env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(np.zeros(1))
    assert not np.all(np.isfinite(obs))
    assert terminated and not truncated and np.isfinite(reward) and reward < 0
    assert info["termination_reason"].startswith("non_finite")
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(np.zeros(1))


def test_a_non_finite_observation_ends_that_vector_environment_only():
    v = QuarterCarVectorEnv(num_envs=2, road=_huge_road(), damper="bingham")
    v.reset(seed=0)
    _, rewards, terminated, _, info = v.step(np.zeros((2, 1)))
    assert terminated.all() and np.all(np.isfinite(rewards))
    assert all(r.startswith("non_finite") for r in info["termination_reason"])
    ok = QuarterCarVectorEnv(num_envs=2, damper="bingham", episode_seconds=0.1)
    ok.reset(seed=0)
    assert not ok.step(np.zeros((2, 1)))[2].any()


# --- item 3: files named by an option ----------------------------------------------------------------------------
READERS = {
    "road csv": lambda p: road_from_csv(p, height_column="z", distance_column="x", speed=10.0),
    "at2": read_at2,
    "two_column": lambda p: read_two_column(p, accel_unit="g"),
    "damper record": DamperRecord.read_csv,
}


def _agent_json(path):
    """An agent folder whose agent.json is ``path`` (a link to it): what loading a shared agent reads first."""
    import tempfile
    from pathlib import Path

    from controllers import load_agent

    folder = Path(tempfile.mkdtemp())
    (folder / "agent.json").symlink_to(Path(path).resolve())
    return load_agent(folder)


#: Files the project loads that are not options' records: a damper preset, a neural inverse's network, an agent's
#: metadata and observation statistics — read the same way (regular files only, a size cap).
LOADERS = {
    "damper preset": lambda p: __import__("mrd_env.dampers.preset_file", fromlist=["read_preset"]).read_preset(p),
    "network": lambda p: __import__("mrd_env.inverse.neural", fromlist=["load_network"]).load_network(p),
    "agent.json": _agent_json,
    "normalization": lambda p: __import__("controllers.agents", fromlist=["x"]).ObservationNormalizer.load(p),
}


@pytest.mark.parametrize("loader", list(LOADERS))
def test_a_shared_file_that_is_a_device_or_fifo_is_refused_without_waiting(tmp_path, loader):
    """A preset, a network, an agent's agent.json or statistics that is /dev/zero was read until memory ran out; a
    FIFO blocked forever. Both are refused at once, by name."""
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    for path in ("/dev/zero", fifo):
        done = []
        t = threading.Thread(target=lambda: done.append(pytest.raises(ValueError, LOADERS[loader], path)),
                             daemon=True)
        t.start()
        t.join(10.0)
        assert done and "not a regular file" in str(done[0].value), (loader, path)


@pytest.mark.parametrize("reader", list(READERS))
def test_a_device_is_refused_without_reading_it(reader):
    """/dev/zero was read until memory ran out."""
    _quick(lambda: READERS[reader]("/dev/zero"), "not a regular file")


@pytest.mark.parametrize("reader", list(READERS))
def test_a_fifo_is_refused_without_waiting(tmp_path, reader):
    """A FIFO blocked forever (no writer ever comes)."""
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    done = []
    t = threading.Thread(target=lambda: done.append(pytest.raises(ValueError, READERS[reader], fifo)), daemon=True)
    t.start()
    t.join(5.0)
    assert done and "not a regular file" in str(done[0].value)


@pytest.mark.parametrize("reader", list(READERS))
def test_a_file_over_the_cap_is_refused_by_its_size(tmp_path, monkeypatch, reader):
    monkeypatch.setenv(resources.ENV_VAR, "32M")  # the cap: 2 MiB
    big = tmp_path / "big.csv"
    big.write_bytes(b"x [m],z [m]\n" + b"0.0,0.0\n" * (300_000))
    _quick(lambda: READERS[reader](big), f"more than the {resources.file_limit()} bytes")


@pytest.mark.skipif(not os.path.isfile("/etc/passwd"), reason="no /etc/passwd")
@pytest.mark.parametrize("reader", list(READERS))
def test_an_error_never_quotes_the_file(reader):
    """/etc/passwd's second line was printed in an error: now the file and the line are named, nothing of it."""
    with pytest.raises(ValueError) as info:
        READERS[reader]("/etc/passwd")
    assert PASSWD_LINE not in str(info.value) and "/etc/passwd" in str(info.value)


@pytest.mark.skipif(not os.path.isfile("/etc/passwd"), reason="no /etc/passwd")
def test_an_environment_names_the_file_not_its_content():
    for make in (lambda: _make("mrd_env/ShearBuilding-v1", ground_motion="at2",
                               ground_motion_params={"path": "/etc/passwd"}),
                 lambda: _make("mrd_env/QuarterCar-v1", road={"kind": "csv", "path": "/etc/passwd",
                                                              "height_column": "root", "time_column": "x"})):
        with pytest.raises(ValueError) as info:
            make()
        assert PASSWD_LINE not in str(info.value) and "/etc/passwd" in str(info.value)
    _quick(lambda: _make("mrd_env/ShearBuilding-v1", ground_motion="at2", ground_motion_params={"path": "/dev/zero"}),
           "not a regular file")


def test_a_record_name_from_a_file_is_not_quoted_in_a_refusal(tmp_path, monkeypatch):
    """The refusal of a long replay names the AT2 file by its path, not by the title its second line gives."""
    at2 = tmp_path / "r.AT2"
    at2.write_text("PEER\nSECRET TITLE\nACCELERATION TIME SERIES IN UNITS OF G\nNPTS=   5, DT=   .0100 SEC\n"
                   "0.1 0.2 0.3 0.2 0.1\n")
    monkeypatch.setenv(resources.ENV_VAR, "1M")
    with pytest.raises(ValueError, match="needs about") as info:
        _make("mrd_env/ShearBuilding-v1", ground_motion="at2", ground_motion_params={"path": str(at2),
                                                                                    "time_scale": 1000})
    assert "SECRET" not in str(info.value) and "r.AT2" in str(info.value)


@pytest.mark.parametrize("values, option", [({"storeys": "²"}, "--storeys"), ({"storeys": "٣"}, "--storeys"),
                                            ({"storeys": "9" * 5000}, "--storeys"),
                                            ({"damper-storeys": "1,²"}, "--damper-storeys")])
def test_the_building_options_refuse_unicode_digits_from_python(values, option):
    """'²'.isdigit() is true and int('²') fails: the plant's own option check (what Python callers and suites reach,
    not only the CLI's argparse type) names the option, with a bounded quote of the value."""
    with pytest.raises(ValueError, match=option) as err:
        BUILDING.with_plant_options(values)
    assert len(str(err.value)) < 300
