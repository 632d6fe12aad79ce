"""What a controller author meets when scoring (issue 49, items 2, 3, 5, 6): the pool from a script without a main
guard (one clear error, no worker started), actions outside the suite's action space refused rather than clipped,
the roles table of docs/your-controller.md checked against every plant, ``score --help`` listing the laws, the
errors for a missing folder, ``mylaws.Class`` and ``--out`` naming a file, and a plain SB3 ``model.zip`` scored
with ``--trust-agent`` (the docs' recipe)."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from experiments.cli import main
from experiments.benchmark.scoring import score
from mrd_env.suites import Reference, Suite, SuiteScenario, write_suite

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "your-controller.md"
CAR = "mrd_env/QuarterCarPhysical-v0"
NAMES = ("ISO-C", "ISO-C again", "ISO-C thrice")


@pytest.fixture(scope="module")
def suite_file(tmp_path_factory) -> Path:
    """Three scenarios of 0.2 s car episodes at 10 ms (one seed each), references set by hand (shares are not the
    point here)."""
    road = {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}}
    suite = Suite(name="tiny-user", version=1, plant="quarter_car", env_id=CAR, description="tests",
                  options={"episode_seconds": 0.2}, control_dt=0.01,
                  scenarios=tuple(SuiteScenario(n, road, (k,)) for k, n in enumerate(NAMES)),
                  criteria=("acc_weighted_rms",), references={n: Reference(-0.2, 0.0, -0.1) for n in NAMES})
    return write_suite(suite, tmp_path_factory.mktemp("suite") / "tiny-user-v1.json")


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


# --------------------------------------------------------------------------------- item 2: the pool's main guard


def test_the_pool_from_an_unguarded_script_is_one_clear_error_and_starts_no_worker(suite_file, tmp_path):
    """A script that calls ``score(..., backend="pool")`` at its top level: before, each spawned worker re-ran the
    script and the score ended in a ``BrokenProcessPool`` traceback; now it is refused before any worker starts
    (the script ran once), and ``backend="auto"`` from the same script stays in the process."""
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent(f"""
        print("RAN", flush=True)
        from mrd_env.executor import Task, run_tasks
        from experiments.benchmark.scoring import score
        print("AUTO", run_tasks([Task(abs, (-1,)), Task(abs, (-2,))], backend="auto", jobs=2, progress=False))
        score({str(suite_file)!r}, "skyhook_on_off", backend="pool", jobs=2)
        print("SCORED")
    """))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=_env(), cwd=tmp_path,
                         timeout=300)
    assert out.returncode != 0
    assert out.stdout.count("RAN") == 1, out.stdout  # no worker re-ran the script
    assert "AUTO [1, 2]" in out.stdout and "SCORED" not in out.stdout
    assert "BrokenProcessPool" not in out.stderr
    last = out.stderr.strip().splitlines()[-1]
    assert "UnguardedMain" in last and 'if __name__ == "__main__":' in last and 'backend="serial"' in last
    assert f"{script}:6" in last  # the unguarded call's line


def test_the_pool_from_a_guarded_script_scores(suite_file, tmp_path):
    script = tmp_path / "guarded.py"
    script.write_text(textwrap.dedent(f"""
        from experiments.benchmark.scoring import score

        if __name__ == "__main__":
            r = score({str(suite_file)!r}, "skyhook_on_off", backend="pool", jobs=2)
            print("SCORED", len(r.episodes))
    """))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=_env(), cwd=tmp_path,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert "SCORED 3" in out.stdout


def test_auto_scores_in_process_what_a_pool_would_not_earn_back(suite_file, monkeypatch):
    """``backend="auto"`` (the default): the tiny suite's other scenarios are not worth a pool (no pool is made);
    with the threshold at zero they go to the pool."""
    import mrd_env.executor as executor

    used = []
    real = executor.run_tasks

    def spy(tasks, **kw):
        used.append(kw.get("backend"))
        return real(tasks, **{**kw, "backend": "serial"})

    monkeypatch.setattr(executor, "run_tasks", spy)
    monkeypatch.setattr(executor, "unguarded_main", lambda: None)
    serial = score(suite_file, "skyhook_on_off")
    assert used == ["serial", "serial"]
    used.clear()
    monkeypatch.setattr("experiments.benchmark.scoring.POOL_MIN_SECONDS", 0.0)
    assert score(suite_file, "skyhook_on_off", jobs=2).episodes == serial.episodes
    assert used == ["serial", "pool"]


# --------------------------------------------------------------------------------- item 3: actions out of range

USER = textwrap.dedent('''
    import numpy as np


    class Newtons:
        """Returns a force (N) where the suite takes a command (V)."""

        def __init__(self, env):
            self.nd = env.n_dampers

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return np.full((len(observation), self.nd), 800.0), state


    class Normalised:
        """Returns [-1, 1] actions on a physical (0-2 V) suite."""

        def __init__(self, env):
            self.nd = env.n_dampers

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return np.full((len(observation), self.nd), -1.0), state


    class AtTheBounds:
        """The bounds, a rounding error beyond them: inside."""

        def __init__(self, env):
            self.low = env.single_action_space.low.astype(float) - 1e-9
            self.high = env.single_action_space.high.astype(float) + 1e-9

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            on = observation[:, :1] > 0
            return np.where(on, self.high, self.low), state
''')


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    (tmp_path / "score_user_actions.py").write_text(USER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    yield "score_user_actions"
    sys.modules.pop("score_user_actions", None)


@pytest.mark.parametrize("cls, low, high", [("Newtons", 800, 800), ("Normalised", -1, -1)])
def test_an_action_outside_the_space_is_refused_with_the_range_and_unit(cls, low, high, suite_file, user_module):
    with pytest.raises(ValueError) as err:
        score(suite_file, f"{user_module}:{cls}", backend="serial")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"controller {user_module}:{cls}: predict returned actions")
    assert f"from {low:g} to" in msg and f"to {high:g};" in msg
    assert "takes 0 to 2 V" in msg  # the suite's range and unit


def test_the_command_line_refuses_it_in_one_line_and_writes_nothing(suite_file, user_module, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["score", "--suite", str(suite_file), "--controller", f"{user_module}:Newtons", "--out", str(out),
                 "--no-progress", "--backend", "serial"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "takes 0 to 2 V" in err
    assert not list(out.glob("*.json"))


def test_a_rounding_error_beyond_the_bounds_is_inside(suite_file, user_module):
    assert len(score(suite_file, f"{user_module}:AtTheBounds", backend="serial").episodes) == 3


def test_normalised_and_force_modes_name_their_units():
    import gymnasium as gym

    import mrd_env  # noqa: F401
    from experiments.benchmark.scoring import action_unit

    for mode, unit in (("physical", "V"), ("normalized", "normalised"), ("force", "N")):
        env = gym.make_vec(CAR, num_envs=1, vectorization_mode="vector_entry_point", action_mode=mode)
        assert unit in action_unit(env)
        env.close()


# --------------------------------------------------------------------------------- item 5: what an author must guess


def _doc_roles() -> list[list[str]]:
    text = DOC.read_text(encoding="utf-8")
    block = text.split("<!-- roles table: checked by tests/experiments/test_score_user.py -->")[1]
    block = block.split("<!-- end of the roles table -->")[0]
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in block.strip().splitlines()]
    return [r for r in rows[2:]]  # past the header and its rule


def test_the_roles_table_is_every_plants_roles():
    """docs/your-controller.md's roles table, row for row, is what each plant's environment declares: role → sensor,
    its unit, one value per damper (a stale row, a missing role or plant fails here)."""
    import gymnasium as gym

    import mrd_env  # noqa: F401
    from mrd_env.plants import plants

    actual = {}
    for name, spec in plants().items():
        env = gym.make(spec.physics_id).unwrapped
        roles, nd = env.roles, env.n_dampers
        env = gym.make(spec.physics_id, sensors=list(dict.fromkeys(roles.values()))).unwrapped
        layout = {n: (sl.stop - sl.start, unit) for n, sl, unit in env.sensor_layout}
        for role, sensor in roles.items():
            width, unit = layout[sensor]
            assert width == nd, f"{name}: {sensor} has {width} values, the doc says one per damper ({nd})"
            actual[(name, role)] = (sensor, unit)
    doc = {(r[0], r[1]): (r[2], r[4]) for r in _doc_roles()}
    assert all(r[3] for r in _doc_roles()), "every row says what its sensor measures"
    expected = "\n".join(f"| {p} | {r} | {s} | ... | {u} |" for (p, r), (s, u) in actual.items())
    assert doc == actual, f"docs/your-controller.md's roles table should be:\n{expected}"


def test_score_help_lists_the_registered_laws(capsys):
    from controllers import available_controllers

    assert main(["score", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for law in available_controllers():
        assert re.search(rf"[(\s]{re.escape(law)}[,)]", text), law


def _one_line_error(argv, capsys) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_a_missing_agent_folder_is_no_such_folder(suite_file, tmp_path, capsys):
    err = _one_line_error(["score", "--suite", str(suite_file), "--controller", "results/agents/mine/best", "--out",
                           str(tmp_path / "out")], capsys)
    assert "results/agents/mine/best" in err and "no such folder" in err
    assert not (tmp_path / "out").exists()


def test_a_dotted_name_of_a_module_here_is_did_you_mean_with_a_colon(suite_file, tmp_path, monkeypatch, capsys):
    """``mylaws.MySkyhook`` where ``mylaws.py`` is in the current folder: "did you mean mylaws:MySkyhook" — found
    without importing it (its import would write a file)."""
    marker = tmp_path / "imported"
    (tmp_path / "score_dotted_laws.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    err = _one_line_error(["score", "--suite", str(suite_file), "--controller", "score_dotted_laws.MySkyhook"],
                          capsys)
    assert "did you mean score_dotted_laws:MySkyhook?" in err
    assert not marker.exists() and "score_dotted_laws" not in sys.modules
    err = _one_line_error(["score", "--suite", str(suite_file), "--controller", "no_such_module_here.Law"], capsys)
    assert "did you mean" not in err and "colon" in err


def test_out_naming_a_file_is_one_line_naming_out(suite_file, tmp_path, capsys):
    afile = tmp_path / "result.json"
    afile.write_text("{}")
    for out in (afile, afile / "sub"):
        err = _one_line_error(["score", "--suite", str(suite_file), "--controller", "skyhook_on_off", "--out",
                               str(out), "--backend", "serial"], capsys)
        assert err.startswith("mrd-env score: error: --out ") and "not a folder" in err and "Errno" not in err
    assert afile.read_text() == "{}"


# --------------------------------------------------------------------------------- item 6: a plain SB3 model.zip


def _doc_block(lang: str, after: str) -> str:
    text = DOC.read_text(encoding="utf-8")
    section = text.split(after, 1)[1]
    return section.split(f"```{lang}\n", 1)[1].split("```", 1)[0]


@pytest.mark.slow  # a PPO training and a pool score (14 s); the zip's refusal is tested below in CI
def test_the_docs_sb3_recipe_trains_saves_and_scores_a_model_zip(tmp_path):
    """The recipe of docs/your-controller.md, run as written but for the training's length (a few hundred steps):
    PPO on QuarterCar-v1, ``model.save("model.zip")``, then ``mrd-env score --controller model.zip --trust-agent``
    with ``--episodes 1``. Without ``--trust-agent`` the zip is refused in one line, nothing written."""
    pytest.importorskip("stable_baselines3")
    heading = "## Score your own Stable-Baselines3 model"
    code = _doc_block("py", heading)  # "py": the page's one "python" block is test_score.py's
    assert "torch.set_num_threads(1)" in code and 'model.save("model.zip")' in code
    code = re.sub(r"total_timesteps=[\d_]+", "total_timesteps=256", code)
    code = code.replace('PPO("MlpPolicy", env,', 'PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1,')
    subprocess.run([sys.executable, "-c", code], check=True, env=_env(), cwd=tmp_path, timeout=600)
    assert (tmp_path / "model.zip").is_file()
    command = _doc_block("bash", heading).split()
    assert command[:2] == ["mrd-env", "score"] and "--trust-agent" in command
    argv = [*command[1:], "--episodes", "1", "--no-progress"]
    cli = [sys.executable, "-m", "experiments.cli"]
    refused = subprocess.run([*cli, *[a for a in argv if a != "--trust-agent"]], capture_output=True, text=True,
                             env=_env(), cwd=tmp_path, timeout=300)
    assert refused.returncode == 2 and "--trust-agent" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1 and not (tmp_path / "results").exists()
    out = subprocess.run([*cli, *argv], capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    (result,) = (tmp_path / "results" / "score").glob("*.json")
    data = json.loads(result.read_text())
    assert data["controller"]["kind"] == "agent" and data["controller"]["spec"] == "model.zip"
    assert data["controller"]["action_options"] == {"action_mode": "normalized"}
    assert data["suite"]["id"] == "car-comfort-v1" and all(np.isfinite(e["return"]) for e in data["episodes"])


def test_a_zip_that_does_not_fit_the_suite_is_refused_in_one_line(tmp_path, capsys):
    """A model trained on the quarter car's observations, scored on the building's suite: its observation shape."""
    pytest.importorskip("stable_baselines3")
    code = textwrap.dedent("""
        import torch
        torch.set_num_threads(1)
        import gymnasium as gym
        import mrd_env
        from stable_baselines3 import PPO
        PPO("MlpPolicy", gym.make("mrd_env/QuarterCar-v1"), n_steps=64, device="cpu").save("car.zip")
    """)
    subprocess.run([sys.executable, "-c", code], check=True, env=_env(), cwd=tmp_path, timeout=600)
    err = _one_line_error(["score", "--suite", "building-seismic-v1", "--controller", str(tmp_path / "car.zip"),
                           "--trust-agent", "--out", str(tmp_path / "out")], capsys)
    assert "trained on observations of shape (8,)" in err and "building-seismic-v1" in err


def test_a_shipped_agent_is_named_by_its_folder_name_and_rows_carry_the_name_given(tmp_path, monkeypatch):
    """Issue 50, names: ``--controller quarter_car_cmaes`` was refused (the user had to find the folder under
    site-packages), and rows were named from agent.json's free text (``agent CMA-ES s0``). A shipped agent is named
    by its folder's name from any working folder; a row carries the name the user gave, beside kind and digest."""
    from controllers.agents import SHIPPED
    from experiments.benchmark.scoring import controller_spec, result_filename

    monkeypatch.chdir(tmp_path)  # not the repository: the name resolves inside the package
    spec = controller_spec("quarter_car_cmaes")
    assert spec.kind == "agent" and spec.name == "quarter_car_cmaes"
    assert spec.description["spec"] == str(SHIPPED / "quarter_car_cmaes") and len(spec.description["agent_digest"]) == 16
    assert result_filename("car-comfort-v1", spec.name) == "car-comfort-v1__quarter_car_cmaes.json"
    given = str(SHIPPED / "quarter_car_cmaes")
    assert controller_spec(given).name == given
    assert controller_spec("quarter_car_cmaes", name="mine").name == "mine"
    with pytest.raises(ValueError, match="did you mean quarter_car_cmaes"):
        controller_spec("quarter_car_cmae")


def test_the_benchmarks_public_api_is_one_module_the_docs_use():
    """Issue 50, one public API: ``experiments.benchmark`` holds suite reading, scoring, results and leaderboards;
    the README and docs/your-controller.md import it, not the internal modules."""
    from pathlib import Path

    import experiments.benchmark as api
    from experiments.benchmark import ranking as leaderboard, scoring
    from mrd_env import suites

    assert api.score is scoring.score and api.leaderboards is leaderboard.leaderboards and api.suite is suites.suite
    assert all(hasattr(api, name) for name in api.__all__)
    root = Path(__file__).resolve().parents[2]
    for page in ("README.md", "docs/your-controller.md"):
        text = (root / page).read_text(encoding="utf-8")
        assert "experiments.benchmark" in text and "from experiments.common." not in text, page
