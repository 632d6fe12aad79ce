"""First use without waiting for the compiler (issue 25, :mod:`mrd_env.stepping.first_use`): the interpreted
kernel is the compiled kernel bit for bit, a switch in the middle of an episode changes nothing, the background
compilation leaves its marker, and a failed one falls back to compiling in the process."""
import os
import sys
import time

import gymnasium as gym
import numpy as np
import pytest

import mrd_env  # noqa: F401
from mrd_env.dampers import available_dampers, damper_class
from mrd_env.stepping import codegen, first_use
from mrd_env.stepping.codegen import kernel_module, kernel_path, kernel_source
from mrd_env.stepping.first_use import SwitchingKernel


def _episode(model, steps, *, switch_at=None, marker=None, seed=3):
    """Observations and rewards of a noisy QuarterCarPhysical-v0 episode under random commands; with ``marker``, the
    ready marker is created before step ``switch_at``."""
    env = gym.make("mrd_env/QuarterCarPhysical-v0", damper=model, episode_seconds=30.0,
                   sensor_noise={"sprung_acc": 0.05, "travel": 1e-4}).unwrapped
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    obs, rewards, compiled = [], [], []
    for i in range(steps):
        if marker is not None and i == switch_at:
            marker.write_text("")
        o, r, *_ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
        obs.append(o.copy())
        rewards.append(r)
        compiled.append(getattr(env.core.driver.kernel, "compiled", True))
    return np.array(obs), np.array(rewards), compiled


def _switching(monkeypatch, tmp_path, model, *, name=None):
    """A SwitchingKernel for ``model`` whose marker lives in ``tmp_path``, installed as the model's kernel."""
    cls = damper_class(model)
    fake = tmp_path / kernel_path(cls).name
    monkeypatch.setattr(cls, "python_functions", None)  # before the stand-in sets them: restored to None after
    source, key = kernel_source(cls)
    k = SwitchingKernel(cls, fake, source, lambda: codegen.load_generated_module(codegen.kernel_prefix(cls), source, key),
                        model_name=name)
    monkeypatch.setitem(codegen._KERNELS, cls, k)
    return k, first_use.ready_marker(fake)


@pytest.mark.parametrize("model", available_dampers())
def test_an_episode_that_switches_to_the_compiled_kernel_is_the_compiled_episode(model, monkeypatch, tmp_path):
    """30 steps interpreted, the marker appears, 10 more compiled: the same observations and rewards bit for bit
    as the compiled kernel all along (sensor noise included: the generator's uint64 wrap-around; the plant's
    static force computed by the model's Python functions)."""
    oc, rc, _ = _episode(model, 40)
    monkeypatch.setattr(SwitchingKernel, "_start_compiler", lambda self: None)
    k, marker = _switching(monkeypatch, tmp_path, model)
    oi, ri, compiled = _episode(model, 40, switch_at=30, marker=marker)
    assert compiled == [False] * 30 + [True] * 10
    assert np.array_equal(oc, oi) and np.array_equal(rc, ri)
    assert np.ptp(oc[:, 0]) > 0  # the episode moves: not two constant sequences
    assert damper_class(model).python_functions is None  # switched: the model's compiled functions again


def _vector_run(steps, markers=()):
    """Observations of a threaded 64-env QuarterCar-v1 batch (``core_step_parallel``) under seeded random
    commands; ``markers`` (step, path) are created before those steps."""
    venv = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=64, vectorization_mode="vector_entry_point",
                        damper="spencer_dyke", episode_seconds=1.0, threads=2)
    venv.reset(seed=5)
    rng = np.random.default_rng(5)
    out = []
    for i in range(steps):
        for at, path in markers:
            if at == i:
                path.write_text("")
        out.append(venv.step(rng.uniform(venv.action_space.low, venv.action_space.high))[0].copy())
    venv.close()
    return np.array(out)


def test_the_serial_entries_switch_first_and_the_threaded_step_at_the_final_marker(monkeypatch, tmp_path):
    """The background process marks the serial entry points ready before it compiles the threaded step: a
    threaded batch switches at the final marker only, and matches the compiled batch bit for bit throughout."""
    reference = _vector_run(6)
    monkeypatch.setattr(SwitchingKernel, "_start_compiler", lambda self: None)
    k, marker = _switching(monkeypatch, tmp_path, "spencer_dyke")
    serial = first_use.ready_marker(marker.with_suffix("").with_suffix(".py"), "serial")
    _episode("spencer_dyke", 1)
    assert not k.compiled
    serial.write_text("")
    _episode("spencer_dyke", 1)
    assert k.compiled and not k._late_compiled  # the scalar step runs compiled, the threaded one not yet
    assert np.array_equal(_vector_run(6, markers=[(3, marker)]), reference)
    assert k._late_compiled


def test_the_default_first_use_interprets_and_a_background_process_compiles(monkeypatch, tmp_path):
    """Without the marker, ``kernel_module`` returns a SwitchingKernel and starts ``python -m mrd_env.warmup``,
    which leaves the marker and removes its lock; the kernel then switches. (The suite runs with
    MRD_ENV_FIRST_USE=wait; the numba cache already holds the kernel here, so the child only loads it.)"""
    cls = damper_class("spencer_dyke")
    _episode("spencer_dyke", 2)  # compiled in this process (wait mode): the child finds numba's cache warm
    path = kernel_path(cls)
    marker = first_use.ready_marker(path)
    marker.unlink(missing_ok=True)
    first_use.ready_marker(path, "serial").unlink(missing_ok=True)
    monkeypatch.setenv(first_use.MODE_VARIABLE, "interpret")
    monkeypatch.delitem(codegen._KERNELS, cls)
    monkeypatch.setattr(cls, "python_functions", None)  # restored after the test
    k = kernel_module(cls)
    assert isinstance(k, SwitchingKernel) and not k.compiled and k._proc is not None
    lock = path.with_suffix(".compiling")
    assert lock.exists()
    monkeypatch.setitem(codegen._KERNELS, cls, k)
    t0 = time.monotonic()
    _, _, compiled = _episode("spencer_dyke", 5)
    assert not compiled[0]  # the first step did not wait for the compiler
    while not k.compiled and time.monotonic() - t0 < 300:
        _episode("spencer_dyke", 5)
        time.sleep(0.2)
    assert k.compiled, path.with_suffix(".log").read_text()
    assert k._proc.wait(timeout=60) == 0
    assert marker.exists() and not lock.exists()
    assert cls.python_functions is None  # the model's static force is compiled again
    assert k.settled is not None and kernel_module(cls) is k.settled  # later drivers take the compiled module
    assert codegen._KERNELS[cls] is k.settled and k.run_systems is k.settled.run_systems  # so do earlier ones


def test_a_failed_background_compilation_falls_back_to_compiling_here(monkeypatch, tmp_path):
    """The child fails (an unknown model): the next call after it exits warns, naming the failure, and compiles
    in the process; the episode goes on."""
    k, marker = _switching(monkeypatch, tmp_path, "spencer_dyke", name="no_such_model")
    assert k._proc is not None
    k._proc.wait(timeout=120)
    k._next_check = 0.0
    with pytest.warns(RuntimeWarning, match="background compilation of the no_such_model kernel failed"):
        _, _, compiled = _episode("spencer_dyke", 3)
    assert compiled[-1] and not marker.exists()


def test_a_lock_left_by_a_dead_process_is_taken_over(monkeypatch, tmp_path):
    started, dead = [], _dead_pid()
    monkeypatch.setattr(first_use.subprocess, "Popen", lambda *a, **kw: started.append(a) or _FakeProc())
    cls = damper_class("spencer_dyke")
    fake = tmp_path / kernel_path(cls).name
    lock = fake.with_suffix(".compiling")
    lock.write_text(str(dead))
    monkeypatch.setattr(cls, "python_functions", None)
    SwitchingKernel(cls, fake, kernel_source(cls)[0], lambda: None)
    assert len(started) == 1 and lock.read_text() == str(_FakeProc.pid)
    lock.write_text(str(os.getpid()))  # a live process holds it: no second compilation
    SwitchingKernel(cls, fake, kernel_source(cls)[0], lambda: None)
    assert len(started) == 1


def test_the_mode_is_checked(monkeypatch):
    monkeypatch.setenv(first_use.MODE_VARIABLE, "soon")
    with pytest.raises(ValueError, match=r"MRD_ENV_FIRST_USE must be one of \('interpret', 'wait'\), got 'soon'"):
        first_use.mode()
    monkeypatch.setenv(first_use.MODE_VARIABLE, "interpret")
    with pytest.raises(ValueError, match="mode must be one of"):
        first_use.set_mode("soon")
    assert os.environ[first_use.MODE_VARIABLE] == "interpret"  # a refused call changes nothing


class _FakeProc:
    pid = 424242

    def poll(self):
        return None


def _dead_pid() -> int:
    import subprocess

    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_a_building_is_made_without_scipy_signal_and_a_car_builds_its_weighting_with_it():
    """scipy.signal (about 1 s of import) is imported only where a weighting or the Kanai–Tajimi noise is built: a
    fresh process makes a building without it, and the quarter car's comfort weighting loads it (``make`` compiles
    nothing: no kernel is needed for this)."""
    import subprocess

    code = ("import sys, gymnasium as gym, mrd_env\n"
            "for env_id in sys.argv[1:]:\n"
            "    gym.make(env_id)\n"
            "    print('scipy.signal' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code, "mrd_env/ShearBuilding-v1", "mrd_env/QuarterCar-v1"],
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True"]
