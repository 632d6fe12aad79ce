"""``mrd-env``: every sub-command refuses bad input with exit code 2 and exactly one line on stderr
(``mrd-env <command>: error: ...``), never a traceback, and before any long computation starts."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from experiments.cli import COMMANDS, main
from mrd_env.identification import DamperRecord


@pytest.fixture
def files(tmp_path):
    """Inputs, good and bad: ``{name}`` in an argument is replaced by the path of file ``name``."""
    n = 400
    t = np.arange(n) * 1e-3
    x = 0.005 * np.sin(2 * np.pi * 3.0 * t)
    cmd = np.where(t < 0.2, 0.0, 1.0)
    good = DamperRecord(t, x, cmd, 800.0 * np.tanh(x / 1e-3), command_unit="V").to_csv(tmp_path / "good.csv")
    paths = {"good": good, "missing": tmp_path / "missing.csv", "folder": tmp_path / "folder",
             "binary": tmp_path / "binary.csv", "wrong": tmp_path / "wrong.csv", "text": tmp_path / "text.csv",
             "one_row": tmp_path / "one_row.csv", "nonuniform": tmp_path / "nonuniform.csv",
             "empty": tmp_path / "empty.csv", "out_file": tmp_path / "out_file"}
    paths["folder"].mkdir()
    paths["binary"].write_bytes(bytes(range(256)) * 8)
    paths["wrong"].write_text("a,b,c\n1,2,3\n4,5,6\n7,8,9\n")
    lines = good.read_text().splitlines()
    paths["text"].write_text("\n".join(lines[:10] + [lines[10].replace(lines[10].split(",")[1], "abc")] + lines[11:]))
    paths["one_row"].write_text("\n".join(lines[:2]) + "\n")
    tt = t.copy()
    tt[200:] += 0.05  # a gap of 50 samples
    DamperRecord(tt, x, cmd, 0 * x).to_csv(paths["nonuniform"])
    paths["empty"].write_text("")
    paths["backwards"] = tmp_path / "backwards.csv"  # a repeated time stamp at data row 3
    paths["backwards"].write_text("t_s,x_m,command_V,force_N\n0,0,0,0\n0.001,0,0,1\n0.002,0,0,2\n0.002,0,0,3\n"
                                  "0.004,0,0,4\n")
    paths["out_file"].write_text("not a folder")
    paths["scalar_yml"] = tmp_path / "scalar.yml"  # an entry that is not a mapping
    paths["scalar_yml"].write_text("mrd_env/QuarterCarPhysical-v0: 3\n")
    # a load cell clipped over the last 3 % of the record: the faults leave a 1 % held-back part nothing to score
    tc = np.arange(2000) * 1e-3
    xc = 0.01 * np.sin(2 * np.pi * tc)
    fc = 800.0 * np.tanh(np.gradient(xc, tc) / 0.02) + 2000.0 * xc
    fc[1940:] = fc.max()
    paths["clipped"] = DamperRecord(tc, xc, np.ones_like(tc), fc, command_unit="V").to_csv(tmp_path / "clipped.csv")
    # saved agents (a folder holding agent.json and the model): without metadata, with broken, foreign or
    # incomplete metadata, for an unknown environment, without the model, and a valid quarter-car one
    good_meta = {"format": "mrd-env-agent", "plant": "quarter_car", "env_id": "mrd_env/QuarterCarPhysical-v0",
                 "algo": "PPO", "env_kwargs": {}, "model": "model.zip"}
    for stem, meta in (("agent_no_meta", None), ("agent_bad_json", "{"), ("agent_foreign", json.dumps({"x": 1})),
                       ("agent_no_keys", json.dumps({"format": "mrd-env-agent", "plant": "quarter_car"})),
                       ("agent_env", json.dumps({**good_meta, "env_id": "mrd_env/Tower-v0"})),
                       ("agent_no_model", json.dumps({**good_meta, "model": "gone.zip"})),
                       ("agent_qc", json.dumps(good_meta))):
        paths[stem] = tmp_path / stem
        paths[stem].mkdir()
        (paths[stem] / "model.zip").write_bytes(b"PK\x03\x04 not really a model")
        if meta is not None:
            (paths[stem] / "agent.json").write_text(meta)
    return paths


def _argv(argv, files):
    return [a.format(**{k: str(v) for k, v in files.items()}) for a in argv]


COLS = "t=t_s,x=x_m,command=command_V,force=force_N"
UNITS = "t=s,x=m,command=V,force=N"
DATA_ERRORS = [  # shared by identify and compare-models
    [],                                                   # --data is required
    ["--data", "{missing}"], ["--data", "{folder}"], ["--data", "{binary}"], ["--data", "{wrong}"],
    ["--data", "{text}"], ["--data", "{one_row}"], ["--data", "{empty}"],
    ["--data", "{good}", "--nope"],
    ["--data", "{good}", "--fs", "500"],                  # the time column is sampled at 1 kHz
    ["--data", "{good}", "--fs", "0"], ["--data", "{good}", "--fs", "nan"], ["--data", "{good}", "--fs", "-1"],
    ["--data", "{good}", "--fs", "abc"],
    ["--data", "{good}", "--dt", "0"], ["--data", "{good}", "--dt", "-1e-3"], ["--data", "{good}", "--dt", "inf"],
    ["--data", "{good}", "--fs", "1000", "--dt", "1e-3"],
    ["--data", "{good}", "--columns", COLS],              # --columns needs --units
    ["--data", "{good}", "--units", UNITS],
    ["--data", "{good}", "--columns", COLS, "--units", "t=s,x=furlong,command=V,force=N"],
    ["--data", "{good}", "--columns", COLS.replace("force_N", "F"), "--units", UNITS],
    ["--data", "{good}", "--columns", "garbage", "--units", UNITS],
    ["--data", "{good}", "--columns", COLS + ",speed=x_m", "--units", UNITS + ",speed=m"],
    ["--data", "{good}", "--columns", COLS, "--units", UNITS + ",v=m/s"],
    ["--data", "{good}", "--fit-fraction", "1.5"], ["--data", "{good}", "--fit-fraction", "0"],
    ["--data", "{good}", "--fit-fraction", "nan"],
    ["--data", "{good}", "--t-start", "10"], ["--data", "{good}", "--t-start", "0.3", "--t-end", "0.1"],
    ["--data", "{good}", "--t-end", "nan"],
    ["--data", "{good}", "--method", "nope"], ["--data", "{good}", "--maxiter", "0"],
    ["--data", "{good}", "--maxiter", "x"], ["--data", "{good}", "--popsize", "0"],
    ["--data", "{good}", "--seed", "-1"], ["--data", "{good}", "--warmup", "-1"],
    ["--data", "{good}", "--warmup", "nan"], ["--data", "{good}", "--warmup", "100"],
    ["--data", "{good}", "--command-range", "nope"],
    ["--data", "{good}", "--faults", "nope"], ["--data", "{good}", "--validate", "{missing}"],
    ["--data", "{good}", "--validate"], ["--data", "{good}", "{missing}"],
]

CASES = {
    "rig": [
        ["--nope"], ["--amplitude", "abc"], ["--amplitude", "-0.01"], ["--amplitude", "nan"], ["--amplitude", "0"],
        ["--frequency", "0"], ["--frequency", "inf"], ["--frequency", "-2"], ["--dt", "0"], ["--dt", "1"],
        ["--dt", "nan"], ["--cycles", "1e12"], ["--cycles", "-1"], ["--cycles", "1e-9"], ["--commands"],
        ["--commands", "99"], ["--commands", "nan"], ["--commands", "-1", "1"], ["--model", "nope"],
        ["--preset", "nope"], ["--model", "bouc_wen", "--preset", "large_scale"],
        ["--record", "{missing}"], ["--record", "{folder}"], ["--record", "{binary}"], ["--record", "{wrong}"],
        ["--record", "{text}"], ["--record", "{one_row}"], ["--record", "{empty}"], ["--record", "{nonuniform}"],
        ["--record", "{good}", "--model", "ali_ramaswamy"],   # a record in V, a damper driven in A
        ["--record", "{good}", "--columns", "t=t_s,x=x_m,command=command_V"],
        ["--record", "{good}", "--units", "t=s,x=m,command=V"],
        ["--record", "{good}", "--columns", "t=t_s,x=x_m,command=command_V", "--units", "t=s,x=furlong,command=V"],
        ["--record", "{good}", "--columns", "t=t_s,x=nope,command=command_V", "--units", "t=s,x=m,command=V"],
        ["--record", "{good}", "--columns", "garbage", "--units", "t=s"],
        ["--record", "{good}", "--columns", "t=t_s,x=x_m", "--units", "t=s,x=m"],   # no command column
        ["--out", "{out_file}"],
    ],
    "benchmark": [
        ["--nope"], ["--plant", "nope"], ["--suite", "nope"], ["--suite", "{missing}"], ["--suite", "{wrong}"],
        ["--suite", "{binary}"], ["--controller", "nope"], ["--controller", "passive_off", "--controller", "nope"],
        ["--controller", "{missing}"], ["--controller", "{folder}"], ["--controller", "{agent_no_meta}"],
        ["--controller", "{agent_bad_json}"], ["--controller", "{agent_foreign}"], ["--controller", "{agent_no_keys}"],
        ["--controller", "{agent_env}"], ["--controller", "{agent_no_model}"],
        ["--suite", "building-six-storey-v1", "--controller", "{agent_qc}"],   # an agent of another plant
        ["--suite", "building-six-storey-v1", "--no-shipped", "--controller", "groundhook"],   # a law it cannot run
        ["--only", "nope"], ["--no-shipped"], ["--no-shipped", "--only", "passive_off"], ["--episodes", "0"],
        ["--episodes", "x"], ["--plant", "quarter_car", "--storeys", "6"], ["--backend", "gpu"], ["--jobs", "0"],
        ["--address", "ray://x:1"], ["--out", "{out_file}"],
    ],
    "train": [
        ["--backend", "gpu"], ["--jobs", "0"], ["--jobs", "-2"], ["--address", "ray://x:1"],
        ["--nope"], ["--algo", "nope"], ["--plant", "nope"], ["--timesteps", "0"], ["--timesteps", "x"],
        ["--timesteps", "-5"], ["--control-dt", "0"], ["--control-dt", "0.0015"], ["--control-dt", "nan"],
        ["--seeds", "-1"], ["--seeds", "x"], ["--history", "0"], ["--sensors", "nope"],
        ["--disturbance", '{{"kind": "nope"}}'], ["--disturbance", '{{"kind": "iso8608", "road_class": "Z"}}'],
        ["--set", "n_envs"], ["--set", "n_envs=0"], ["--set", "nope=1"], ["--hyperparams", "{missing}"],
        ["--hyperparams", "{binary}"], ["--algo", "sac", "--hyperparams", "{empty}"], ["--eval-freq", "-1"],
        ["--eval-episodes", "0"], ["--checkpoint-freq", "-1"], ["--plant", "shear_building", "--set", "n_envs=2.5"],
        ["--hyperparams", "{scalar_yml}"], ["--set", "env_kwargs=3"], ["--set", "normalize=3"],
    ],
    "tune": [
        ["--nope"], ["--plant", "nope"], ["--algo", "nope"], ["--algo", "a2c"], ["--trials", "0"],
        ["--timesteps", "0"], ["--eval-freq", "0"], ["--eval-episodes", "0"], ["--seed", "-1"],
        ["--hyperparams", "{missing}"], ["--backend", "gpu"], ["--jobs", "0"], ["--address", "ray://x:1"],
        ["--space", "nope"], ["--space", "residual"], ["--space", "residual", "--algo", "sac"],
        ["--hyperparams", "{scalar_yml}"],
    ],
    "identify": DATA_ERRORS + [
        ["--data", "{good}", "--model", "nope"], ["--data", "{good}", "--preset", "nope"],
        ["--data", "{good}", "--free", "nope"], ["--data", "{good}", "--model", "ali_ramaswamy"],
        ["--data", "{good}", "--model", "neural", "--free", "c0a"],
        ["--data", "{good}", "--model", "neural", "--method", "pso"],
    ],
    "compare-models": DATA_ERRORS + [
        ["--data", "{good}", "--models", "nope"], ["--data", "{good}", "--models", "bingham", "nope"],
        ["--data", "{good}", "--models", "bingham", "bingham"], ["--data", "{good}", "--plot-window", "0"],
        ["--data", "{good}", "--plot-window", "nan"], ["--data", "{good}", "--backend", "gpu"],
        ["--data", "{good}", "--jobs", "0"], ["--data", "{good}", "--address", "ray://x:1"],
    ],
    "warmup": [["--nope"], ["--models", "nope"], ["--models"], ["--jobs", "0"], ["--jobs", "x"]],
    "inverse": [
        [], ["nope"], ["achievable", "--nope"], ["achievable", "--inverses", "nope"], ["achievable", "--plants", "nope"],
        ["achievable", "--preset", "nope"], ["achievable", "--duration", "0"], ["achievable", "--rms", "-1"],
        ["achievable", "--seed", "-1"], ["achievable", "--mismatch", "bouc_wen"],
        ["achievable", "--network", "{missing}"], ["achievable", "--network", "{binary}"],
        ["record"], ["record", "--data", "{missing}"], ["record", "--data", "{good}", "--validate", "{good}"], ["record", "--data", "{good}", "--model", "nope"],
        ["record", "--data", "{good}", "--inverses", "nope"], ["record", "--data", "{good}", "--plant-preset",
                                                                "{missing}"],
        ["record", "--data", "{good}", "--epochs", "0"], ["record", "--data", "{good}", "--fs", "500"],
        ["train", "--epochs", "0"], ["train", "--out", "{folder}"], ["train", "--model", "nope", "--out", "{missing}"],
        ["train", "--rms", "0", "1", "--out", "{missing}"], ["train", "--seed", "-1", "--out", "{missing}"],
        ["train", "--history", "0", "--out", "{missing}"], ["train", "--dt", "0", "--out", "{missing}"],
    ],
    "score": [
        ["--nope"], [], ["--suite", "nope", "--controller", "passive_off"],
        ["--suite", "{missing}", "--controller", "passive_off"], ["--suite", "{wrong}", "--controller", "passive_off"],
        ["--suite", "{binary}", "--controller", "passive_off"], ["--suite", "nope", "--controller", "passive_off",
                                                                 "--episodes", "0"],
        ["--suite", "nope", "--controller", "passive_off", "--jobs", "0"],
    ],
    "leaderboard": [["--nope"], [], ["{missing}"], ["{binary}"], ["{wrong}"], ["{good}"], ["{folder}"]],
    "dataset": [
        ["--nope"], [], ["--suite", "nope", "--controller", "passive_off"], ["--suite", "car-comfort-v1", "--controller",
                                                                              "nope"],
        ["--suite", "car-comfort-v1", "--controller", "passive_off", "--episodes", "0"],
        ["--suite", "car-comfort-v1", "--controller", "passive_off", "--scenario", "nope"],
        ["--suite", "car-comfort-robust-v1", "--controller", "passive_off"],   # every episode its own environment
        ["--suite", "car-comfort-v1", "--controller", "skyhook_continuous", "--law-options", "x"],
        ["--suite", "car-comfort-v1", "--controller", "passive_off", "--out", "{out_file}"],
    ],
    "suite": [["--nope"], [], ["nope"], ["build"], ["build", "{missing}"], ["build", "{binary}"], ["build", "{wrong}"],
              ["build", "{folder}"], ["show"], ["show", "nope"], ["show", "{binary}"],
              ["build", "{wrong}", "--jobs", "0"], ["build", "{wrong}", "--backend", "nope"]],
}


@pytest.mark.parametrize("command, argv", [pytest.param(c, a, id=f"{c} {' '.join(a)}") for c, cases in CASES.items()
                                           for a in cases])
def test_bad_input_is_one_line_and_exit_2(command, argv, files, capsys, tmp_path):
    argv = _argv(argv, files)
    # safety nets: should a case pass its checks after all, it stays short instead of running for minutes
    extra = {"benchmark": ["--suite", "car-comfort-v1", "--episodes", "1", "--backend", "serial", "--no-progress", None],
             "train": ["--timesteps", "1", "--eval-freq", "0"], "tune": ["--trials", "1", "--timesteps", "1"],
             "identify": ["--maxiter", "1"], "compare-models": ["--maxiter", "1", "--models", "bingham"]}
    for opt, val in zip(extra.get(command, [])[::2], extra.get(command, [])[1::2]):
        if opt not in argv:
            argv += [opt, val] if val is not None else [opt]
    argv += ["--out", str(tmp_path / "out")] if "--out" not in argv and command != "warmup" else []
    code = main([command, *argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert code == 2, err
    assert err.startswith(f"mrd-env {command}: error: "), err
    assert err.count("\n") == 1 and err.endswith("\n"), err


def test_every_command_is_covered():
    assert set(CASES) == set(COMMANDS)


def test_unknown_command_and_no_command(capsys):
    for argv in (["nope"], [], ["--nope"]):
        code = main(argv)
        _, err = capsys.readouterr()
        assert code == 2 and err.startswith("mrd-env: error: ") and err.count("\n") == 1, err


def test_help_exits_0_without_importing_the_commands():
    code = ("import sys, contextlib, io\n"
            "from experiments.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "    rc = main(['--help'])\n"
            "mods = [m for m in ('experiments.commands.rig', 'experiments.commands.benchmark',\n"
            "        'experiments.commands.train', 'experiments.commands.score', 'experiments.common.scenarios',\n"
            "        'experiments.commands.warmup', 'experiments.commands.identify',\n"
            "        'experiments.commands.compare_models', 'mrd_env.rig',\n"
            "        'mrd_env.identification', 'stable_baselines3', 'torch') if m in sys.modules]\n"
            "print(rc, 'COMMANDS' if all(c in out.getvalue() for c in ('rig', 'benchmark', 'train', 'score', 'identify',\n"
            "      'compare-models')) else 'missing', mods)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "0 COMMANDS []", res.stdout + res.stderr


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_command_help_exits_0(command, capsys):
    assert main([command, "--help"]) == 0
    out, err = capsys.readouterr()
    assert f"mrd-env {command}" in out and err == ""


MESSAGES = [  # (argv, what the one line says): the option by its name, values as written
    (["identify", "--data", "{good}", "--t-start", "0.3", "--t-end", "0.1"],
     "--t-start 0.3 s must be before --t-end 0.1 s"),
    (["identify", "--data", "{good}", "--t-start", "10"], "--t-start/--t-end keep 0 samples of 'good'"),
    (["identify", "--data", "{good}", "--maxiter", "0"], "argument --maxiter: 0 is invalid: must be a whole number >= 1"),
    (["identify", "--data", "{backwards}"], "not strictly increasing at data row 3 (0.002 followed by 0.002)"),
    (["identify", "--data", "{good}", "--model", "neural", "--free", "c0a"], "--free: parametric models only"),
    (["identify", "--data", "{good}", "--warmup", "100"], "are left to score after a warm-up of 100 s"),
    (["identify", "--data", "{good}", "--bounds", "c0a=1"], "--bounds: expected NAME=LO:HI (numbers in SI units)"),
    (["identify", "--data", "{good}", "--force-offset", "2", "--align"], "--align estimates the force offset and"),
    (["identify", "--data", "{clipped}", "--fit-fraction", "0.99"],
     "fit_fraction = 0.99 leaves 0 sample(s) of 'clipped' to validate on once its faults are excluded"),
    (["benchmark", "--suite", "building-six-storey-v1", "--no-shipped", "--controller", "groundhook"],
     "controller groundhook: Groundhook needs signals with the role(s) ['wheel_velocity'], which the "
     "'shear_building' environment does not declare"),
    (["benchmark", "--suite", "car-comfort-v1", "--only", "passive_off", "nope"],
     "only: 'nope' is none of the shipped controllers of the chosen suites (clipped_optimal, groundhook,"),
    (["train", "--hyperparams", "{scalar_yml}"], "the entry for mrd_env/QuarterCarPhysical-v0 must be a mapping"),
    (["train", "--set", "normalize=3"], "hyperparameter normalize must be true, false or a mapping"),
    (["compare-models", "--data", "{good}", "--models", "bingham", "bingham"],
     "--models: bingham given more than once"),
    (["compare-models", "--data", "{good}", "--plot-window", "0"], "argument --plot-window: 0 is invalid"),
    (["inverse", "achievable", "--plants", "nope"], "--plants: unknown damper model(s) ['nope']; available"),
    (["inverse", "achievable", "--network", "{binary}"], "not a neural-inverse network file"),
    (["inverse", "train", "--history", "0"], "argument --history: 0 is invalid: must be a whole number >= 1"),
    (["inverse", "train", "--damper", "nope"], "--damper: unknown damper model(s) ['nope']"),
    (["train", "--disturbance", '{{"kind": "iso8608", '], "--disturbance is not valid JSON (Expecting property name"),
]
LEAKS = ("np.float64(", "np.int64(", "slice", "pickle", "NeuralOptions", "Traceback", "['nope', 'nope']")


@pytest.mark.parametrize("argv, text", MESSAGES, ids=[" ".join(a) for a, _ in MESSAGES])
def test_error_messages_name_the_option_and_show_plain_values(argv, text, files, capsys, tmp_path):
    """The line names what the user typed (the option, the value as written); never an internal call, a NumPy
    repr, a library's option class or a name twice."""
    code = main(_argv(argv, files) + ["--out", str(tmp_path / "out.npz")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert text in err, err
    assert not [leak for leak in LEAKS if leak in err], err


# with bingham's other tests on one worker (``--dist loadgroup``, tests/conftest.py): its kernel is compiled once
@pytest.mark.xdist_group("bingham")
def test_warmup_compiles_a_model_and_says_so(capsys):
    assert main(["warmup", "--models", "bingham"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("bingham") and "1 model(s) ready" in out


@pytest.mark.xdist_group("bingham")
def test_warmup_compiles_models_side_by_side(capsys):
    """Two models on a pool of two processes: each reported once, in the order asked (the default model and
    bingham, whose kernels the suite compiles anyway)."""
    assert main(["warmup", "--models", "bingham", "spencer_dyke", "--jobs", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines[:2]] == ["bingham", "spencer_dyke"] and "2 model(s) ready" in lines[-1]


def _raising_run(monkeypatch, exc):
    """``mrd-env benchmark`` made to raise ``exc`` once its options are parsed."""
    import experiments.commands.benchmark as cmd

    def run(args):
        raise exc
    monkeypatch.setattr(cmd, "run", run)


def test_a_user_error_in_a_sweep_worker_is_one_line_and_exit_2(monkeypatch, capsys):
    from mrd_env.executor import Task, TaskFailed

    task = Task(print, (1,), label="El Centro / groundhook")
    _raising_run(monkeypatch, TaskFailed(task, ValueError("Groundhook needs the sensor(s) ['wheel_velocity']")))
    assert main(["benchmark"]) == 2
    err = capsys.readouterr().err
    assert err == "mrd-env benchmark: error: El Centro / groundhook: Groundhook needs the sensor(s) " \
                  "['wheel_velocity']\n"


def test_a_bug_is_one_line_and_exit_1_and_traceback_shows_it(monkeypatch, capsys):
    from mrd_env.executor import Task, TaskFailed

    for exc in (RuntimeError("boom"), TaskFailed(Task(print, label="t"), KeyError("boom"))):
        _raising_run(monkeypatch, exc)
        assert main(["benchmark"]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"mrd-env benchmark: error: internal error: {type(exc).__name__}: ") and \
            err.count("\n") == 1 and "--traceback" in err, err
        with pytest.raises(type(exc)):
            main(["--traceback", "benchmark"])


def test_interrupted_is_exit_130(monkeypatch, capsys):
    _raising_run(monkeypatch, KeyboardInterrupt())
    assert main(["benchmark"]) == 130
    assert capsys.readouterr().err == "mrd-env benchmark: interrupted\n"


def test_a_missing_optional_dependency_names_its_extra(monkeypatch, capsys):
    """'No module named osqp' alone left a user to guess which extra brings it: the line names the extra, read from
    the installed package's metadata (pyproject.toml's optional dependencies), one line, exit 2."""
    import sys

    import experiments.commands.warmup as warmup
    from experiments.cli import extras_of, main

    assert extras_of("osqp")[0] == "optimal" and extras_of("yaml")[-1] == "test" and extras_of("not_a_module") == []

    def run(args):
        import osqp  # noqa: F401  (blocked below: what a machine without the extra raises)

    monkeypatch.setitem(sys.modules, "osqp", None)
    monkeypatch.setattr(warmup, "run", run)
    assert main(["warmup"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "osqp" in err and "pip install 'mrd-env[optimal]'" in err, err


def test_the_readme_lists_every_command():
    """The README's command list is the CLI's (it once missed score and leaderboard)."""
    import re
    from pathlib import Path

    from experiments.cli import COMMANDS

    readme = Path(__file__).resolve().parents[2] / "README.md"
    line = re.search(r"`mrd-env --help` lists every command: (.*?)\.", readme.read_text(), re.S).group(1)
    assert set(re.findall(r"`([a-z-]+)`", line)) == set(COMMANDS)
