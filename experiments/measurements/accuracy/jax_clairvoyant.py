"""The clairvoyant optimum by gradient (:func:`mrd_env.jax.clairvoyant.clairvoyant` through the plant's JAX twin,
:mod:`mrd_env.jax.env`, differentiable scheme) on the episodes of a suite (default ``car-comfort-v1``), against the
suite's stored R_c (the CasADi path, :func:`mrd_env.optimal.clairvoyant`), both re-simulated in the native
environment.

``nice -n 10 python -m experiments.measurements.accuracy.jax_clairvoyant [--suite ID] [--per-scenario K] [--starts N]
[--out results/bench]`` (CPU; needs ``pip install mrd-env[jax]``). The procedure is the references' (1 ms commands,
the warm laws of the suite's procedure at 1 ms and the best of its 17 constant commands, the optimiser from the
``--starts`` best, 10 ms blocks then 1 ms); writes ``<out>/jax_clairvoyant[-<suite>].json`` after each episode and prints a
table. The stored wall time is the references' ``clairvoyant_s`` (its solves, compilation from the cache).
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

SUITE = "car-comfort-v1"


def episode(suite, scenario, seed: int, n_starts: int, scheme_options: dict) -> dict:
    from experiments.benchmark.yardstick import warm_starts
    from experiments.benchmark.references import STEP, best_constant
    from mrd_env.jax.clairvoyant import clairvoyant
    from mrd_env.jax import env as je
    from mrd_env.optimal import episode_problem

    opts = suite.reference_options(scenario, seed)
    problem = episode_problem(suite.env_id, seed=int(seed), control_dt=STEP, **opts)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    rp, vp = best_constant(problem)
    starts = warm_starts(problem, suite.procedure["warm_laws"], agents=())
    starts["best constant"] = np.full((problem.n_steps, problem.nd), vp)
    t1 = time.perf_counter()
    params = je.params_of_problem(problem, scheme="differentiable", **scheme_options)
    _, s0 = je.reset(None, params, record=0)
    cv = clairvoyant(je.episode_return, lambda V: problem.replay(V).ret, starts,
                     problem.v_min, problem.v_max, data=(params, s0), n_starts=n_starts)
    label = scenario.label(seed)
    ref = suite.references[label]
    stored = suite.procedure.get("episodes", {}).get(label, {})
    return {"episode": label, "R_p": float(rp), "R_c_casadi": float(ref.clairvoyant), "R_gradient": cv.ret,
            "difference": cv.ret - float(ref.clairvoyant), "source": cv.source,
            "warm_returns": cv.warm_returns, "solves": [vars(s) for s in cv.solves],
            "wall_warm_starts_s": round(t1 - t0, 2), "wall_gradient_s": round(cv.wall_time, 2),
            "compile_s": round(cv.compile_seconds, 2),
            "wall_casadi_s": stored.get("wall", {}).get("clairvoyant_s"),
            "casadi_solves": stored.get("solves"), "casadi_load": stored.get("load_average"),
            "load_before": round(load0, 2), "load_after": round(os.getloadavg()[0], 2)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default=SUITE, help=f"a shipped suite's id (default {SUITE})")
    ap.add_argument("--per-scenario", type=int, default=0, help="the first K episodes of each scenario (0: all)")
    ap.add_argument("--starts", type=int, default=2, help="warm starts the optimiser runs from (the references: 2)")
    ap.add_argument("--newton-iterations", type=int, default=2)
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    if a.per_scenario < 0 or a.starts < 1:
        ap.exit(2, "bench_jax_clairvoyant: --per-scenario must be >= 0 and --starts >= 1\n")
    from mrd_env import storage
    from mrd_env.suites import suite

    try:
        s = suite(a.suite)
    except ValueError as exc:
        ap.exit(2, f"bench_jax_clairvoyant: {exc}\n")
    out = Path(a.out) / ("jax_clairvoyant.json" if s.id == SUITE else f"jax_clairvoyant-{s.id}.json")
    rows = []
    meta = {"suite": s.id, "starts": a.starts, "newton_iterations": a.newton_iterations, "cpus": os.cpu_count(),
            "platform": platform.platform(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    for sc in s.scenarios:
        for seed in (sc.seeds[:a.per_scenario] if a.per_scenario else sc.seeds):
            r = episode(s, sc, seed, a.starts, {"newton_iterations": a.newton_iterations})
            rows.append(r)
            storage.write_json(out, {**meta, "episodes": rows}, indent=1)
            print(f"| {r['episode']} | {r['R_c_casadi']:.5f} | {r['R_gradient']:.5f} | {r['difference']:+.5f} | "
                  f"{r['source']} | {r['wall_casadi_s']} | {r['wall_gradient_s']:.1f} ({r['compile_s']:.1f}) | "
                  f"{r['load_before']} / {r['load_after']} |", flush=True)


if __name__ == "__main__":
    main()
