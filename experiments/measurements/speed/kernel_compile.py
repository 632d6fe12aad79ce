"""Where a damper model's kernel compilation goes, and what calling the model through a function pointer would cost
(issue 52, item 5: the test suite's cold time is mostly these compilations).

Run: ``python -m experiments.measurements.speed.kernel_compile [--models bingham,dahl,spencer_dyke]
[--calls 2000000] [--repeats 3] [--out results/bench/kernel_compile.json]``

1. **Compilation, per model**: a fresh process with an empty cache folder (``MRD_ENV_CACHE_DIR``,
   ``MRD_ENV_FIRST_USE=wait``) makes a quarter car with the model and takes one reset and one step. Recorded: the
   wall seconds of that first reset and step, and numba's own timers of each level of the generated kernel
   (:mod:`mrd_env.stepping.codegen`): ``core_reset``; ``run_systems`` → ``_advance_one`` → ``macro_step`` →
   ``sdirk_step``, each level's seconds *including* the levels it calls (numba links a callee's code into its
   caller and optimises and generates machine code for the whole again), and of that the part spent in LLVM.
   A model without internal states (Bingham) next to one with two (Spencer–Dyke) shows how much of it is the
   model's own code.
2. **The call probe**: ns per iteration of a compiled loop that calls a model's ``rhs`` and ``force_law`` once
   each, (a) compiled for the model, its functions compile-time constants that LLVM inlines (the kernel inlines them
   at numba's level), and (b) through numba first-class function pointers (``numba.types.FunctionType``: one
   compiled loop serves every model), same run, median of ``--repeats``;
   both loops must return the same number bit for bit.

Writes the JSON atomically and prints one line per figure, with the load average.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.measurements import load_average, refusing

#: The kernel's levels, each compiled as its own numba function (callers after callees).
LEVELS = ("core_reset", "sdirk_step", "macro_step", "_advance_one", "run_systems")


def compile_child(model: str) -> dict:
    """In this (fresh) process: the first reset and step of a quarter car with ``model``, timed, and numba's timers
    of each kernel level (seconds: total, LLVM)."""
    import gymnasium as gym

    from mrd_env import envs  # noqa: F401  (registers the environments)
    from mrd_env.dampers import damper_class
    from mrd_env.stepping.codegen import kernel_module

    t0 = time.perf_counter()
    env = gym.make("mrd_env/QuarterCar-v1", damper=model, episode_seconds=0.01)
    env.reset(seed=0)
    env.step(env.action_space.low)
    wall = time.perf_counter() - t0
    kernel = kernel_module(damper_class(model), compiled=True)
    levels = {}
    for name in LEVELS:
        (cres,) = getattr(kernel, name).overloads.values()
        timers = cres.metadata.get("timers", {})
        levels[name] = {"total_s": round(timers.get("compiler_lock", float("nan")), 2),
                        "llvm_s": round(timers.get("llvm_lock", float("nan")), 2)}
    return {"model": model, "n_states": damper_class(model)().n_states, "first_reset_and_step_s": round(wall, 2),
            "levels": levels}


def compile_cost(model: str) -> dict:
    """:func:`compile_child` in a fresh interpreter with an empty cache folder."""
    with tempfile.TemporaryDirectory(prefix="mrd_env_kernel_compile_") as cache:
        env = dict(os.environ, MRD_ENV_CACHE_DIR=cache, MRD_ENV_FIRST_USE="wait")
        load = load_average()
        done = subprocess.run([sys.executable, "-m", __spec__.name, "--child", model], env=env, check=True,
                              capture_output=True, text=True)
    row = json.loads(done.stdout.strip().splitlines()[-1])
    row["load_average"] = load
    return row


def call_probe(model: str, calls: int, repeats: int) -> dict:
    """ns per iteration of rhs + force, compiled for the model against through function pointers (same run, median)."""
    import numba as nb
    from numba import types

    from mrd_env.dampers import damper_class

    cls = damper_class(model)
    d = cls()
    A = types.float64[::1]
    sig_rhs = types.void(A, A, types.float64, types.float64, types.float64, A)
    sig_force = types.float64(A, A, types.float64, types.float64, types.float64, types.float64)
    rhs_py, force_py = cls.rhs.py_func, cls.force_law.py_func

    def loop(rhs, force, p, s, g, n):
        acc = 0.0
        for i in range(n):
            x = 1e-3 * (i % 17)
            v = 0.01 * (i % 13)
            rhs(p, s, x, v, 1.0, g)
            acc += force(p, s, x, v, 0.0, 1.0) + g[0]
        return acc

    # (a) numba functions as arguments: compile-time constants, the loop compiled for this model and its calls
    # inlined by LLVM; (b) function pointers: one compiled loop for every model, each call through the pointer
    specialised = nb.njit(loop)
    pointers = nb.njit(types.float64(types.FunctionType(sig_rhs), types.FunctionType(sig_force), A, A, A,
                                     types.int64))(loop)
    rhs_in, force_in = nb.njit(rhs_py), nb.njit(force_py)

    def inlined(p, s, g, n):
        return specialised(rhs_in, force_in, p, s, g, n)

    rhs_fp, force_fp = nb.njit(sig_rhs)(rhs_py), nb.njit(sig_force)(force_py)
    p = d.params.as_array()
    s = d.initial_state().astype(np.float64)
    g = np.zeros(max(1, d.n_states))
    inlined(p, s.copy(), g, 10)
    pointers(rhs_fp, force_fp, p, s.copy(), g, 10)
    t_in, t_fp = [], []
    for _ in range(repeats):
        s1, s2 = s.copy(), s.copy()
        t0 = time.perf_counter()
        a = inlined(p, s1, g, calls)
        t_in.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        b = pointers(rhs_fp, force_fp, p, s2, g, calls)
        t_fp.append(time.perf_counter() - t0)
        if a != b:
            raise RuntimeError(f"{model}: the two loops differ ({a!r} against {b!r})")
    ns_in = float(np.median(t_in)) / calls * 1e9
    ns_fp = float(np.median(t_fp)) / calls * 1e9
    return {"model": model, "inlined_ns": round(ns_in, 2), "pointer_ns": round(ns_fp, 2),
            "per_call_ns": round((ns_fp - ns_in) / 2, 2), "same_bits": True, "load_average": load_average()}


def main(argv=None) -> int:
    """The command line: exit 2 with one line on stderr for a refused option, before anything is measured."""
    return refusing("kernel_compile", _main, argv)


def _main(argv) -> int:
    from mrd_env.dampers import available_dampers
    from mrd_env.storage import write_json

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="bingham,dahl,spencer_dyke")
    ap.add_argument("--calls", type=int, default=2_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("results/bench/kernel_compile.json"))
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child is not None:
        print(json.dumps(compile_child(a.child)))
        return 0
    models = [m for m in a.models.split(",") if m]
    unknown = [m for m in models if m not in available_dampers()]
    if not models or unknown:
        raise ValueError(f"--models must name damper models among {sorted(available_dampers())}, got {a.models!r}")
    if not 1_000 <= a.calls <= 100_000_000:
        raise ValueError(f"--calls must be in [1000, 100000000], got {a.calls}")
    if not 1 <= a.repeats <= 20:
        raise ValueError(f"--repeats must be in [1, 20], got {a.repeats}")
    out = {"cpus": os.cpu_count(), "load_start": load_average(), "compile": [], "call_probe": []}
    for m in models:
        row = compile_cost(m)
        out["compile"].append(row)
        lv = row["levels"]
        print(f"{m} ({row['n_states']} states): first reset and step {row['first_reset_and_step_s']} s; "
              + ", ".join(f"{k} {v['total_s']} s (LLVM {v['llvm_s']})" for k, v in lv.items())
              + f"; load {row['load_average']}", flush=True)
        write_json(a.out, out, indent=1)
    for m in models:
        row = call_probe(m, a.calls, a.repeats)
        out["call_probe"].append(row)
        print(f"{m}: rhs + force {row['inlined_ns']} ns inlined, {row['pointer_ns']} ns through pointers "
              f"({row['per_call_ns']} ns per call); load {row['load_average']}", flush=True)
        write_json(a.out, out, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
