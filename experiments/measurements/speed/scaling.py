"""Wall time of the sweeps serially, on a local process pool (1 and 2 workers) and on a local Ray instance (2
workers), on this machine: the benchmark (every law on the published plants' nominal suites, car-comfort-v1 and
building-seismic-v1), training several seeds, a model comparison on a synthetic record, and a Monte-Carlo
sensor-error propagation. Each configuration's result is
checked to equal the serial one.

    python -m experiments.measurements.speed.scaling [--train-steps 100000] [--out results/scaling]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode

CONFIGS = (("serial", None), ("pool", 1), ("pool", 2), ("ray", 2))


#: The benchmark's sweep: the published plants' nominal suites.
SUITES = ("car-comfort-v1", "building-seismic-v1")


def _benchmark(backend, jobs):
    from controllers import available_controllers

    from experiments.benchmark.run import run_benchmark, shipped_controllers
    from mrd_env.suites import suite

    laws = {c["name"] for sid in SUITES for c in shipped_controllers(suite(sid))
            if c["controller"] in available_controllers() and c["controller"] != "mpc"}
    bench = run_benchmark(SUITES, only=laws, backend=backend, jobs=jobs)
    return [(e.suite.id, s.name, tuple(x["return"] for x in s.result.episodes)) for e in bench.suites for s in e.scored]


def _train(backend, jobs, steps):
    from mrd_env.plants.quarter_car.profile import PROFILE as QUARTER_CAR

    from experiments.commands.train import train
    from experiments.training.trainers import env_options, hyperparameters

    with tempfile.TemporaryDirectory() as d:
        folders = train(QUARTER_CAR, "ppo", [0, 1], out=Path(d), timesteps=steps, eval_freq=0,
                        hyper=hyperparameters("ppo", QUARTER_CAR.env_id), env_kwargs=env_options(QUARTER_CAR),
                        backend=backend, jobs=jobs)
        from controllers import load_agent
        return [np.concatenate([v.numpy().ravel() for v in load_agent(f).model.policy.state_dict().values()])
                .tobytes() for f in folders]


def _record():
    from mrd_env.dampers import make_damper
    from mrd_env.rig import random_test

    return random_test(make_damper("spencer_dyke", "spencer1997"), 0.004, 8.0, 20.0, switch_rate=2.0, rng=0)


def _compare(backend, jobs):
    from mrd_env.identification import compare_models

    out = compare_models([_record()], ["bingham", "bouc_wen", "spencer_dyke", "hyperbolic_tangent", "dahl", "lugre",
                                       "sigmoid", "bi_viscous"],
                         search={"maxiter": 100, "progress": False}, plot_window=None, backend=backend, jobs=jobs)
    return [(m.model, None if m.fit is None else m.validation_overall.get("E_t")) for m in out.models]


def _propagate(backend, jobs):
    from mrd_env.identification.propagate import propagate_sensor_errors

    res = propagate_sensor_errors("bouc_wen", n_draws=16, rng=0, free=["c0a", "alpha_b", "gamma", "beta"],
                                  search={"maxiter": 100, "progress": False}, progress=False, backend=backend,
                                  jobs=jobs)
    return {k: v.tobytes() for k, v in res.mc.samples.items()}


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--train-steps", type=int, default=100_000)
    p.add_argument("--out", type=Path, default=Path("results/scaling"))
    p.add_argument("--sweeps", nargs="+", default=["benchmark", "train", "compare-models", "propagate"])
    args = p.parse_args(argv)
    import mrd_env  # noqa: F401

    sweeps = {"benchmark": _benchmark, "train": lambda b, j: _train(b, j, args.train_steps),
              "compare-models": _compare, "propagate": _propagate}
    rows = []
    for name in args.sweeps:
        ref = sweeps[name]("serial", None)  # untimed: compiles or loads every kernel the sweep uses, in this process
        for backend, jobs in CONFIGS:
            t0 = time.perf_counter()
            result = sweeps[name](backend, jobs)
            wall = time.perf_counter() - t0
            rows.append({"sweep": name, "backend": backend, "workers": jobs or 1, "wall_s": wall,
                         "speed_up": np.nan, "same_result": result == ref})
        base = next(r["wall_s"] for r in rows if r["sweep"] == name and r["backend"] == "serial")
        for r in rows:
            if r["sweep"] == name:
                r["speed_up"] = base / r["wall_s"]
        print(rows[-4:], flush=True)
    md, _ = write_table(rows, args.out / "scaling", floatfmt=".3g",
                        title="Sweeps on this machine (2 cores): wall time and speed-up over serial")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
