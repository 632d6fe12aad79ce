"""The benchmark: one evaluation loop over controllers and scenarios, well-formed reproducible reports."""
import csv

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from controllers import AgentController, ClippedOptimal, SkyhookOnOff, make_controller
from experiments.commands.benchmark import run_benchmark
from experiments.common.evaluation import evaluate
from experiments.common.scenarios import Scenario
from experiments.cli import main
from experiments.common.plants import profile


def short_building():
    return [Scenario("El Centro 1.5 s", "mrd_env/ShearBuildingPhysical-v0",
                     dict(ground_motion="el_centro", ground_motion_params={"time_scale": 0.2}, episode_seconds=1.5))]


def test_controller_on_env_without_needed_sensors_raises():
    env = gym.make("mrd_env/QuarterCarPhysical-v0", episode_seconds=0.5, sensors=("sprung_acc", "travel"))
    with pytest.raises(ValueError, match="sprung_vel"):
        SkyhookOnOff(env)
    env_b = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=("abs_acc", "ground_acc"), episode_seconds=0.5)
    with pytest.raises(ValueError, match="damper_force"):
        ClippedOptimal(env_b)


def test_benchmark_reports_are_well_formed_and_reproducible(tmp_path):
    ctrls = ["passive_off", "passive_on", "clipped_optimal"]
    a = run_benchmark(profile("shear_building"), ctrls, short_building(), out=tmp_path / "a", progress=False)
    b = run_benchmark(profile("shear_building"), ctrls, short_building(), out=tmp_path / "b", progress=False)
    assert [e.controller for e in a] == ctrls
    for ea, eb in zip(a, b):
        assert np.array_equal(ea.response, eb.response) and ea.metrics == eb.metrics
    assert (tmp_path / "a" / "shear_building_benchmark.csv").read_text() == (tmp_path / "b" / "shear_building_benchmark.csv").read_text()
    with (tmp_path / "a" / "shear_building_benchmark.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3 + 3  # per scenario, then the worst case per controller
    for r in rows:
        for k in ("J1", "J2", "J4"):
            assert 0.0 < float(r[k]) < 2.0
    md = (tmp_path / "a" / "shear_building_benchmark.md").read_text().splitlines()
    header = [ln for ln in md if ln.startswith("| scenario")][0]
    assert all(ln.count("|") == header.count("|") for ln in md if ln.startswith("|"))
    pngs = sorted(p.name for p in (tmp_path / "a").glob("*.png"))
    assert "shear_building_bars.png" in pngs and any(p.startswith("shear_building_history") for p in pngs)
    # a damper in the loop cuts the peak drift relative to the uncontrolled building
    assert all(float(r["J1"]) < 1.0 for r in rows)


def test_quarter_car_benchmark_with_seeded_roads(tmp_path):
    sc = [Scenario("ISO-C 1 s", "mrd_env/QuarterCarPhysical-v0",
                   dict(road="iso8608", road_params={"road_class": "C", "speed": 20.0}, episode_seconds=1.0), seeds=(3,))]
    eps = run_benchmark(profile("quarter_car"), ["passive_off", "skyhook_on_off", "groundhook"], sc, out=tmp_path,
                        progress=False)
    assert eps[-1].controller.startswith("passive_ref")
    with (tmp_path / "quarter_car_benchmark.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    off = [r for r in rows if r["controller"] == "passive_off"][0]
    assert float(off["acc_weighted_rms/off"]) == pytest.approx(1.0)
    assert all(float(r["acc_weighted_rms (m/s²)"]) > 0 for r in rows)   # headers carry their units
    assert rows[-1]["scenario"] == "worst over scenarios"


def test_benchmark_tables_hold_means_over_seeds_and_figures_only_ratios(tmp_path):
    """Issue 22: the table a report quotes is the mean over a scenario's seeds (every episode in its own CSV); the
    bar chart draws ratios only; a history shows at most four controllers."""
    from experiments.commands.benchmark import HISTORY_LINES

    sc = [Scenario("ISO-C 1 s", "mrd_env/QuarterCarPhysical-v0",
                   dict(road="iso8608", road_params={"road_class": "C", "speed": 20.0}, episode_seconds=0.5),
                   seeds=(3, 4))]
    ctrls = ["passive_off", "passive_on", "skyhook_on_off", "groundhook", "hybrid"]
    eps = run_benchmark(profile("quarter_car"), ctrls, sc, out=tmp_path, progress=False, reference_passive=False)
    with (tmp_path / "quarter_car_benchmark.csv").open() as fh:
        means = list(csv.DictReader(fh))
    with (tmp_path / "quarter_car_benchmark_episodes.csv").open() as fh:
        per_episode = list(csv.DictReader(fh))
    assert len(per_episode) == 2 * len(ctrls) and len(means) == 2 * len(ctrls)  # means, then the worst case
    sky = [float(r["return"]) for r in per_episode if r["controller"] == "skyhook_on_off"]
    row = next(r for r in means if r["controller"] == "skyhook_on_off" and r["scenario"] == "ISO-C 1 s")
    assert float(row["return"]) == pytest.approx(np.mean(sky)) and row["episodes"] == "2"
    from experiments.commands.benchmark import history_selection

    shown = history_selection([e for e in eps if e.scenario == eps[0].scenario])
    assert len(shown) == HISTORY_LINES and {"passive_off", "passive_on"} <= {e.controller for e in shown}


def test_history_shows_one_line_per_law():
    """A law and the same law with an inverse draw on top of each other: the history takes the better of the two
    and then the next law."""
    from types import SimpleNamespace

    from experiments.commands.benchmark import history_selection

    eps = [SimpleNamespace(controller=c, episode_return=r) for c, r in
           [("passive_off", -2.1), ("passive_on", -1.0), ("clipped_optimal", -0.85), ("clipped_optimal+model", -0.855),
            ("clipped_optimal_reward", -0.86), ("lyapunov", -1.03)]]
    assert [e.controller for e in history_selection(eps)] == ["passive_off", "passive_on",
                                                              "clipped_optimal", "clipped_optimal_reward"]


def test_building_history_follows_the_damper_storey():
    assert profile("shear_building").response({"damper_floors": (2,)}) == "drift[1]"
    assert profile("shear_building").response({}) == "drift[0]"
    assert profile("quarter_car").response({}) == "sprung_acc"


def test_agent_and_classical_controllers_share_the_loop():
    env = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=("abs_acc", "damper_force", "drift", "damper_velocity",
                                                        "ground_acc"), episode_seconds=0.3)

    class Constant:  # anything with SB3's predict
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.array([1.0], dtype=np.float32), state

    ep = evaluate(AgentController(env, Constant(), name="const"), env, 0, "drift")
    assert ep.metrics and len(ep.t) == 300 and np.isfinite(ep.episode_return)
    assert make_controller("passive_on", env).predict(np.zeros(env.observation_space.shape))[0][0] == 2.25


def test_cli_benchmark_quick(tmp_path):
    assert main(["benchmark", "--plant", "shear_building", "--quick", "--controllers", "passive_off", "passive_on",
                 "--out", str(tmp_path), "--no-progress"]) == 0
    assert (tmp_path / "shear_building_benchmark_worst.md").exists()


def test_model_based_estimate_stays_at_rest_despite_the_damper_preload():
    """The damper force sensor includes the static preload (k1·x0), which the plant balances: the Kalman
    filter must not read it as a load (regression: a 0.14 mm phantom drift)."""
    from mrd_env.disturbances import Record

    quiet = Record(1e-3, np.zeros((1001, 1)), ("xg_ddot",), ("m/s^2",))
    env = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=("abs_acc", "damper_force", "ground_acc"),
                   ground_motion=quiet, episode_seconds=0.8)
    co = ClippedOptimal(env)
    obs, _ = env.reset(seed=0)
    assert obs[env.unwrapped.sensor_layout[1][1]][0] == pytest.approx(env.unwrapped.F_static, abs=1e-6)
    for _ in range(700):
        obs, *_ = env.step(co.predict(obs)[0])
    assert np.max(np.abs(co.kf.x)) < 1e-9


def test_a_vector_environment_scores_every_seed_as_scalar_episodes_would():
    """The benchmark's batched evaluation (one vector env, one row per seed) gives each seed the metrics and
    return of a scalar episode with that seed."""
    from experiments.common.evaluation import evaluate_batch

    sc = Scenario("KT", "mrd_env/ShearBuildingPhysical-v0", dict(ground_motion="kanai_tajimi", episode_seconds=0.6),
                  seeds=(4, 5, 6))
    sensors = ("abs_acc", "drift", "damper_force", "damper_velocity", "ground_acc")
    batch = evaluate_batch(lambda v: make_controller("clipped_optimal", v), sc, "drift", sensors=sensors)
    for seed, ep in zip(sc.seeds, batch):
        env = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=sensors, **sc.options)
        single = evaluate(make_controller("clipped_optimal", env), env, seed, "drift")
        assert ep.metrics == single.metrics and ep.episode_return == single.episode_return


def test_the_default_controller_set_runs_on_a_fitted_damper_leaving_out_the_rows_it_cannot_serve(tmp_path, capsys):
    """A fitted damper has no shipped neural inverse: the default set's clipped_optimal+neural row is left out with a
    note, every other default law runs (issue 36); named explicitly, the row is refused before any episode."""
    from mrd_env.dampers import make_damper
    from mrd_env.identification.presets import save_preset

    fitted = make_damper("spencer_dyke")
    fitted.params = fitted.params.replace(c0a=1.1 * fitted.params.c0a)
    preset = save_preset(fitted, tmp_path / "fitted.json", source="test: a refitted damper")
    out = tmp_path / "out"
    assert main(["benchmark", "--plant", "shear_building", "--quick", "--damper", str(preset), "--out", str(out),
                 "--no-progress", "--yardstick", "off"]) == 0
    err = capsys.readouterr().err
    assert "note: clipped_optimal+neural left out of the shear building benchmark: no neural inverse ships" in err
    table = (out / "shear_building_benchmark.md").read_text()
    for law in profile("shear_building").benchmark_laws:
        assert (law in table) == (law != "clipped_optimal+neural"), law
    assert main(["benchmark", "--plant", "shear_building", "--quick", "--damper", str(preset), "--controllers",
                 "clipped_optimal+neural", "--out", str(out), "--no-progress"]) == 2
    assert "--controllers: clipped_optimal+neural does not apply to the shear building" in capsys.readouterr().err


def test_an_unwritable_out_folder_is_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["benchmark", "--plant", "shear_building", "--quick", "--out", str(blocker / "sub"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and err.count("\n") == 1
