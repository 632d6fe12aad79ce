"""The sweep executor: the same results in the same order on every backend, one retry, failures named."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrd_env.executor import Task, TaskFailed, resolve_backend, run_tasks
from experiments.common.plants import profile


def draw(seed: int, n: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=n)


def flaky(marker: str, value: int) -> int:
    """Fails on its first call (a marker file records it), succeeds on the retry."""
    p = Path(marker)
    if not p.exists():
        p.write_text("failed once")
        raise OSError("transient failure")
    return value * 2


def draw_then_fail_once(marker: str, rng: np.random.Generator) -> float:
    """Draws from its generator, then fails on its first call."""
    x = rng.random()
    flaky(marker, 0)
    return x


def broken(x: int) -> int:
    raise ValueError(f"bad input {x}")


TASKS = [Task(draw, (s,), label=f"seed {s}") for s in range(6)]


def test_serial_and_pool_give_identical_results_in_task_order():
    serial = run_tasks(TASKS, backend="serial", progress=False)
    pool = run_tasks(TASKS, backend="pool", jobs=2, progress=False)
    assert len(serial) == len(pool) == 6
    for a, b, s in zip(serial, pool, range(6)):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, draw(s))


@pytest.mark.parametrize("backend", ["serial", "pool"])
def test_a_failed_task_is_retried_once(tmp_path, backend):
    out = run_tasks([Task(flaky, (str(tmp_path / "m"), 21))], backend=backend, jobs=1, progress=False)
    assert out == [42]


@pytest.mark.parametrize("backend", ["serial", "pool"])
def test_a_task_that_fails_twice_is_reported_with_its_inputs(backend):
    with pytest.raises(TaskFailed, match=r"task broken\(7\) failed twice: ValueError: bad input 7"):
        run_tasks([Task(draw, (1,)), Task(broken, (7,))], backend=backend, jobs=2, progress=False)


def test_a_pool_from_a_script_on_standard_input_is_refused_in_one_line_and_auto_is_serial():
    """``python -`` names its main script ``<stdin>``, which a spawned worker cannot import: before, every worker died
    first and the sweep ended in "its worker process ended" after a traceback per worker. Now the pool is refused
    before any worker starts (one line naming the way out), and ``auto`` runs the tasks in the process."""
    import os
    import subprocess
    import sys

    script = ("from mrd_env.executor import Task, run_tasks\n"
              "print('AUTO', run_tasks([Task(abs, (-1,)), Task(abs, (-2,))], backend='auto', jobs=2, progress=False))\n"
              "run_tasks([Task(abs, (-1,)), Task(abs, (-2,))], backend='pool', jobs=2, progress=False)\n")
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-"], input=script, capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(root)})
    assert out.returncode == 1 and out.stdout == "AUTO [1, 2]\n", (out.stdout, out.stderr)
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("mrd_env.executor.UnguardedMain: backend 'pool' called from a main script that is no "
                           "file (<stdin>)") and 'backend="serial"' in last, out.stderr
    assert out.stderr.count("Traceback") == 1  # the script's own; no worker started


def test_backend_and_jobs_are_checked():
    with pytest.raises(ValueError, match="backend must be one of"):
        run_tasks(TASKS, backend="gpu")
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="jobs must be an integer >= 1"):
            run_tasks(TASKS, jobs=bad)
    assert resolve_backend("auto", 1, 4) == "serial" and resolve_backend("auto", 3, 2) == "pool"
    assert resolve_backend("auto", 3, 1) == "serial"


# --- the sweeps on the executor ---------------------------------------------------------------------------------

def test_benchmark_on_a_local_ray_instance_equals_the_serial_scores(tmp_path):
    pytest.importorskip("ray")
    import json

    from experiments.cli import main

    for backend in ("serial", "ray"):
        assert main(["benchmark", "--suite", "building-six-storey-v1", "--only", "passive_on", "clipped_optimal",
                     "--episodes", "1", "--backend", backend, "--jobs", "2", "--out", str(tmp_path / backend),
                     "--no-progress"]) == 0
    files = sorted(p.name for p in (tmp_path / "serial" / "results").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "ray" / "results").iterdir()) and len(files) == 2
    for name in files:
        a, b = (json.loads((tmp_path / bk / "results" / name).read_text()) for bk in ("serial", "ray"))
        assert a["episodes"] == b["episodes"] and a["summary"] == b["summary"], name


def test_training_seeds_on_a_pool_equal_serial_ones(tmp_path):
    from experiments.cli import main
    from controllers import load_agent

    tiny = ["--timesteps", "128", "--eval-freq", "0", "--no-progress", "--set", "n_envs=2", "n_steps=64",
            "batch_size=64", "n_epochs=1"]
    for backend in ("serial", "pool"):
        assert main(["train", "--plant", "quarter_car", "--seeds", "0", "1", "--backend", backend, "--jobs", "2",
                     "--out", str(tmp_path / backend), *tiny]) == 0
    for s in (0, 1):
        a, b = (load_agent(tmp_path / bk / f"quarter_car_ppo_s{s}") for bk in ("serial", "pool"))
        for va, vb in zip(a.model.policy.state_dict().values(), b.model.policy.state_dict().values()):
            assert np.array_equal(va.numpy(), vb.numpy())


def test_tune_runs_trials_and_writes_the_best_hyperparameters(tmp_path):
    pytest.importorskip("optuna")
    import yaml

    from experiments.cli import main

    base = tmp_path / "base.yml"
    base.write_text(yaml.safe_dump({"mrd_env/QuarterCarPhysical-v0": {"n_envs": 2, "policy": "MlpPolicy", "normalize": True,
                                                              "n_epochs": 1}}))
    assert main(["tune", "--plant", "quarter_car", "--trials", "2", "--timesteps", "128", "--eval-freq", "64",
                 "--eval-episodes", "1", "--hyperparams", str(base), "--backend", "serial", "--out",
                 str(tmp_path / "t"), "--no-progress"]) == 0
    best = yaml.safe_load((tmp_path / "t" / "quarter_car_ppo_best.yml").read_text())["mrd_env/QuarterCarPhysical-v0"]
    assert best["n_envs"] == 2 and best["n_steps"] in (64, 128, 256, 512) and 1e-5 <= best["learning_rate"] <= 1e-3
    rows = (tmp_path / "t" / "quarter_car_ppo_trials.csv").read_text().splitlines()
    assert len(rows) == 1 + 2
    # rerunning the command resumes the study
    assert main(["tune", "--plant", "quarter_car", "--trials", "1", "--timesteps", "128", "--eval-freq", "64",
                 "--eval-episodes", "1", "--hyperparams", str(base), "--backend", "serial", "--out",
                 str(tmp_path / "t"), "--no-progress"]) == 0
    assert len((tmp_path / "t" / "quarter_car_ppo_trials.csv").read_text().splitlines()) == 1 + 3


def _fake_train_one(stopped_at: dict, untrained: float | None = None):
    """A stand-in for ``train_one`` in a study: trial k scores -k at every validation (every 64 steps); with
    ``untrained``, every trial first scores that at step 0, as a residual agent scores its law before training."""
    def train_one(plant, algo, seed, *, out, timesteps, report, **kw):
        trial = int(Path(out).name.split("_")[1])
        rows = ["timesteps,validation_return,validation_return_std"]
        if untrained is not None:
            rows.append(f"0,{untrained},0")
            assert report(0, untrained)
        for step in range(64, timesteps + 1, 64):
            rows.append(f"{step},{-float(trial)},0")
            if not report(step, -float(trial)):
                stopped_at[trial] = step
                break
        run = Path(out) / "run"
        run.mkdir(parents=True)
        (run / "validation.csv").write_text("\n".join(rows) + "\n")
        return run
    return train_one


def test_a_resumed_study_draws_new_trials(tmp_path, monkeypatch):
    """Rerunning `mrd-env tune` adds trials the first run did not propose (the same sampler seed would repeat
    them), and a new study with the same seed proposes the same ones (reproducible)."""
    pytest.importorskip("optuna")
    import experiments.training.trainers as trainers
    from experiments.commands.tune import tune

    monkeypatch.setattr(trainers, "train_one", _fake_train_one({}))

    def params(st):
        return [tuple(sorted(t.params.items())) for t in st.trials]

    first = params(tune(profile("quarter_car"), "ppo", trials=3, timesteps=64, eval_freq=64, out=tmp_path / "a",
                        backend="serial", progress=False))
    both = params(tune(profile("quarter_car"), "ppo", trials=3, timesteps=64, eval_freq=64, out=tmp_path / "a",
                       backend="serial", progress=False))
    assert both[:3] == first and not set(both[3:]) & set(first)
    again = params(tune(profile("quarter_car"), "ppo", trials=3, timesteps=64, eval_freq=64, out=tmp_path / "b",
                        backend="serial", progress=False))
    assert again == first


@pytest.mark.parametrize("untrained", [None, 1.0])
def test_tune_prunes_a_trial_below_the_median_after_the_warm_up(tmp_path, monkeypatch, untrained):
    """The study's median pruner, in the worker that runs the trials, stops the fourth trial where its validation
    falls below the earlier trials' median, from the second validation on; the training is told through
    ``report`` and stops. A step-0 validation above every later one (a residual agent at its law) does not
    shield the trial: the pruner judges a trial by its best validation, and the untrained one is not the
    trial's (until 2026-11-27 it was: a residual trial below its law was pruned only where the earlier trials'
    median stood above the law)."""
    pytest.importorskip("optuna")
    import experiments.training.trainers as trainers
    from experiments.commands.tune import tune

    stopped_at = {}
    monkeypatch.setattr(trainers, "train_one", _fake_train_one(stopped_at, untrained))
    st = tune(profile("quarter_car"), "ppo", trials=4, timesteps=320, eval_freq=64, out=tmp_path, backend="serial",
              progress=False)
    states = [t.state.name for t in st.trials]
    assert states == ["COMPLETE", "COMPLETE", "COMPLETE", "PRUNED"], states
    assert stopped_at == {3: 128}  # the second validation (the warm-up: 2 × 64 steps)
    assert st.best_value == 0.0


@pytest.mark.slow  # 3 PPO trials (12 s); TD3's residual space, tested below in CI, shares its code path
def test_tune_residual_space_starts_at_the_recipe_and_keeps_gamma_high(tmp_path):
    """--space residual: the first trial is the YAML entry as it is, the others draw γ in [0.995, 0.999] and the
    residual's scale, which lands in the best YAML's residual."""
    pytest.importorskip("optuna")
    import yaml

    from experiments.cli import main

    entry = {"n_envs": 2, "policy": "MlpPolicy", "normalize": True, "residual": {"law": "skyhook_continuous",
             "scale": 0.5}, "n_steps": 256, "batch_size": 1024, "n_epochs": 5, "gamma": 0.998, "gae_lambda": 0.99,
             "learning_rate": 1e-4, "policy_kwargs": {"log_std_init": -3.5}}
    base = tmp_path / "base.yml"
    base.write_text(yaml.safe_dump({"mrd_env/QuarterCarPhysical-v0": entry}))
    assert main(["tune", "--plant", "quarter_car", "--space", "residual", "--trials", "3", "--timesteps", "64",
                 "--eval-freq", "64", "--eval-episodes", "1", "--hyperparams", str(base), "--backend", "serial",
                 "--out", str(tmp_path / "t"), "--no-progress"]) == 0
    import csv

    rows = list(csv.DictReader((tmp_path / "t" / "quarter_car_ppo_trials.csv").open()))
    assert len(rows) == 3
    assert float(rows[0]["residual_scale"]) == 0.5 and float(rows[0]["gamma"]) == 0.998
    assert all(0.995 <= float(r["gamma"]) <= 0.999 and 0.2 <= float(r["residual_scale"]) <= 1.0 for r in rows)
    best = yaml.safe_load((tmp_path / "t" / "quarter_car_ppo_best.yml").read_text())["mrd_env/QuarterCarPhysical-v0"]
    assert best["residual"]["law"] == "skyhook_continuous" and "residual_scale" not in best
    assert 0.2 <= best["residual"]["scale"] <= 1.0 and -3.5 <= best["policy_kwargs"]["log_std_init"] <= -1.0


def test_tune_residual_space_of_td3_starts_at_the_recipe_and_searches_its_pace(tmp_path, capsys):
    """--space residual for an off-policy algorithm: the first trial is the YAML entry (the actor's warm-up, absent
    there, is 0), the others draw within the off-policy space, TD3's action noise included; an entry whose value
    lies outside a searched choice is refused by name."""
    pytest.importorskip("optuna")
    import csv

    import yaml

    from experiments.cli import main

    entry = {"n_envs": 1, "policy": "MlpPolicy", "normalize": True, "learning_starts": 32,
             "residual": {"law": "skyhook_continuous", "scale": 0.5}, "learning_rate": 3e-4, "batch_size": 256,
             "gamma": 0.998, "tau": 0.01, "train_freq": 4, "noise_type": "normal", "noise_std": 0.05,
             "policy_kwargs": {"net_arch": [8]}}
    base = tmp_path / "base.yml"
    base.write_text(yaml.safe_dump({"mrd_env/QuarterCarPhysical-v0": entry}))
    args = ["tune", "--plant", "quarter_car", "--algo", "td3", "--space", "residual", "--trials", "2", "--timesteps",
            "64", "--eval-freq", "64", "--eval-episodes", "1", "--hyperparams", str(base), "--backend", "serial",
            "--out", str(tmp_path / "t"), "--no-progress"]
    assert main(args) == 0
    rows = list(csv.DictReader((tmp_path / "t" / "quarter_car_td3_trials.csv").open()))
    assert len(rows) == 2
    first = rows[0]
    assert float(first["noise_std"]) == 0.05 and float(first["tau"]) == 0.01 and int(first["actor_warmup_steps"]) == 0
    assert all(0.99 <= float(r["gamma"]) <= 0.999 and 0.01 <= float(r["noise_std"]) <= 0.2 for r in rows)
    best = yaml.safe_load((tmp_path / "t" / "quarter_car_td3_best.yml").read_text())["mrd_env/QuarterCarPhysical-v0"]
    assert 0.1 <= best["residual"]["scale"] <= 1.0 and "actor_warmup_steps" in best

    base.write_text(yaml.safe_dump({"mrd_env/QuarterCarPhysical-v0": {**entry, "tau": 0.3}}))
    capsys.readouterr()
    assert main([*args[:-2], str(tmp_path / "u"), "--no-progress"]) == 2
    assert "entry's tau must be one of" in capsys.readouterr().err and not (tmp_path / "u").exists()


def test_a_trials_value_is_its_best_validation_once_trained():
    """The untrained residual agent (its law, at step 0) does not set a trial's value: trials that fall below the
    law are ranked by how far they fell, not tied with it."""
    from experiments.commands.tune import trial_value

    rows = [{"timesteps": "0", "validation_return": "-9.26"}, {"timesteps": "20000", "validation_return": "-10.5"},
            {"timesteps": "40000", "validation_return": "-9.8"}]
    assert trial_value(rows) == -9.8
    assert trial_value(rows[:1]) == -9.26   # a trial stopped before its first validation after step 0


def test_model_comparison_and_sensor_propagation_on_a_pool_equal_serial_ones():
    """compare-models and the Monte-Carlo propagation run their fits as tasks: the same numbers on a pool."""
    from mrd_env.dampers import make_damper
    from mrd_env.identification import compare_models
    from mrd_env.identification.propagate import default_excitation, propagate_sensor_errors
    from mrd_env.rig import random_test

    d = make_damper("bouc_wen")
    rec = random_test(d, 0.004, 5.0, 2.0, switch_rate=2.0, rng=3)
    quiet = {"maxiter": 5, "progress": False}
    kw = dict(search=quiet, plot_window=None)
    a = compare_models([rec], ["bingham", "bouc_wen"], backend="serial", **kw)
    b = compare_models([rec], ["bingham", "bouc_wen"], backend="pool", jobs=2, **kw)
    assert [m.model for m in b.models] == ["bingham", "bouc_wen"] and all(m.fit is not None for m in b.models)
    for ma, mb in zip(a.models, b.models):
        assert ma.fit.params == mb.fit.params and ma.validation_overall == mb.validation_overall

    exc = default_excitation(d, duration=1.0, rng=1)
    kw = dict(excitation=exc, n_draws=2, rng=7, free=["c0a", "alpha_b"], progress=False, search=quiet)
    p = propagate_sensor_errors(d, backend="serial", **kw)
    q = propagate_sensor_errors(d, backend="pool", jobs=2, **kw)
    assert q.free == ("c0a", "alpha_b")
    for k in p.mc.samples:
        assert np.array_equal(p.mc.samples[k], q.mc.samples[k])


@pytest.mark.parametrize("backend", ["serial", "pool"])
def test_a_retry_starts_from_the_task_s_own_inputs(tmp_path, backend):
    """The retried task draws what its first try drew (a generator among its inputs is not left advanced)."""
    task = Task(draw_then_fail_once, (str(tmp_path / "marker"), np.random.default_rng(5)))
    assert run_tasks([task], backend=backend, jobs=1, progress=False) == [np.random.default_rng(5).random()]


def test_without_retries_a_failure_is_reported_at_once(tmp_path):
    with pytest.raises(TaskFailed, match="only try") as err:
        run_tasks([Task(flaky, (str(tmp_path / "m"), 3))], backend="serial", progress=False, retry=False)
    assert isinstance(err.value.error, OSError)


# --- stopping a pool (issue 48, item 7) ---------------------------------------------------------------------------

#: A sweep of tasks that block forever on a pool, run as its own program: SIGTERM raises KeyboardInterrupt there (as
#: mrd-env routes it); each task leaves its worker's process id in a file before it blocks.
BLOCKING_SWEEP = """
import os, signal, sys, time
from pathlib import Path
from mrd_env.executor import Task, run_tasks

def block(folder, stubborn):
    Path(folder, f"worker.{os.getpid()}").write_text("blocking")
    try:
        time.sleep(10 ** 6)
    except KeyboardInterrupt:  # the stop: a task saves what it has (a training run: the agent so far)
        Path(folder, f"saved.{os.getpid()}").write_text("saved")
        if stubborn:  # ... or will not stop
            time.sleep(10 ** 6)
        raise

def on_term(signum, frame):
    raise KeyboardInterrupt

if __name__ == "__main__":
    if sys.argv[2] != "-":
        signal.signal(signal.SIGTERM, on_term)
    try:
        run_tasks([Task(block, (sys.argv[1], sys.argv[2] == "stubborn")) for _ in range(2)], backend="pool", jobs=2,
                  progress=False)
    except KeyboardInterrupt:
        sys.exit(143)
"""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


def _until(predicate, seconds: float) -> bool:
    import time

    end = time.monotonic() + seconds
    while time.monotonic() < end and not predicate():
        time.sleep(0.05)
    return predicate()


@pytest.mark.hostile
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the processes from /proc")
@pytest.mark.parametrize("stop", ["SIGTERM handled", "SIGTERM stubborn", "SIGKILL"])
def test_a_stopped_pool_leaves_no_worker_running(tmp_path, stop):
    """SIGTERM (routed to KeyboardInterrupt, as mrd-env does) while the tasks block in the workers: the sweep ends
    at once, each task interrupted where it is (it saves what it has), and a task that will not stop is killed after
    the grace (ProcessPoolExecutor waits for running tasks: score kept running 596 s); SIGKILL of the parent: the
    kernel kills the workers (PR_SET_PDEATHSIG), none is left blocking on its own."""
    from mrd_env.executor import STOP_GRACE

    import os
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "sweep.py"
    script.write_text(BLOCKING_SWEEP)
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path), stop.split()[1] if " " in stop else "-"],
                            env={**os.environ, "PYTHONPATH": str(root)}, stderr=subprocess.PIPE)
    workers: list[int] = []
    try:
        assert _until(lambda: len(list(tmp_path.glob("worker.*"))) == 2, 120), proc.stderr.read1().decode()
        workers = [int(p.suffix[1:]) for p in tmp_path.glob("worker.*")]
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM if "SIGTERM" in stop else signal.SIGKILL)
        code = proc.wait(timeout=30)
        assert code == (143 if "SIGTERM" in stop else -signal.SIGKILL), proc.stderr.read().decode()
        assert _until(lambda: not any(map(_alive, workers)), 10), [w for w in workers if _alive(w)]
        took = time.monotonic() - t0
        if stop == "SIGTERM handled":
            assert took < 3, f"{took:.1f} s"
            assert sorted(p.suffix for p in tmp_path.glob("saved.*")) == sorted(f".{w}" for w in workers)
        else:
            assert took < STOP_GRACE + 5, f"{took:.1f} s"
    finally:
        for w in workers:
            if _alive(w):
                os.kill(w, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()


def exits(code):
    import sys

    sys.exit(code)


def interrupts():
    raise KeyboardInterrupt


@pytest.mark.hostile
@pytest.mark.parametrize("task, raised", [(Task(exits, (0,)), r"SystemExit\(0\)"),
                                          (Task(interrupts), "KeyboardInterrupt")])
def test_a_task_exiting_in_a_worker_fails_as_a_task_not_as_the_caller(task, raised):
    """sys.exit(0) in a pool's task raised SystemExit(0) in the caller: mrd-env exited 0 with nothing written."""
    with pytest.raises(TaskFailed, match=raised):
        run_tasks([task, Task(draw, (1,))], backend="pool", jobs=2, progress=False, retry=False)
