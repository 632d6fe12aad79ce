"""``mrd-env score`` and ``mrd-env leaderboard`` (issue 39, item 2): a registered law, a Python ``module:attribute``
controller and an agent scored on a tiny suite against its stored references (one episode's computed by the
yardstick on a 0.2 s episode, the others set by hand); the share arithmetic by hand; result files written
atomically, read back, merged into one table and one figure; results of another suite version or digest refused;
one-line errors; the docs page's example runs."""
from __future__ import annotations

import json
import math
import re
import shutil
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controllers.protocol import ControllerProtocol, build_controller, import_object
from experiments.cli import main
from experiments.benchmark.ranking import leaderboard, read_result
from experiments.benchmark.scoring import score
from mrd_env.suites import Reference, Suite, SuiteScenario, read_suite, write_suite

ROOT = Path(__file__).resolve().parents[2]
CAR = "mrd_env/QuarterCarPhysical-v0"
#: A module of the user's, importable as ``score_user_laws:...`` once its folder is on the path.
USER_LAWS = textwrap.dedent('''
    import numpy as np

    from mrd_env.envs.sensors import newest_layout


    class MySkyhook:
        def __init__(self, env):
            where = newest_layout(env)
            self.body = where[env.roles["body_velocity"]]
            self.rate = where[env.roles["damper_velocity"]]
            self.low, self.high = env.single_action_space.low, env.single_action_space.high

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            on = observation[:, self.body] * observation[:, self.rate] >= 0
            return np.where(on, self.high, self.low), state


    def make(env):
        return MySkyhook(env)


    class Wrong:
        def __init__(self, env):
            pass

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return np.zeros((3, 7)), state


    class Buggy(Wrong):
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return observation[:, 99], state
''')


def _road(road_class: str) -> dict:
    return {"road": "iso8608", "road_params": {"road_class": road_class, "speed": 20.0}}


def tiny(references: dict, version: int = 1) -> Suite:
    """Two scenarios of 0.2 s car episodes at 10 ms: ISO-C with two seeds, ISO-D with one."""
    return Suite(name="tiny-car", version=version, plant="quarter_car", env_id=CAR,
                 description="two tiny scenarios for the tests", options={"episode_seconds": 0.2}, control_dt=0.01,
                 scenarios=(SuiteScenario("ISO-C", _road("C"), (1, 2)), SuiteScenario("ISO-D", _road("D"), (3,))),
                 criteria=("acc_weighted_rms", "travel_peak"), references=references)


#: Hand-set references of the ISO-C episodes (returns of 0.2 s car episodes: the share's arithmetic needs no more).
HAND_SET = {"ISO-C s1": Reference(-0.20, 0.0, -0.12), "ISO-C s2": Reference(-0.19, 0.0, -0.16)}


@pytest.fixture(scope="module")
def suite_file(tmp_path_factory) -> Path:
    """The tiny suite: the ISO-D episode's references computed by the yardstick (best constant command, clairvoyant;
    no bound), the ISO-C ones set by hand."""
    from experiments.common.scenarios import Scenario
    from experiments.benchmark.yardstick import episode_yardstick

    sc = tiny({}).scenarios[1]
    y = episode_yardstick(Scenario(sc.name, CAR, {"episode_seconds": 0.2, **sc.options}, sc.seeds), sc.seeds[0],
                          ("passive_off", "passive_on"), bound=False, cache=False)
    assert y.passive < y.clairvoyant
    refs = {**HAND_SET, "ISO-D": Reference(y.passive, float(y.passive_command), y.clairvoyant)}
    return write_suite(tiny(refs), tmp_path_factory.mktemp("suite") / "tiny-car-v1.json")


@pytest.fixture
def user_laws(tmp_path, monkeypatch):
    (tmp_path / "score_user_laws.py").write_text(USER_LAWS)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "score_user_laws"
    import sys
    sys.modules.pop("score_user_laws", None)


def stand_in_agent(folder: Path, control_dt: float = 0.01) -> Path:
    """A tiny CMA-ES network (8 → 4 → 1, fixed weights) saved in the code-free format, trained 'normalized'."""
    from controllers.agents import ObservationNormalizer, save_agent
    from controllers.mlp_policy import MLPPolicy

    sizes = (8, 4, 1)
    theta = np.random.default_rng(0).normal(0.0, 0.5, MLPPolicy(sizes).n_params)
    meta = {"plant": "quarter_car", "env_id": CAR, "algo": "CMA-ES", "name": "tiny CMA-ES",
            "env_kwargs": {"control_dt": control_dt, "action_mode": "normalized", "episode_seconds": 0.2}}
    return save_agent(folder, meta, policy=MLPPolicy(sizes, theta),
                      normalizer=ObservationNormalizer(np.zeros(8), np.full(8, 0.1)))


@pytest.fixture(scope="module")
def scored(suite_file, tmp_path_factory):
    """The law, a Python controller and the agent scored on the tiny suite, their result files written."""
    import sys

    folder = tmp_path_factory.mktemp("scored")
    (folder / "score_user_laws.py").write_text(USER_LAWS)
    sys.path.insert(0, str(folder))
    try:
        results = {"law": score(suite_file, "skyhook_on_off"),
                   "python": score(suite_file, "score_user_laws:MySkyhook"),
                   "agent": score(suite_file, stand_in_agent(folder / "agent"))}
    finally:
        sys.path.remove(str(folder))
        sys.modules.pop("score_user_laws", None)
    paths = {k: r.write(folder / f"{k}.json") for k, r in results.items()}
    return results, paths, folder


# --------------------------------------------------------------------------------------------- scoring


def test_a_law_is_scored_against_the_stored_references_by_hand(suite_file, scored):
    from experiments.common.evaluation import controller_episodes
    from experiments.common.scenarios import Scenario

    r = scored[0]["law"]
    stored = json.loads(suite_file.read_text())["references"]
    assert [e["label"] for e in r.episodes] == ["ISO-C s1", "ISO-C s2", "ISO-D"]
    for e in r.episodes:
        ref = stored[e["label"]]
        assert e["share"] == pytest.approx((e["return"] - ref["passive"]) / (ref["clairvoyant"] - ref["passive"]),
                                           rel=1e-12)
        assert set(e["criteria"]) >= {"acc_weighted_rms", "travel_peak"} and e["terminated"] is None
    # the episodes are the suite's: its options and seeds, at its control step
    eps = controller_episodes("skyhook_on_off", Scenario("ISO-C", CAR, {"episode_seconds": 0.2, **_road("C")}, (1, 2)),
                              control_dt=0.01)
    assert [e["return"] for e in r.episodes[:2]] == [e.episode_return for e in eps]
    # per scenario: mean and 95 % interval over its episodes (none for one episode); then over all
    rows = {row["scenario"]: row for row in r.summary()}
    c = [e["share"] for e in r.episodes[:2]]
    assert rows["ISO-C"]["share"] == pytest.approx(np.mean(c)) and rows["ISO-C"]["episodes"] == 2
    assert rows["ISO-C"]["share lo95"] < rows["ISO-C"]["share"] < rows["ISO-C"]["share hi95"]
    assert math.isnan(rows["ISO-D"]["share lo95"]) and rows["ISO-D"]["share"] == r.episodes[2]["share"]
    assert rows["all scenarios"]["episodes"] == 3
    assert rows["all scenarios"]["share"] == pytest.approx(np.mean([e["share"] for e in r.episodes]))
    assert r.units["acc_weighted_rms"] == "m/s²" and r.complete
    assert "share" in r.markdown() and "acc_weighted_rms (m/s²)" in r.markdown()


def test_a_python_controller_acts_as_the_law_it_writes_and_is_described(scored):
    law, mine = scored[0]["law"], scored[0]["python"]
    assert [e["return"] for e in mine.episodes] == [e["return"] for e in law.episodes]
    assert mine.controller["kind"] == "python" and mine.controller["name"] == "score_user_laws:MySkyhook"
    assert re.fullmatch(r"[0-9a-f]{64}", mine.controller["source_sha256"])


def test_factories_objects_and_classes_are_controllers(suite_file, user_laws):
    """A factory, an object with predict, a class passed from Python: the same episodes."""
    import gymnasium as gym

    mod = import_object(f"{user_laws}:make").__module__
    import sys
    laws = sys.modules[mod]
    venv = gym.make_vec(CAR, num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(build_controller(laws.make, venv), ControllerProtocol)
    obj = laws.MySkyhook(venv)
    assert build_controller(obj, venv) is obj
    with pytest.raises(ValueError, match="neither a controller"):
        build_controller(3, venv)
    with pytest.raises(ValueError, match="no predict"):
        build_controller(lambda env: object(), venv)
    venv.close()
    a = score(suite_file, f"{user_laws}:make", episodes=1)
    b = score(suite_file, laws.MySkyhook, episodes=1, name="mine")
    assert [e["return"] for e in a.episodes] == [e["return"] for e in b.episodes]
    assert b.name == "mine" and not b.complete and len(b.episodes) == 2     # the first seed of each scenario


def test_an_agent_is_scored_in_the_suites_environment_with_its_own_action_mode(scored, tmp_path, suite_file):
    from controllers.agents import agent_digest
    from experiments.common.evaluation import controller_episodes
    from experiments.common.scenarios import Scenario

    results, _, folder = scored
    r = results["agent"]
    assert r.controller["kind"] == "agent" and r.controller["agent_digest"] == agent_digest(folder / "agent")
    assert r.controller["action_options"] == {"action_mode": "normalized"}
    eps = controller_episodes(folder / "agent", Scenario("ISO-D", CAR, {"episode_seconds": 0.2, **_road("D")}, (3,)))
    assert r.episodes[2]["return"] == eps[0].episode_return
    # an agent trained at another control step does not fit the suite: one line, before any episode
    with pytest.raises(ValueError, match="trained at 0.001 s"):
        score(suite_file, stand_in_agent(tmp_path / "fast", control_dt=0.001))


def test_a_suite_without_a_reference_for_an_episode_is_refused(suite_file, tmp_path):
    s = read_suite(suite_file)
    refs = dict(s.references)
    refs.pop("ISO-D")
    path = write_suite(replace(s, references=refs), tmp_path / "holed.json")
    with pytest.raises(ValueError, match=r"no reference for the episode\(s\) \['ISO-D'\]"):
        score(path, "passive_off")


# --------------------------------------------------------------------------------------------- result files


def test_the_result_file_round_trips(scored):
    results, paths, _ = scored
    data = json.loads(paths["law"].read_text())
    assert data["format"] == "mrd-env-score" and data["suite"]["id"] == "tiny-car-v1"
    assert data["suite"]["digest"] == results["law"].suite["digest"] and data["controller"]["kind"] == "law"
    back = read_result(paths["law"])
    assert back.episodes == results["law"].episodes and back.controller == results["law"].controller
    assert back.to_json() == data == results["law"].to_json()     # summary, NaNs (null) and all


def test_the_result_file_is_written_atomically(scored, tmp_path, monkeypatch):
    results, paths, _ = scored
    target = shutil.copy(paths["law"], tmp_path / "r.json")
    before = Path(target).read_bytes()

    def fail(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr("mrd_env.storage.os.replace", fail)
    with pytest.raises(OSError):
        results["python"].write(target)
    assert Path(target).read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


# --------------------------------------------------------------------------------------------- leaderboard


def test_leaderboard_merges_three_results_into_a_table_and_a_figure(scored, tmp_path):
    _, paths, _ = scored
    board = leaderboard([paths["law"], paths["python"], paths["agent"]], out=tmp_path / "board")
    assert [r["rank"] for r in board.table] == [1, 2, 3]
    # the kind, with the digest of what was scored where the result records one (issue 50: name, kind and digest)
    assert {r["kind"].split()[0] for r in board.table} == {"law", "python", "agent"}
    assert {r["kind"] for r in board.table if r["kind"] != "law"} == {
        f"agent {read_result(paths['agent']).controller['agent_digest'][:12]}",
        f"python {read_result(paths['python']).controller['source_sha256'][:12]}"}
    shares = [read_result(p).pooled_shares()["all scenarios"][0] for p in paths.values()]   # ranked by the pooled
    assert [r["all scenarios"].split()[0] for r in board.table] == [f"{s:.3f}" for s in sorted(shares, reverse=True)]
    assert set(board.table[0]) >= {"controller", "episodes", "all scenarios", "ISO-C", "ISO-D"}
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard_rows.csv", "leaderboard.png"):
        assert (tmp_path / "board" / name).stat().st_size > 0
    assert (tmp_path / "board" / "leaderboard.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_leaderboard_refuses_another_suite_version_and_another_digest(scored, suite_file, tmp_path, capsys):
    _, paths, _ = scored
    # version 2 of the suite (the same episodes and references): scored for real, then refused beside version 1
    v2 = write_suite(replace(read_suite(suite_file), version=2), tmp_path / "tiny-car-v2.json")
    other = score(v2, "passive_off", episodes=1).write(tmp_path / "v2.json")
    with pytest.raises(ValueError, match="scored on suite tiny-car-v2"):
        leaderboard([paths["law"], other])
    # the same version with another digest (other reference values)
    data = json.loads(paths["python"].read_text())
    data["suite"]["digest"] = "0" * 64
    forged = tmp_path / "forged.json"
    forged.write_text(json.dumps(data))
    # the command line groups the files by suite: one leaderboard per suite version, each checked against its file
    code = main(["leaderboard", str(paths["law"]), str(other), "--suite", str(suite_file), "--suite", str(v2),
                 "--out", str(tmp_path / "both")])
    capsys.readouterr()
    assert code == 0 and sorted(f.name for f in (tmp_path / "both").iterdir()) == ["tiny-car-v1", "tiny-car-v2"]
    code = main(["leaderboard", str(paths["law"]), str(forged), "--suite", str(suite_file), "--out",
                 str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2 and err.startswith("mrd-env leaderboard: error: result file ") and err.count("\n") == 1, err
    assert "not merged" in err
    assert not (tmp_path / "out").exists()      # refused before anything is written
    # not a result, another format version, a malformed episode
    for edit, message in ((lambda d: d.update(format="x"), "not a result"),
                          (lambda d: d.update(format_version=9), "format version 9"),
                          (lambda d: d["episodes"][0].update(share="high"), "episode 0")):
        data = json.loads(paths["law"].read_text())
        edit(data)
        forged.write_text(json.dumps(data))
        with pytest.raises(ValueError, match=message):
            read_result(forged)


# --------------------------------------------------------------------------------------------- the command line


def test_the_command_line_scores_and_merges(suite_file, user_laws, tmp_path, capsys):
    out = tmp_path / "score"
    code = main(["score", "--suite", str(suite_file), "--controller", "passive_off", "--controller",
                 f"{user_laws}:MySkyhook", "--episodes", "1", "--backend", "serial", "--no-progress",
                 "--out", str(out)])
    text, err = capsys.readouterr()
    assert code == 0, err
    files = sorted(out.glob("*.json"))
    assert [f.name for f in files] == ["tiny-car-v1__passive_off.json", "tiny-car-v1__score_user_laws_myskyhook.json"]
    assert "partial: 2 of 3 episodes" in text and (out / "tiny-car-v1__passive_off.md").exists()
    assert read_result(files[0]).command[:2] == ["mrd-env", "score"]
    code = main(["leaderboard", *map(str, files), "--suite", str(suite_file), "--out", str(tmp_path / "board")])
    text, err = capsys.readouterr()
    assert code == 0, err
    # partial results (--episodes 1) are shown apart, never ranked
    assert "nothing is ranked" in text and "| 1 |" not in text and text.count("| partial: 2 of 3 episodes |") == 2


def test_against_compares_on_the_same_episodes(suite_file, tmp_path, capsys):
    """--against: each controller against a reference on the same episodes, from this run or from a result file;
    a controller compared with itself is a tie of exactly 0; passive-on against passive-off is decided."""
    out = tmp_path / "score"
    code = main(["score", "--suite", str(suite_file), "--controller", "passive_on", "--against", "passive_off",
                 "--backend", "serial", "--no-progress", "--out", str(out)])
    text, err = capsys.readouterr()
    assert code == 0, err
    assert "pooled share difference" in text and "episodes won" in text
    off = score(suite_file, "passive_off")
    off.write(tmp_path / "off.json")
    code = main(["score", "--suite", str(suite_file), "--controller", "passive_off", "--against",
                 str(tmp_path / "off.json"), "--backend", "serial", "--no-progress", "--out", str(out)])
    text, err = capsys.readouterr()
    assert code == 0, err
    assert "0.000" in text.split("all scenarios")[-1] and "0/" in text.split("all scenarios")[-1]
    code = main(["score", "--suite", str(suite_file), "--controller", "passive_on", "--against", "nope",
                 "--out", str(tmp_path / "refused")])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and not (tmp_path / "refused").exists()


def test_a_law_takes_its_options_from_python_and_the_command_line(suite_file, tmp_path, capsys):
    """The options reach the law: MPC of horizon 1 with a bound that never binds is the sampled-data LQR, i.e.
    clipped-optimal of the sampled design (tests/controllers/test_mpc.py), so the two score the same returns; with a
    force bound of 10 N, which binds, it does not. The options are recorded in the result file."""
    h1 = score(suite_file, "mpc", options={"horizon": 1, "f_max": 1e7}, name="mpc h1")
    co = score(suite_file, "clipped_optimal", options={"design": "sampled"})
    bound = score(suite_file, "mpc", options={"horizon": 1, "f_max": 10.0})
    assert [e["return"] for e in h1.episodes] == pytest.approx([e["return"] for e in co.episodes], rel=1e-9)
    assert [e["return"] for e in h1.episodes] != pytest.approx([e["return"] for e in bound.episodes], rel=1e-6)
    assert h1.name == "mpc h1" and h1.controller["options"] == {"horizon": 1, "f_max": 1e7}
    assert co.name == 'clipped_optimal {"design": "sampled"}' and "options" not in score(suite_file, "mpc",
                                                                                         episodes=1).controller
    out = tmp_path / "score"
    code = main(["score", "--suite", str(suite_file), "--controller", "mpc", "--law-options",
                 '{"horizon": 1, "f_max": 1e7}', "--name", "mpc h1", "--backend", "serial", "--no-progress",
                 "--out", str(out)])
    _, err = capsys.readouterr()
    assert code == 0, err
    cli = read_result(out / "tiny-car-v1__mpc_h1.json")
    assert cli.controller["options"] == {"horizon": 1, "f_max": 1e7} and cli.name == "mpc h1"
    assert [e["return"] for e in cli.episodes] == [e["return"] for e in h1.episodes]


def test_torch_runs_on_one_thread_only_in_the_projects_own_processes(suite_file, tmp_path, monkeypatch):
    """An agent's episodes in an executor's worker (another process than score's caller) set torch to one thread
    (its default takes every core: an SB3 policy scored 10x slower on 2 loaded cores); in the caller's own process,
    or for a law, nothing is changed."""
    import os

    import torch

    from experiments.benchmark.scoring import controller_spec, scenario_episodes

    calls = []
    monkeypatch.setattr(torch, "set_num_threads", lambda n: calls.append(n))
    suite = read_suite(suite_file)
    agent = controller_spec(stand_in_agent(tmp_path / "agent"))
    law = controller_spec("passive_on")
    scenario_episodes(suite, 1, (3,), agent, caller=os.getpid())
    scenario_episodes(suite, 1, (3,), law, caller=os.getpid() + 1)
    assert calls == []
    eps = scenario_episodes(suite, 1, (3,), agent, caller=os.getpid() + 1)     # as in a worker
    assert calls == [1] and eps[0]["label"] == "ISO-D"


def test_a_users_code_in_a_worker_imports_torch_only_if_it_does_and_then_runs_it_on_one_thread(suite_file, tmp_path):
    """A user's NumPy controller in a worker does not import torch (it cost every pool worker 2-3 s, only to set its
    threads); one whose module imports torch gets it on one thread once built. In a fresh process: the test's own
    has torch imported."""
    import os
    import subprocess
    import sys

    (tmp_path / "np_law.py").write_text(textwrap.dedent('''
        import numpy as np


        class Law:
            def __init__(self, env):
                self.high = env.single_action_space.high

            def predict(self, observation, state=None, episode_start=None, deterministic=True):
                return np.broadcast_to(self.high, (len(observation), self.high.size)).copy(), state
    '''))
    (tmp_path / "torch_law.py").write_text("import torch\n\nfrom np_law import Law  # noqa: F401\n\n"
                                           "torch.set_num_threads(3)\n")
    code = textwrap.dedent(f'''
        import os, sys
        from experiments.benchmark.scoring import controller_spec, scenario_episodes
        from mrd_env.suites import read_suite
        suite = read_suite({str(suite_file)!r})
        scenario_episodes(suite, 1, (3,), controller_spec("np_law:Law"), caller=os.getpid() + 1)
        print("torch" in sys.modules)
        scenario_episodes(suite, 1, (3,), controller_spec("torch_law:Law"), caller=os.getpid() + 1)
        print(sys.modules["torch"].get_num_threads())
    ''')
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(root), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "False\n1\n", proc.stdout


@pytest.mark.parametrize("argv, message", [
    (["--controller", "mpc", "--law-options", "{horizon: 1}"], "--law-options must be a JSON object"),
    (["--controller", "mpc", "--law-options", "[1]"], "--law-options must be a JSON object"),
    (["--controller", "mpc", "--law-options", '{"horizn": 1}'], "controller mpc {\"horizn\": 1}: options"),
    (["--controller", "mpc", "--law-options", '{"horizon": 0}'], "horizon"),
    (["--controller", "mpc", "--controller", "passive_on", "--law-options", "{}"], "applies to one --controller"),
    (["--controller", "mpc", "--controller", "passive_on", "--name", "x"], "applies to one --controller"),
    (["--controller", "{laws}:MySkyhook", "--law-options", '{"a": 1}'], "options are a registered law's"),
])
def test_bad_law_options_are_one_line_and_exit_2(argv, message, suite_file, user_laws, tmp_path, capsys):
    code = main(["score", "--suite", str(suite_file), *(a.replace("{laws}", user_laws) for a in argv),
                 "--backend", "serial", "--no-progress", "--out", str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2 and err.startswith("mrd-env score: error: ") and err.count("\n") == 1, err
    assert message in err, err
    assert not list((tmp_path / "out").glob("*.json"))


@pytest.mark.parametrize("controller, message", [
    ("no_such_package_xyz.laws:Law", "no module named 'no_such_package_xyz'"),
    ("{laws}:Nope", "has no attribute 'Nope'"),
    ("{laws}:Wrong", "predict returned an action of shape (3, 7)"),
    ("{laws}:Buggy", "controller score_user_laws:Buggy: predict raised IndexError"),
    ("not a law", "is none of: a registered law"),
    ("groundhook:", "is none of"),
])
def test_a_bad_controller_is_one_line_and_exit_2(controller, message, suite_file, user_laws, tmp_path, capsys):
    code = main(["score", "--suite", str(suite_file), "--controller", controller.format(laws=user_laws),
                 "--backend", "serial", "--no-progress", "--out", str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2 and err.startswith("mrd-env score: error: ") and err.count("\n") == 1, err
    assert message in err, err
    assert not list((tmp_path / "out").glob("*.json"))


def test_a_module_that_fails_on_import_is_one_line(suite_file, tmp_path, monkeypatch, capsys):
    (tmp_path / "score_broken_laws.py").write_text("raise RuntimeError('boom')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    code = main(["score", "--suite", str(suite_file), "--controller", "score_broken_laws:X",
                 "--out", str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2 and "importing score_broken_laws failed: RuntimeError: boom" in err and err.count("\n") == 1


# --------------------------------------------------------------------------------------------- the docs page


def test_the_docs_example_runs(suite_file, tmp_path, monkeypatch, capsys):
    """docs/your-controller.md's Python block, on the tiny suite in place of car-comfort-v1."""
    import mrd_env.suites

    page = (ROOT / "docs" / "your-controller.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    assert len(blocks) == 1
    lines = [ln for ln in blocks[0].splitlines() if ln.strip()]
    assert len(lines) <= 30, "the example must stay short"
    tiny_suite = read_suite(suite_file)
    shipped = mrd_env.suites.suite
    monkeypatch.setattr(mrd_env.suites, "suite", lambda name: tiny_suite if name == "car-comfort-v1" else shipped(name))
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "docs_example"}
    exec(compile(blocks[0], "docs/your-controller.md", "exec"), namespace)
    text = capsys.readouterr().out
    assert "MySkyhook on tiny-car-v1" in text and "| rank |" in text
    mine = read_result(tmp_path / "results" / "score" / "my_skyhook.json")
    assert mine.controller["kind"] == "python" and mine.complete
    law = score(tiny_suite, "skyhook_on_off")
    assert [e["return"] for e in mine.episodes] == [e["return"] for e in law.episodes]   # the protocol's law
    assert (tmp_path / "results" / "leaderboard" / "leaderboard.png").exists()
