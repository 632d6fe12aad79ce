"""The benchmark (``mrd-env benchmark``, :func:`experiments.benchmark.run_benchmark`): every controller that fits a
suite scored on it, the result files and leaderboards it writes, what does not fit listed with the reason, the
user's errors refused in one line before anything runs or is written; and the evaluation loop under it."""
import json

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from controllers import AgentController, ClippedOptimal, SkyhookOnOff, make_controller
from experiments.benchmark import run_benchmark, score, shipped_controllers, suite
from experiments.cli import main
from experiments.common.evaluation import evaluate, evaluate_batch
from experiments.common.plants import profile
from experiments.common.scenarios import Scenario

CAR = "car-comfort-v1"
LAWS = ["passive_off", "skyhook_continuous"]


def _smoke(tmp_path, *extra) -> list[str]:
    """The command line of a smoke run: one episode per scenario, serially, no progress bar."""
    return ["benchmark", "--episodes", "1", "--backend", "serial", "--no-progress", "--out", str(tmp_path), *extra]


def test_a_smoke_run_writes_a_result_per_controller_a_leaderboard_and_the_summary(tmp_path, capsys):
    assert main(_smoke(tmp_path / "b", "--suite", CAR, "--only", *LAWS)) == 0
    out = capsys.readouterr().out
    results = sorted((tmp_path / "b" / "results").iterdir())
    assert [p.name for p in results] == [f"{CAR}__{law}.json" for law in LAWS]
    board = tmp_path / "b" / "leaderboards" / CAR
    assert sorted(p.name for p in board.iterdir()) == sorted(
        ["leaderboard.md", "leaderboard.csv", "leaderboard_rows.md", "leaderboard_rows.csv", "leaderboard.png",
         "leaderboard.html"])
    assert (board / "leaderboard.png").stat().st_size > 10_000
    # the summary: one row per suite, the best law (partial: one episode per scenario, 4 of the suite's 31)
    assert f"| {CAR} | 31 | 2 (0) | skyhook_continuous:" in out and "(partial: 4 episodes)" in out
    assert (tmp_path / "b" / "benchmark.md").read_text() in out
    record = json.loads((tmp_path / "b" / "benchmark.json").read_text())
    assert [(c["name"], c["result"], c["complete"]) for c in record["suites"][0]["scored"]] == \
        [(law, f"{CAR}__{law}.json", False) for law in LAWS]
    data = json.loads(results[1].read_text())
    assert data["controller"]["name"] == "skyhook_continuous" and data["complete"] is False
    assert len(data["episodes"]) == len(suite(CAR).scenarios)


def test_the_benchmark_scores_as_score_does_and_reproducibly(tmp_path):
    """Each share is the one ``score`` gives on the same episodes, against the suite's stored references, and a
    second run gives the same shares bit for bit."""
    a = run_benchmark([CAR], only=LAWS, episodes=1, backend="serial", out=tmp_path / "a")
    b = run_benchmark([CAR], only=LAWS, episodes=1, backend="serial")
    direct = score(CAR, "skyhook_continuous", episodes=1)
    got = {s.name: s.result for s in a.suites[0].scored}
    assert [e["share"] for e in got["skyhook_continuous"].episodes] == [e["share"] for e in direct.episodes]
    assert [[e["share"] for e in s.result.episodes] for s in a.suites[0].scored] == \
        [[e["share"] for e in s.result.episodes] for s in b.suites[0].scored]
    # physics: the fixed passive-off damper captures nothing on the bump, where skyhook captures a part
    bump = {name: r.shares()["bump 5 cm"][0] for name, r in got.items()}
    assert bump["skyhook_continuous"] > bump["passive_off"]
    assert all(s.wall_s > 0 and len(s.load) == 2 for s in a.suites[0].scored)
    assert b.suites[0].leaderboard is None and a.suites[0].leaderboard == tmp_path / "a" / "leaderboards" / CAR


def test_a_python_controller_of_the_user_is_scored_beside_the_shipped_ones(tmp_path):
    """A controller object of the user's (run in the caller's process) under the name given; a shipped law given
    again as the user's is scored once."""
    class Off:  # the lowest command, always (the vector environment's space: one row per episode)
        def __init__(self, env):
            self.low = np.asarray(env.action_space.low, dtype=np.float32)

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return self.low.copy(), state

    bench = run_benchmark([CAR], {"mine": Off, "passive_off": "passive_off"}, only=["passive_off"], episodes=1,
                          backend="serial")
    scored = {s.name: s for s in bench.suites[0].scored}
    assert sorted(scored) == ["mine", "passive_off"] and not scored["mine"].shipped
    # the lowest command is passive-off: the same returns
    assert [e["return"] for e in scored["mine"].result.episodes] == \
        [e["return"] for e in scored["passive_off"].result.episodes]
    assert "yours" in bench.summary_rows()[0]


def test_what_does_not_fit_a_suite_is_listed_with_the_reason(tmp_path):
    """An agent trained with road preview on the plain suite, the neural inverse's law on the six-storey building
    (its inverse is of the three-storey model): listed, not scored; the preview agent fits the preview suite. Each
    suite gets its own leaderboard (a leaderboard's bounds are per suite)."""
    plain = run_benchmark([CAR, "car-preview-v1"], only=["passive_off", "quarter_car_cmaes_preview"], episodes=1,
                          backend="serial", out=tmp_path)
    assert sorted(p.name for p in (tmp_path / "leaderboards").iterdir()) == sorted([CAR, "car-preview-v1"])
    on = {e.suite.id: e for e in plain.suites}
    assert [n for n, _ in on[CAR].not_applicable] == ["quarter_car_cmaes_preview"]
    assert "preview" in on[CAR].not_applicable[0][1]
    assert [s.name for s in on["car-preview-v1"].scored] == ["passive_off", "quarter_car_cmaes_preview"]
    six = run_benchmark(["building-six-storey-v1"], only=["passive_off", "clipped_optimal+neural"], episodes=1,
                        backend="serial")
    assert [n for n, _ in six.suites[0].not_applicable] == ["clipped_optimal+neural"]


def test_the_shipped_controllers_of_a_suite_are_its_plants_laws_mpc_rows_and_agents():
    """The MPC rows at the suite's control step, a preview row only where the suite grants preview, each label once;
    the agents trained on the suite's environment."""
    for sid in ("car-comfort-v1", "car-preview-v1", "building-seismic-v1"):
        s = suite(sid)
        rows = shipped_controllers(s)
        names = [r["name"] for r in rows]
        assert len(names) == len(set(names)), sid
        assert set(profile(s.plant).laws) <= set(names)
        mpc = [r["name"] for r in rows if r["controller"] == "mpc"]
        assert mpc and all(("preview" in m) == ("road_preview" in s.options.get("sensors", ())) for m in mpc), sid
    assert any(r["name"] == "quarter_car_cmaes" for r in shipped_controllers(suite(CAR)))
    assert not any(r["name"].startswith("quarter_car") for r in shipped_controllers(suite("building-seismic-v1")))


def test_plant_options_choose_the_suites_of_the_plant_they_describe(tmp_path, capsys):
    assert main(_smoke(tmp_path / "b", "--plant", "shear_building", "--storeys", "6", "--only", "passive_off")) == 0
    assert [p.name for p in (tmp_path / "b" / "results").iterdir()] == ["building-six-storey-v1__passive_off.json"]


@pytest.mark.parametrize("argv, message", [
    (["--suite", "car-nowhere-v1"], "car-nowhere"),
    (["--suite", "building-six-storey-v1", "--no-shipped", "--controller", "quarter_car_cmaes"],
     "agent quarter_car_cmaes: trained on mrd_env/QuarterCarPhysical-v0"),
    (["--suite", CAR, "--suite", "building-six-storey-v1", "--no-shipped", "--controller", "quarter_car_cmaes_preview"],
     "controller 'quarter_car_cmaes_preview' fits none of the chosen suites (car-comfort-v1: agent"),
    (["--suite", CAR, "--controller", "no_such_law"], "no_such_law"),
    (["--suite", CAR, "--only", "no_such_law"], "only: 'no_such_law' is none of the shipped controllers"),
    (["--suite", CAR, "--no-shipped"], "--no-shipped leaves nothing to score"),
    (["--suite", CAR, "--suite", CAR], "given twice"),
    (["--plant", "quarter_car", "--storeys", "6"], "--storeys"),
    (["--suite", CAR, "--episodes", "0"], "--episodes"),
])
def test_the_users_errors_are_one_line_and_write_nothing(tmp_path, capsys, argv, message):
    out = tmp_path / "never"
    assert main(_smoke(out, *argv)) == 2
    err = capsys.readouterr().err
    assert err.startswith("mrd-env benchmark: error: ") and err.count("\n") == 1 and message in err, err
    assert not out.exists()


def test_an_out_that_is_a_file_is_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(_smoke(blocker / "sub", "--suite", CAR, "--only", "passive_off")) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is a file" in err and err.count("\n") == 1


@pytest.mark.parametrize("command", ["evaluate", "yardstick"])
def test_the_folded_commands_answer_one_line_naming_the_benchmark(command, capsys):
    assert main([command, "--plant", "quarter_car"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mrd-env {command}: error: mrd-env {command} was folded into the suites' benchmark")
    assert "mrd-env benchmark" in err and err.count("\n") == 1


# ---------------------------------------------------------------------------------------------- the evaluation loop


def short_building():
    return Scenario("El Centro 1.5 s", "mrd_env/ShearBuildingPhysical-v0",
                    dict(ground_motion="el_centro", ground_motion_params={"time_scale": 0.2}, episode_seconds=1.5))


def test_a_damper_in_the_loop_cuts_the_peak_drift_of_the_uncontrolled_building():
    """J1-J4 are ratios to the uncontrolled building: every damper setting stays within (0, 2), and each cuts the
    peak drift (J1 < 1); the same episode twice gives the same metrics."""
    sensors = ("abs_acc", "drift", "damper_force", "damper_velocity", "ground_acc")
    for law in ("passive_off", "passive_on", "clipped_optimal"):
        a, b = (evaluate_batch(lambda v, n=law: make_controller(n, v), short_building(), "drift", sensors=sensors)[0]
                for _ in range(2))
        assert a.metrics == b.metrics and np.array_equal(a.response, b.response), law
        assert all(0.0 < a.metrics[k] < 2.0 for k in ("J1", "J2", "J4")), (law, a.metrics)
        assert a.metrics["J1"] < 1.0, law


def test_controller_on_env_without_needed_sensors_raises():
    env = gym.make("mrd_env/QuarterCarPhysical-v0", episode_seconds=0.5, sensors=("sprung_acc", "travel"))
    with pytest.raises(ValueError, match="sprung_vel"):
        SkyhookOnOff(env)
    env_b = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=("abs_acc", "ground_acc"), episode_seconds=0.5)
    with pytest.raises(ValueError, match="damper_force"):
        ClippedOptimal(env_b)


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
    """The batched evaluation (one vector env, one row per seed) gives each seed the metrics and return of a scalar
    episode with that seed."""
    sc = Scenario("KT", "mrd_env/ShearBuildingPhysical-v0", dict(ground_motion="kanai_tajimi", episode_seconds=0.6),
                  seeds=(4, 5, 6))
    sensors = ("abs_acc", "drift", "damper_force", "damper_velocity", "ground_acc")
    batch = evaluate_batch(lambda v: make_controller("clipped_optimal", v), sc, "drift", sensors=sensors)
    for seed, ep in zip(sc.seeds, batch):
        env = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=sensors, **sc.options)
        single = evaluate(make_controller("clipped_optimal", env), env, seed, "drift")
        assert ep.metrics == single.metrics and ep.episode_return == single.episode_return
