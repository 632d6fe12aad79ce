"""What a suite's build costs per unit, before it is started (issue 51: plan a build that fits the time it has).

Run: ``nice -n 5 python -m experiments.measurements.speed.build_cost --spec SPEC [--episodes LABEL ...]
[--batch 2,56] [--repeats 3] [--out results/bench/build_cost_<suite id>.json]``

For the suite spec ``SPEC`` (shipped or pending; procedure 3 or later), on this machine, the two costs a build is
made of (``experiments.benchmark.references``):

1. **The gradient path's batched round 1**: one value-and-gradient evaluation of the JAX twin's episode return
   (the batched solver's unit of work: every L-BFGS iteration makes one or more) over a batch of ``B`` rows (an
   episode's start each, the suite's own episodes in turn), for each ``B`` of ``--batch``: seconds per evaluation
   and per row (median of ``--repeats``, compilation timed apart). A round 1 costs about its iterations times this;
   its iterations are only known once it has run (the build record has them).
2. **The CasADi path's round 1** on each episode of ``--episodes`` (labels; default: each scenario's first
   episode): the build's own call (``certify.casadi_path`` from the procedure's ``N_STARTS`` best warm starts),
   wall seconds and the solver's iterations and evaluations.

The load average is recorded around each part. Writes the JSON atomically and prints one line per figure.
"""
from __future__ import annotations

import argparse
import os
import resource
import time
from pathlib import Path

import numpy as np

from experiments.measurements import load_average, refusing


def evaluation_cost(problems, batch: int, repeats: int) -> dict:
    """Seconds of one jitted, vmapped value-and-gradient of the episode return over ``batch`` rows (the problems'
    best-constant commands, cycling through the problems)."""
    import jax

    from experiments.benchmark.references import best_constant
    from mrd_env.jax import env as je
    from mrd_env.jax.clairvoyant import episode_batch

    rows = [problems[i % len(problems)] for i in range(batch)]
    eb = episode_batch(rows, scheme="differentiable")
    V = eb.pad([np.full((p.n_steps, p.nd), best_constant(p)[1]) for p in rows])
    f = jax.jit(jax.vmap(jax.value_and_grad(je.episode_return)))
    t0 = time.perf_counter()
    jax.block_until_ready(f(V, eb.data))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(V, eb.data))
        times.append(time.perf_counter() - t0)
    s = float(np.median(times))
    return {"rows": batch, "compile_and_first_s": round(first, 2), "evaluation_s": round(s, 4),
            "per_row_s": round(s / batch, 4), "repeats": times, "load_average": load_average(),
            "max_rss_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 2)}


def casadi_cost(problem, warm_laws) -> dict:
    """The CasADi path's round 1 on one episode, as the build calls it."""
    from experiments.benchmark.certify import casadi_path
    from experiments.benchmark.references import N_STARTS, episode_starts

    _, _, starts = episode_starts(problem, warm_laws)
    load0, t0 = load_average(), time.perf_counter()
    r = casadi_path(problem, starts, N_STARTS)
    wall = time.perf_counter() - t0
    runs = r.runs
    return {"wall_s": round(wall, 1), "return": float(r.ret),
            "iterations": int(sum(x.get("iterations", 0) for x in runs)),
            "evaluations": int(sum(x.get("evaluations", 0) for x in runs)),
            "statuses": [x.get("status") for x in runs], "load_average": [load0, load_average()]}


def main(argv=None) -> int:
    """The command line: exit 2 with one line on stderr for a refused option, before anything is measured."""
    return refusing("build_cost", _main, argv)


def _main(argv) -> int:
    from mrd_env.plants import plant, suite_spec
    from mrd_env.storage import write_json
    from mrd_env.suites import draws

    from experiments.benchmark.references import episode_problem

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", type=Path, required=True)
    ap.add_argument("--episodes", nargs="*", default=None, help="labels (default: each scenario's first episode)")
    ap.add_argument("--batch", default="2,56", help="batch sizes (rows) of the evaluation's cost")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--parts", default="gradient,casadi")
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    try:
        batches = [int(x) for x in a.batch.split(",") if x]
        if not batches or min(batches) < 1 or max(batches) > 128:
            raise ValueError
    except ValueError:
        raise ValueError(f"--batch must be comma-separated ints in [1, 128] (each row holds its episode's "
                         f"gradient tape in memory), got {a.batch!r}") from None
    if not 1 <= a.repeats <= 20:
        raise ValueError(f"--repeats must be in [1, 20], got {a.repeats}")
    parts = set(a.parts.split(","))
    if not parts <= {"gradient", "casadi"}:
        raise ValueError(f"--parts must name gradient and/or casadi, got {a.parts!r}")
    name, env_id, definition = suite_spec(a.spec)
    if definition.procedure < 3:
        raise ValueError(f"--spec: procedure {definition.procedure} has no batched round 1 (3 or more)")
    suite = definition.suite(name, env_id, draws(definition, env_id))
    eps = suite.episodes()
    labels = {sc.label(s): (sc, s) for sc, s in eps}
    chosen = a.episodes if a.episodes is not None else [sc.label(sc.seeds[0]) for sc in suite.scenarios]
    unknown = [x for x in chosen if x not in labels]
    if unknown:
        raise ValueError(f"--episodes: no episode {unknown[0]!r} in {suite.id}")
    problems = [episode_problem(env_id, suite.reference_options(sc, s), s, suite.control_dt) for sc, s in eps]
    out = {"suite": suite.id, "episodes": len(eps), "control_dt": suite.control_dt, "cpus": os.cpu_count(),
           "load_start": load_average(), "gradient_evaluation": [], "casadi_round_1": {}}
    path = a.out or Path("results/bench") / f"build_cost_{suite.id}.json"
    if "gradient" in parts:
        for b in batches:
            row = evaluation_cost(problems, b, a.repeats)
            out["gradient_evaluation"].append(row)
            print(f"{suite.id}: gradient evaluation over {b} rows: {row['evaluation_s']:.3f} s "
                  f"({row['per_row_s'] * 1e3:.1f} ms per row; compile and first {row['compile_and_first_s']} s; "
                  f"load {row['load_average']})", flush=True)
            write_json(path, out, indent=1)
    if "casadi" in parts:
        warm = tuple(plant(name).profile.warm_laws)
        for label in chosen:
            sc, s = labels[label]
            row = casadi_cost(problems[eps.index((sc, s))], warm)
            out["casadi_round_1"][label] = row
            print(f"{suite.id}: CasADi round 1 on {label}: {row['wall_s']} s, {row['iterations']} iterations, "
                  f"{row['evaluations']} evaluations (load {row['load_average']})", flush=True)
            write_json(path, out, indent=1)
    out["load_end"] = load_average()
    write_json(path, out, indent=1)
    print(f"written {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
