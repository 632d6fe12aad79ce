"""The JAX twin's memory estimate (issue 48, item 5): a batch (``num_envs``), a bank (``seeds``, ``records``) and a
randomised bank's plants estimated before anything is drawn or allocated, refused above ``MRD_ENV_MEMORY_LIMIT``
with the option, the estimate and the limit; the estimate near what the arrays take. No compile here."""
from __future__ import annotations

import time

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import gymnasium as gym  # noqa: E402

import mrd_env  # noqa: E402,F401
from mrd_env.disturbances import iso8608_road  # noqa: E402
from mrd_env.jax import env as je  # noqa: E402
from mrd_env.jax import vector as jv  # noqa: E402
from mrd_env.plants.quarter_car.suites import ROBUST_BANDS  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")
CAR = "mrd_env/QuarterCar-v1"


def _rss() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096


@pytest.fixture
def nothing_drawn(monkeypatch):
    """Drawing a record or building a bank fails the test: a refusal must come before them."""
    def drawn(*args, **kwargs):
        raise AssertionError("a record was drawn before the memory check")

    monkeypatch.setattr(je, "native_records", drawn)
    monkeypatch.setattr(je, "drawn_episodes", drawn)
    monkeypatch.setattr(je, "params_of_episodes", drawn)


@pytest.mark.hostile
def test_ten_million_environments_are_refused_at_once_before_any_allocation(nothing_drawn, monkeypatch):
    """``num_envs=10**7`` (its first step asked XLA for 23 GB) is refused in milliseconds with the option, the
    estimate and the limit; no array is made (the live arrays and the resident memory unchanged)."""
    monkeypatch.delenv("MRD_ENV_MEMORY_LIMIT", raising=False)
    je.assembly_of(CAR, {})  # the plant's imports, outside the timing
    live, rss, t = len(jax.live_arrays()), _rss(), time.perf_counter()
    with pytest.raises(ValueError, match=r"num_envs=10000000.* needs about \d+ GiB .*; the limit is .*"
                                         r"MRD_ENV_MEMORY_LIMIT") as e:
        gym.make_vec(CAR, num_envs=10 ** 7, vectorization_mode="vector_entry_point", backend="jax")
    assert time.perf_counter() - t < 1.0, "refused in well under a second (the plant's assembly included)"
    assert len(jax.live_arrays()) == live and _rss() - rss < 32 * 2 ** 20
    assert "environments' state and step" in str(e.value)


@pytest.mark.hostile
def test_the_quarter_cars_road_bank_is_refused_before_a_road_is_drawn(monkeypatch):
    """The quarter car's own twin (``jax_twin.make_params(n_roads=...)``) drew every road before any check."""
    from mrd_env.plants.quarter_car import jax_twin

    def drawn(*args, **kwargs):
        raise AssertionError("a road was drawn before the memory check")

    monkeypatch.setattr(jax_twin, "iso8608_road", drawn)
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", "1G")
    with pytest.raises(ValueError, match=r"n_roads=20000 \(20000 episodes of 10 s.* needs about .*the limit is 1 GiB"):
        jax_twin.make_params(n_roads=20_000)


@pytest.mark.hostile
def test_a_huge_seed_list_is_refused_by_its_memory_and_count(nothing_drawn, monkeypatch):
    """12 000 seeds of 10 s roads (7.9 GB before) are refused by their estimate, naming ``seeds``, for
    ``make_params`` and the vector environment alike; 10¹² seeds by their count, before a list is made."""
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", "4G")
    for make in (lambda s: je.make_params(CAR, seeds=s), lambda s: jv.JaxVectorEnv(CAR, 2, seeds=s)):
        t = time.perf_counter()
        with pytest.raises(ValueError, match=r"seeds \(12000 episodes of 10 s.* needs about .*the inputs W.*"
                                             r"the limit is 4 GiB"):
            make(range(12_000))
        with pytest.raises(ValueError, match=r"seeds must name 1 to 100000 episodes, got 1000000000000"):
            make(range(10 ** 12))
        assert time.perf_counter() - t < 1.0
    with pytest.raises(ValueError, match=r"seeds must be ints >= 0, got -1"):
        je.make_params(CAR, seeds=[-1])


@pytest.mark.hostile
def test_a_records_bank_and_a_randomised_bank_are_estimated_under_a_small_limit(monkeypatch):
    """Given records are counted (their inputs W at every physics step), and a randomised bank counts each
    episode's own plant: both refused under a 4 MiB limit, naming ``records`` / ``seeds``."""
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", "4M")
    road = iso8608_road("C", 20.0, 10.0, 1e-3, rng=1, method="fft")
    with pytest.raises(ValueError, match=r"records \(40 records of up to 10001 samples\) needs about .*the inputs W"):
        je.make_params(CAR, records=[road] * 40)
    with pytest.raises(ValueError, match=r"num_envs=2, records \(40 records"):
        jv.JaxVectorEnv(CAR, 2, records=[road] * 40)
    monkeypatch.setattr(je, "drawn_episodes", lambda *a, **k: pytest.fail("drawn before the check"))
    with pytest.raises(ValueError, match=r"seeds \(2000 episodes.*the plant of each episode"):
        je.make_params(CAR, seeds=range(2000), randomise=ROBUST_BANDS, episode_seconds=0.01)


def test_the_bank_estimate_is_near_the_banks_arrays():
    """The estimate of a small bank is at least its arrays (the inputs W, the plants, the initial states) and
    within a few times them (the records it was made from are counted too)."""
    opts = dict(episode_seconds=0.2)
    asm, _ = je.assembly_of(CAR, opts)
    for randomise in (None, ROBUST_BANDS):
        params = je.make_params(CAR, seeds=range(6), randomise=randomise, **opts)
        held = sum(np.asarray(x).nbytes for x in jax.tree_util.tree_leaves(params))
        est = sum(je.bank_parts(asm, 6, je.record_samples(asm, [0]), drawn=randomise is not None,
                                generated=False).values())
        assert held <= est <= 4 * held, (randomise is not None, held, est)


def test_within_the_limit_nothing_changes(monkeypatch):
    """A bank and a batch within the limit are made as before (the check returns its estimate)."""
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", "none")
    asm, _ = je.assembly_of(CAR, {})
    assert je.check_bank(asm, seeds=list(range(100_000)), num_envs=10 ** 9) > 1e12  # no limit: no refusal
    monkeypatch.setenv("MRD_ENV_MEMORY_LIMIT", "4G")
    env = jv.JaxVectorEnv(CAR, 3, seeds=[0, 1], episode_seconds=0.02)
    assert env.num_envs == 3 and env.params.W.shape[0] == 2
