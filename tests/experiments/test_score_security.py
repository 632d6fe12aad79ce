"""``mrd-env score`` with hostile controllers (issue 48, items 7 and 8): SIGTERM stops a score whose controller blocks
in a pool's worker, and no worker is left; a controller's ``sys.exit()`` or ``KeyboardInterrupt`` is its error (one
line, exit 2, nothing written), on the serial and the pool backends; a controller sees the environment's declarations
only (stepping, resetting, the state, the disturbance are refused with one line), and the shipped laws and an agent
drive the view exactly as they drove the environment; plant options with Unicode digits name the option; an error
line quoting a huge value is cut."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from experiments.cli import MAX_ERROR_LINE, main
from mrd_env.suites import Reference, Suite, SuiteScenario, write_suite

ROOT = Path(__file__).resolve().parents[2]
CAR = "mrd_env/QuarterCarPhysical-v0"

#: The user's module of hostile controllers, importable as ``hostile_laws:...`` from the test's folder.
HOSTILE = textwrap.dedent('''
    import os
    import sys
    import time

    import numpy as np

    HERE = os.path.dirname(os.path.abspath(__file__))


    class Fine:
        def __init__(self, env):
            self.high = env.single_action_space.high

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            return np.broadcast_to(self.high, (len(observation), self.high.size)).copy(), state


    class Sleeper(Fine):
        """Blocks in predict, after leaving a mark (its process id) that it got there."""

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            with open(os.path.join(HERE, f"predicting.{os.getpid()}"), "w") as f:
                f.write("x")
            time.sleep(10 ** 6)


    class Exits(Fine):
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            sys.exit(0)


    class Dies(Fine):
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            os._exit(3)


    class ExitsWhenBuilt:
        def __init__(self, env):
            sys.exit(0)


    class Interrupts(Fine):
        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            raise KeyboardInterrupt


    class Steps(Fine):
        def __init__(self, env):
            super().__init__(env)
            self.env = env

        def predict(self, observation, state=None, episode_start=None, deterministic=True):
            self.env.step(np.zeros((len(observation), self.high.size), np.float32))
            return super().predict(observation, state)


    class Resets:
        def __init__(self, env):
            env.reset(seed=0)


    class ReadsTheRoad:
        def __init__(self, env):
            self.road = env.assembly.disturbance


    class Unwraps:
        def __init__(self, env):
            self.core = env.unwrapped.core


    class CallsTheEnvs:
        def __init__(self, env):
            env.call("damper_force")


    class ReadsTheForce:
        def __init__(self, env):
            self.force = env.damper_force


    class Writes:
        def __init__(self, env):
            env.control_dt = 1.0
''')


def tiny_suite(folder: Path) -> Path:
    """Two scenarios of 0.1 s car episodes at 10 ms, references set by hand (scoring solves nothing)."""
    road = {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}}
    suite = Suite(name="hostile-car", version=1, plant="quarter_car", env_id=CAR, description="hostile tests",
                  options={"episode_seconds": 0.1}, control_dt=0.01,
                  scenarios=(SuiteScenario("A", road, (1, 2)), SuiteScenario("B", road, (3,))),
                  criteria=("acc_weighted_rms",),
                  references={"A s1": Reference(-0.2, 0.0, -0.1), "A s2": Reference(-0.2, 0.0, -0.1),
                              "B": Reference(-0.2, 0.0, -0.1)})
    return write_suite(suite, folder / "hostile-car-v1.json")


@pytest.fixture
def hostile(tmp_path, monkeypatch):
    """The tiny suite and the hostile module in ``tmp_path``, which is the current folder (score imports from it)."""
    (tmp_path / "hostile_laws.py").write_text(HOSTILE)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path, tiny_suite(tmp_path)
    sys.modules.pop("hostile_laws", None)


def _session(sid: int) -> list[int]:
    """The processes of session ``sid`` still alive (not zombies), from /proc."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat.rpartition(")")[2].split()  # after "pid (comm)": state, ppid, pgrp, session, ...
        if int(fields[3]) == sid and fields[0] != "Z":
            out.append(int(d.name))
    return out


def _wait_for(predicate, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.1)
    return predicate()


@pytest.mark.hostile
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the processes from /proc")
def test_sigterm_stops_a_score_whose_controller_blocks_in_a_pool_worker(hostile):
    """Was: still running after 596 s (the pool waited for the blocked worker); --backend serial stopped in 0.9 s."""
    folder, suite = hostile
    proc = subprocess.Popen([sys.executable, "-m", "experiments.cli", "score", "--suite", str(suite), "--controller",
                             "hostile_laws:Sleeper", "--backend", "pool", "--jobs", "2", "--no-progress", "--out",
                             str(folder / "out")], cwd=folder, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        # both scenarios' workers block in predict (the check before the run builds, it does not predict)
        assert _wait_for(lambda: len(list(folder.glob("predicting.*"))) == 2, 240), proc.stderr.read1().decode()
        workers = [int(p.suffix[1:]) for p in folder.glob("predicting.*")]
        assert all(w != proc.pid for w in workers)  # they block in the pool's workers, not in the command
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=30)
        took = time.monotonic() - t0
        err = proc.stderr.read().decode()
        assert code == 143, err
        assert took < 10, f"{took:.1f} s to stop"
        assert err.strip().splitlines()[-1] == "mrd-env score: terminated", err
        assert _wait_for(lambda: not _session(proc.pid), 10), f"left running: {_session(proc.pid)}"
        assert not (folder / "out").exists() or not list((folder / "out").glob("*.json"))
    finally:
        for pid in _session(proc.pid):  # whatever the test left (the command's own processes only)
            os.kill(pid, signal.SIGKILL)
        proc.wait()


@pytest.mark.hostile
@pytest.mark.parametrize("backend", ["serial", "pool"])
@pytest.mark.parametrize("controller, what", [("Exits", r"predict raised SystemExit\(0\)"),
                                              ("Interrupts", "predict raised KeyboardInterrupt"),
                                              ("ExitsWhenBuilt", r"raised SystemExit\(0\)")])
def test_a_controller_that_exits_is_its_error_one_line_exit_2_nothing_written(hostile, capsys, backend, controller,
                                                                            what):
    """Was: sys.exit(0) in predict made score exit 0 with nothing written."""
    folder, suite = hostile
    code = main(["score", "--suite", str(suite), "--controller", f"hostile_laws:{controller}", "--backend", backend,
                 "--jobs", "2", "--no-progress", "--out", str(folder / "out")])
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and f"controller hostile_laws:{controller}" in err, err
    assert __import__("re").search(what, err), err
    assert not list((folder / "out").glob("*"))  # the folder is made before the episodes run; nothing in it


@pytest.mark.hostile
def test_a_controller_that_kills_its_worker_is_its_error_one_line_exit_2(hostile, capsys):
    """Was: os._exit() in predict broke the process pool: a BrokenProcessPool, "internal error", exit 1."""
    folder, suite = hostile
    code = main(["score", "--suite", str(suite), "--controller", "hostile_laws:Dies", "--backend", "pool",
                 "--jobs", "2", "--no-progress", "--out", str(folder / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "controller hostile_laws:Dies" in err and "worker process ended" in err, err


@pytest.mark.hostile
def test_a_module_that_exits_on_import_is_refused_with_one_line(hostile, capsys):
    folder, suite = hostile
    (folder / "exits_on_import.py").write_text("import sys\nsys.exit(0)\n")
    try:
        code = main(["score", "--suite", str(suite), "--controller", "exits_on_import:X", "--out",
                     str(folder / "out")])
    finally:
        sys.modules.pop("exits_on_import", None)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "exits_on_import" in err and "SystemExit" in err, err
    assert not (folder / "out").exists()


@pytest.mark.hostile
@pytest.mark.parametrize("controller, name", [("Steps", "env.step"), ("Resets", "env.reset"),
                                              ("ReadsTheRoad", "env.assembly.disturbance"),
                                              ("Unwraps", "env.unwrapped"), ("CallsTheEnvs", "env.call"),
                                              ("ReadsTheForce", "env.damper_force"), ("Writes", "'control_dt'")])
def test_a_controller_cannot_step_reset_or_read_the_state_of_its_environment(hostile, capsys, controller, name):
    """Was: a controller that stepped or reset its environment hung the scorer; one could read the road ahead."""
    folder, suite = hostile
    code = main(["score", "--suite", str(suite), "--controller", f"hostile_laws:{controller}", "--backend", "serial",
                 "--no-progress", "--out", str(folder / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and name in err and f"hostile_laws:{controller}" in err, err
    assert "declarations only" in err or "read-only" in err, err
    assert not list((folder / "out").glob("*"))


@pytest.mark.hostile
def test_the_view_refuses_every_name_but_the_declarations_and_copies_what_it_gives():
    import gymnasium as gym

    import mrd_env  # noqa: F401
    from controllers.protocol import ASSEMBLY_DECLARATIONS, ENV_DECLARATIONS, DeclarationsOnly, declarations

    venv = gym.make_vec(CAR, num_envs=2, vectorization_mode="vector_entry_point", episode_seconds=0.1)
    try:
        view = declarations(venv)
        assert declarations(view) is view
        for name in ("step", "reset", "close", "call", "get_wrapper_attr", "set_wrapper_attr", "unwrapped", "core",
                     "assembly_", "damper_force", "plant_state", "_rngs", "np_random", "render", "spec"):
            with pytest.raises(DeclarationsOnly, match=f"env.{name} is refused"):
                getattr(view, name)
        assert getattr(view, "unwrapped", view) is view  # the laws' getattr(env, "unwrapped", env) gets the view
        for name in ("disturbance", "new_episode", "metrics", "renderer", "signals"):
            with pytest.raises(DeclarationsOnly, match=f"env.assembly.{name} is refused"):
                getattr(view.assembly, name)
        for name in ENV_DECLARATIONS:
            a, b = getattr(view, name), getattr(venv, name)
            assert type(a) is type(b)
        for name in ASSEMBLY_DECLARATIONS:
            assert type(getattr(view.assembly, name)) is type(getattr(venv.assembly, name))
        # copies: what a controller changes is its own
        view.sensor_layout.clear()
        view.damper.command.v_max  # noqa: B018
        m = view.signal_matrices("sprung_acc")
        m["C"][:] = 1e9
        assert venv.sensor_layout and not np.any(venv.signal_matrices("sprung_acc")["C"] == 1e9)
        assert view.command_spec is view.damper.command is view.assembly.damper.command
        with pytest.raises(DeclarationsOnly, match="read-only"):
            view.dt = 1.0
        assert venv.dt == 1e-3
    finally:
        venv.close()


#: Laws (with options) whose episodes are compared driven by the environment and by its view.
LAWS = [("skyhook_continuous", {}), ("clipped_optimal", {}), ("clipped_optimal_reward", {}),
        ("modulated_friction", {}), ("groundhook", {}),
        ("mpc", {"weights": "reward", "f_max": 1e5, "force_ref": 200.0, "horizon": 10})]


def _returns(make, env_id, options, seeds):
    from experiments.common.evaluation import evaluate_batch
    from experiments.common.scenarios import Scenario

    eps = evaluate_batch(make, Scenario("x", env_id, options, seeds), "")
    return [e.episode_return for e in eps], [e.metrics for e in eps]


@pytest.mark.parametrize("law, options", LAWS)
def test_the_laws_score_the_same_on_the_view_as_on_the_environment(law, options):
    """The view changes nothing a law reads: every return and metric equal bit for bit (the MPC with the road
    preview, which reads the road ahead from its observation)."""
    import mrd_env  # noqa: F401
    from controllers import make_controller
    from controllers.protocol import declarations

    env = {"episode_seconds": 0.2, "control_dt": 0.01, "road": "iso8608",
           "road_params": {"road_class": "C", "speed": 20.0},
           "sensors": ["sprung_acc", "unsprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel",
                       "damper_force", "command", "road_preview"], "preview": [0.01, 0.02, 0.05]}
    raw = _returns(lambda v: make_controller(law, v, **options), CAR, env, (1, 2))
    seen = _returns(lambda v: make_controller(law, declarations(v), **options), CAR, env, (1, 2))
    assert raw == seen


@pytest.mark.parametrize("law, control_dt", [("nmpc", 0.01), ("clipped_optimal+neural", 0.001)])
def test_the_nonlinear_mpc_and_the_neural_inverse_score_the_same_on_the_view(law, control_dt):
    """The laws that read the damper model and the coupled plant's matrices (NMPC), or build an inverse on the
    damper (its network trained at 1 ms)."""
    import mrd_env  # noqa: F401
    from controllers import make_controller
    from controllers.protocol import declarations

    env = {"episode_seconds": 0.05, "control_dt": control_dt}
    raw = _returns(lambda v: make_controller(law, v), CAR, env, (1, 2))
    assert raw == _returns(lambda v: make_controller(law, declarations(v)), CAR, env, (1, 2))


def test_a_shipped_agent_scores_the_same_on_the_view_as_on_the_environment():
    import mrd_env  # noqa: F401
    from controllers import load_agent
    from controllers.protocol import declarations

    agent = load_agent(ROOT / "controllers/agents/quarter_car_cmaes")
    env = {**agent.env_kwargs, "episode_seconds": 0.2}
    raw = _returns(lambda v: agent.bind(v), agent.env_id, env, (1, 2))
    seen = _returns(lambda v: agent.bind(declarations(v)), agent.env_id, env, (1, 2))
    assert raw == seen


def test_every_registered_law_builds_on_the_view_of_every_plant():
    """What the laws read at construction is declared (the check builds each law on the view, as score does)."""
    import gymnasium as gym

    import mrd_env  # noqa: F401
    from controllers import available_controllers, make_controller
    from controllers.protocol import declarations

    from experiments.common.plants import profiles

    for env_id in sorted({p.env_id for p in profiles().values()}):
        options = {"episode_seconds": 0.1}
        venv = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", **options)
        try:
            for law in available_controllers():
                try:
                    make_controller(law, venv)
                except ValueError as exc:  # a law that does not apply to the plant fails the same on the view
                    with pytest.raises(ValueError, match=__import__("re").escape(str(exc)[:40])):
                        make_controller(law, declarations(venv))
                    continue
                make_controller(law, declarations(venv))
        finally:
            venv.close()


@pytest.mark.hostile
@pytest.mark.parametrize("argv", [["--storeys", "²"], ["--storeys", "٣"], ["--damper-storeys", "1,²"],
                                  ["--storeys", "1" * 5000]])
def test_plant_options_with_unicode_digits_name_the_option(argv, capsys, tmp_path):
    """Was: '²'.isdigit() is True and int('²') raised "invalid literal for int()", naming no option."""
    code = main(["score", "--suite", "building-seismic-v1", "--controller", "passive_on", *argv, "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and argv[0] in err and "invalid literal" not in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.hostile
@pytest.mark.parametrize("argv", [["--episodes", "²"], ["--episodes", "0"], ["--episodes", "9" * 5000],
                                  ["--jobs", "²"]])
def test_numeric_options_name_the_option(argv, capsys, tmp_path):
    code = main(["score", "--suite", "car-comfort-v1", "--controller", "passive_on", *argv, "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and argv[0] in err, err
    assert len(err) < MAX_ERROR_LINE + 200


@pytest.mark.hostile
@pytest.mark.parametrize("argv", [["--controller", "x" * 3_000_000], ["--controller", "passive_on", "--law-options",
                                                                      "[" + "1," * 1_000_000 + "1]"]])
def test_an_error_quoting_a_huge_value_is_one_bounded_line(argv, capsys, tmp_path):
    """Was: one error line of 23.9 MB."""
    code = main(["score", "--suite", "car-comfort-v1", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err[:300]
    assert len(err) <= MAX_ERROR_LINE + 100, len(err)
    assert not (tmp_path / "out").exists()
