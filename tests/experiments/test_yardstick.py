"""The per-episode yardstick (experiments.benchmark.yardstick, the learning curves' references): shares of the
achievable gain, the bracket, the cache and its keys."""
import math

import pytest

from experiments.benchmark.yardstick import EpisodeYardstick
from mrd_env.optimal import cache
from experiments.common.plants import profile


def test_share_of_the_achievable_gain():
    y = EpisodeYardstick("ISO-C s1", 1, passive=-10.0, passive_command=2.0, clairvoyant=-6.0, source="optimiser",
                         clairvoyant_seconds=1.0, bound=-5.0)
    assert y.share(-10.0) == 0.0 and y.share(-6.0) == 1.0 and y.share(-9.0) == pytest.approx(0.25)
    assert y.share(-12.0) < 0                         # worse than the best passive setting
    assert y.bracket == pytest.approx(1.0 / 5.0)      # (−5 + 6) / (−5 + 10)
    flat = EpisodeYardstick("x", 0, -1.0, 0.0, -1.0, "passive", 0.0)
    assert math.isnan(flat.share(-1.0))               # no gain to share: not a number, not a division by zero


def test_cache_returns_only_the_exact_key(tmp_path, monkeypatch):
    monkeypatch.setattr("mrd_env.optimal.cache.cache_dir", lambda: tmp_path / "optimal")  # kernels stay cached
    key = {"env_id": "mrd_env/QuarterCarPhysical-v0", "seed": 1, "damper_params": {"c0a": 1.0}}
    assert cache.load("clairvoyant", key) is None
    path = cache.store("clairvoyant", key, {"ret": -3.5})
    assert path.parent == tmp_path / "optimal" and cache.load("clairvoyant", key) == {"ret": -3.5}
    assert cache.load("clairvoyant", {**key, "damper_params": {"c0a": 2.0}}) is None   # another damper
    assert cache.load("bound", key) is None                                            # another kind
    # a file whose stored key is not the one asked for (edited, or a hash collision) is refused
    text = path.read_text().replace('"seed": 1', '"seed": 2')
    path.write_text(text)
    assert cache.load("clairvoyant", key) is None


def test_intervals_only_where_there_are_repeats_and_never_beyond_the_possible():
    """Issue 22: one episode has no interval; a return (≤ 0) never gets an interval reaching above zero."""
    from experiments.common.evaluation import mean_ci

    m, lo, hi = mean_ci([-2.0])
    assert m == -2.0 and math.isnan(lo) and math.isnan(hi)
    m, lo, hi = mean_ci([-0.1, -0.2, -5.0], upper=0.0)
    assert lo < m < hi == 0.0
    assert mean_ci([-1.0, -1.0]) == (-1.0, -1.0, -1.0)


def test_the_yardstick_brackets_every_controller_on_an_episode(tmp_path, monkeypatch):
    """On one held-out car episode: no law, no shipped agent and no MPC (with or without preview) beats the
    clairvoyant return, and the clairvoyant stays below the active bound, which covers their forces."""
    from controllers import shipped_agents
    from experiments.common.evaluation import controller_episodes
    from experiments.common.scenarios import Scenario, preview_options
    from experiments.benchmark.yardstick import episode_yardstick

    monkeypatch.setattr("mrd_env.optimal.cache.cache_dir", lambda: tmp_path / "optimal")  # kernels stay cached
    sc = Scenario("ISO-C 1 s", "mrd_env/QuarterCarPhysical-v0",
                  dict(road="iso8608", road_params={"road_class": "C", "speed": 20.0}, episode_seconds=1.0),
                  seeds=(1_000_000,))
    agents = shipped_agents("quarter_car")
    y = episode_yardstick(sc, 1_000_000, profile("quarter_car").warm_laws, agents=agents)
    assert y.passive <= y.clairvoyant <= y.bound
    # the passivity-aware bound lies between: every semi-active damper (the clairvoyant too) is a passive device
    assert y.clairvoyant <= y.dissipative <= y.bound + 1e-6 * abs(y.bound)
    assert 0.0 <= y.dissipative_bracket <= y.bracket + 1e-6
    assert set(y.warm_starts) >= {"passive_off", "passive_on", "skyhook_continuous", "clipped_optimal"}
    assert all(r <= y.clairvoyant for r in y.warm_starts.values())   # every law at 1 ms and the shipped agent
    assert y.clairvoyant > max(y.warm_starts.values())               # and strictly better than the best of them
    others = [controller_episodes("mpc", sc, control_dt=0.01)[0],
              controller_episodes("mpc", sc, **preview_options(profile("quarter_car"), {"control_dt": 0.01}))[0],
              controller_episodes("skyhook_continuous", sc, control_dt=0.01)[0]]
    for e in others:
        assert e.episode_return <= y.clairvoyant, e.controller
        assert y.share(e.episode_return) <= 1.0
    # the cache returns the same yardstick without solving
    again = episode_yardstick(sc, 1_000_000, profile("quarter_car").warm_laws, agents=agents, solve=False)
    assert again is not None and again.clairvoyant == y.clairvoyant and again.bound == y.bound
    assert again.dissipative == y.dissipative
    # a yardstick cached before R_d was reported gets R_d alone (the clairvoyant is not solved again), then keeps it
    from mrd_env.optimal import cache, episode_problem
    from experiments.benchmark.yardstick import YARDSTICK_DT, yardstick_key

    problem = episode_problem(sc.env_id, seed=1_000_000, control_dt=YARDSTICK_DT, **sc.options)
    key = yardstick_key(problem, sc.label(1_000_000), profile("quarter_car").warm_laws, agents)
    old = {k: v for k, v in cache.load("yardstick", key).items() if not k.startswith("dissipative")}
    cache.store("yardstick", key, old)
    assert math.isnan(episode_yardstick(sc, 1_000_000, profile("quarter_car").warm_laws, agents=agents,
                                        solve=False).dissipative)                 # a cached-only read solves nothing
    monkeypatch.setattr("mrd_env.optimal.clairvoyant", None)                      # it must not be called
    filled = episode_yardstick(sc, 1_000_000, profile("quarter_car").warm_laws, agents=agents)
    assert filled.dissipative == pytest.approx(y.dissipative, rel=1e-9) and filled.clairvoyant == y.clairvoyant
    assert cache.load("yardstick", key)["dissipative"] == filled.dissipative


def test_the_cache_lives_under_the_projects_cache_directory(tmp_path, monkeypatch):
    monkeypatch.setenv("MRD_ENV_CACHE_DIR", str(tmp_path))
    assert cache.cache_dir() == tmp_path / "optimal"


def test_cached_yardsticks_are_keyed_by_the_agents_content_not_their_folder_names(tmp_path):
    """Every training run keeps its best agent in a folder named best/: two different agents there must not share a
    cached yardstick, and the same agent copied elsewhere may."""
    import shutil

    from controllers import shipped_agents
    from controllers.agents import agent_digest

    car, building = shipped_agents("quarter_car")[0], shipped_agents("shear_building")[0]
    a, b, c = (shutil.copytree(src, tmp_path / n / "best") for n, src in (("a", car), ("b", building), ("c", car)))
    assert agent_digest(a) == agent_digest(c) == agent_digest(car)
    assert agent_digest(a) != agent_digest(b)
    (c / "agent.json").write_text((c / "agent.json").read_text().replace('"seed": 0', '"seed": 7'))
    assert agent_digest(c) != agent_digest(a)


def test_the_yardstick_key_changes_with_what_the_result_depends_on(monkeypatch):
    """A default the options do not name (the car's reward weights) changes the key: a cached yardstick of the
    old problem is not served for the new one."""
    from experiments.common.scenarios import held_out_scenarios
    from experiments.benchmark.yardstick import YARDSTICK_DT, yardstick_key
    from mrd_env.plants.quarter_car import env as quarter_car
    from mrd_env.optimal import episode_problem

    sc = held_out_scenarios(profile("quarter_car"), quick=True)[0]

    def key():
        problem = episode_problem(sc.env_id, seed=sc.seeds[0], control_dt=YARDSTICK_DT,
                                  **{**sc.options, "episode_seconds": 0.05})
        return yardstick_key(problem, sc.label(sc.seeds[0]), profile("quarter_car").warm_laws)

    before = key()
    assert key() == before
    assert before["damper"] == "spencer_dyke"   # the damper is part of the key: another damper, another yardstick
    other = episode_problem(sc.env_id, seed=sc.seeds[0], control_dt=YARDSTICK_DT,
                            **{**sc.options, "episode_seconds": 0.05, "damper": "bingham"}).key()
    assert other["damper"] == "bingham"
    monkeypatch.setitem(quarter_car.DEFAULT_REWARD_WEIGHTS, "travel",
                        2.0 * quarter_car.DEFAULT_REWARD_WEIGHTS["travel"])
    after = key()
    assert after["problem_digest"] != before["problem_digest"] and after != before
