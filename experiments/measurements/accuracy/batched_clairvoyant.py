"""The clairvoyant of a suite's episodes solved together (:func:`mrd_env.jax.clairvoyant.batched_clairvoyant`, issue
52, item 3) against the two per-episode paths of the certification (:mod:`experiments.benchmark.certify`): the
gradient path (:func:`mrd_env.jax.clairvoyant.clairvoyant`, scipy's L-BFGS-B from the host, one episode at a time)
and the CasADi path (:func:`mrd_env.optimal.clairvoyant`), on the same episodes at the suite's 10 ms control step,
from the same start (each episode's best constant command), each result re-simulated in the native environment.

``nice -n 10 python -m experiments.measurements.accuracy.batched_clairvoyant [--suite car-comfort-v1]
[--per-scenario 3] [--paths batched,gradient,casadi] [--out results/bench/batched_clairvoyant.json]``
(needs ``pip install mrd-env[jax]``). Prints a Markdown table per episode (the returns, the batch's shortfall from
the per-episode gradient path's return as a share of the episode's range R_c − R_p, R_c the best of the paths) and
the wall and CPU times of each path (compilation apart), with the load average; writes the JSON (atomically).
The coarse level is the certification's (50 ms blocks), the stop rules the paths' own.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

SUITE = "car-comfort-v1"
#: The suites' control step (s) at which the references are certified.
STEP = 0.01
#: The certification's coarse level (s).
COARSE = 0.05
#: Share of an episode's range R_c − R_p within which the batch must reach the per-episode gradient path.
TOLERANCE = 0.005


def load_average() -> float:
    return round(os.getloadavg()[0], 2)


def suite_problems(suite_id: str, per_scenario: int, *, seconds: float | None = None) -> list:
    """[(label, problem, R_p, start)] of the first ``per_scenario`` episodes of each scenario of the suite at
    :data:`STEP` (``seconds``: each episode cut to that length), the start each episode's best constant command."""
    from experiments.benchmark.references import best_constant
    from mrd_env.optimal import episode_problem
    from mrd_env.suites import suite

    s = suite(suite_id)
    out = []
    for sc in s.scenarios:
        for seed in sc.seeds[:per_scenario]:
            opts = s.reference_options(sc, seed)
            if seconds is not None:
                opts = {**opts, "episode_seconds": seconds}
            p = episode_problem(s.env_id, seed=int(seed), control_dt=STEP, **opts)
            r_p, v = best_constant(p)
            out.append((sc.label(seed), p, float(r_p), np.full((p.n_steps, p.nd), v)))
    return out


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def solve_batched(episodes) -> dict:
    """The batch's solve: {returns (native), model_returns, status, success, iterations, evaluations, wall_s,
    cpu_s, compile_s, build_s}."""
    import jax

    from mrd_env.jax import env as je
    from mrd_env.jax.clairvoyant import batched_clairvoyant, episode_batch

    p0 = episodes[0][1]
    w0, c0 = _clock()
    batch = episode_batch([p for _, p, _, _ in episodes], scheme="differentiable")
    build = time.perf_counter() - w0
    w1, c1 = _clock()
    res = batched_clairvoyant(je.episode_return, batch.data, batch.pad([V for *_, V in episodes]), p0.v_min,
                              p0.v_max, coarse=(int(round(COARSE / STEP)),))
    w2, c2 = _clock()
    rets = [float(p.replay(V).ret) for (_, p, _, _), V in zip(episodes, batch.unpad(res.commands))]
    return {"returns": rets, "model_returns": [float(x) for x in res.model_returns], "status": res.status,
            "success": [bool(x) for x in res.success], "iterations": [int(x) for x in res.iterations],
            "evaluations": [int(x) for x in res.evaluations], "wall_s": w2 - w1, "cpu_s": c2 - c1,
            "compile_s": res.compile_seconds, "build_s": build, "device": str(jax.devices()[0])}


def solve_gradient(label, problem, start) -> dict:
    """The per-episode gradient path from the start alone (the certification's coarse level)."""
    from mrd_env.jax import env as je
    from mrd_env.jax.clairvoyant import clairvoyant

    w0, c0 = _clock()
    params = je.params_of_problem(problem, scheme="differentiable")
    _, s0 = je.reset(None, params, record=0)
    cv = clairvoyant(je.episode_return, lambda V: problem.replay(V).ret, {"best constant": start}, problem.v_min,
                     problem.v_max, data=(params, s0), coarse=(int(round(COARSE / STEP)),))
    w1, c1 = _clock()
    s = cv.solves[0]
    return {"return": float(s.ret), "status": s.status, "success": bool(s.success), "iterations": s.iterations,
            "evaluations": s.evaluations, "wall_s": w1 - w0, "cpu_s": c1 - c0, "compile_s": cv.compile_seconds}


def solve_casadi(label, problem, start) -> dict:
    """The CasADi path from the start alone, as the certification runs it (round 1)."""
    from experiments.benchmark.certify import casadi_path

    w0, c0 = _clock()
    r = casadi_path(problem, {"best constant": start}, 1)
    w1, c1 = _clock()
    run = r.runs[0]
    return {"return": float(run["return"]), "status": run["status"], "success": run["success"],
            "iterations": run["iterations"], "evaluations": run["evaluations"], "wall_s": w1 - w0, "cpu_s": c1 - c0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default=SUITE, help=f"a shipped suite's id (default {SUITE})")
    ap.add_argument("--per-scenario", type=int, default=3, help="the first K episodes of each scenario")
    ap.add_argument("--paths", default="batched,gradient,casadi", help="comma-separated, among batched, gradient, "
                                                                         "casadi")
    ap.add_argument("--out", type=Path, default=Path("results/bench/batched_clairvoyant.json"))
    a = ap.parse_args(argv)
    paths = [p for p in a.paths.split(",") if p]
    if a.per_scenario < 1:
        ap.exit(2, f"batched_clairvoyant: --per-scenario must be >= 1, got {a.per_scenario}\n")
    if not paths or set(paths) - {"batched", "gradient", "casadi"} or "batched" not in paths:
        ap.exit(2, f"batched_clairvoyant: --paths must include batched, among batched, gradient, casadi, got "
                   f"{a.paths!r}\n")
    import mrd_env.jax  # noqa: F401  (float64)
    from mrd_env.report import markdown_table
    from mrd_env.storage import writable_folder, write_json
    from mrd_env.suites import suite

    try:
        suite(a.suite)
        writable_folder(a.out.parent)
    except (ValueError, OSError) as exc:
        ap.exit(2, f"batched_clairvoyant: {exc}\n")
    episodes = suite_problems(a.suite, a.per_scenario)
    out = {"suite": a.suite, "control_dt": STEP, "coarse_s": COARSE, "episodes": [e[0] for e in episodes],
           "cpus": os.cpu_count(), "platform": platform.platform(),
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load_start": load_average(), "load": {}}
    print(f"{len(episodes)} episodes of {a.suite} at {STEP * 1e3:g} ms; load {out['load_start']}", flush=True)
    l0 = load_average()
    out["batched"] = solve_batched(episodes)
    out["load"]["batched"] = [l0, load_average()]
    print(f"batched: {out['batched']['wall_s']:.1f} s wall ({out['batched']['compile_s']:.1f} s compiling)",
          flush=True)
    for name, fn in (("gradient", solve_gradient), ("casadi", solve_casadi)):
        if name not in paths:
            continue
        l0 = load_average()
        out[name] = [fn(label, p, V) for label, p, _, V in episodes]
        out["load"][name] = [l0, load_average()]
        print(f"{name}: {sum(r['wall_s'] for r in out[name]):.1f} s wall", flush=True)
        write_json(a.out, out, indent=1)
    rows = []
    for b, (label, p, r_p, _) in enumerate(episodes):
        row = {"episode": label, "steps": p.n_steps, "R_p": r_p, "R_batched": out["batched"]["returns"][b]}
        best = row["R_batched"]
        for name in ("gradient", "casadi"):
            if name in out:
                row[f"R_{name}"] = out[name][b]["return"]
                best = max(best, row[f"R_{name}"])
        span = best - r_p
        if "gradient" in out:
            row["batch short of gradient (share of range)"] = (row["R_gradient"] - row["R_batched"]) / span
        if "casadi" in out:
            row["batch short of casadi (share of range)"] = (row["R_casadi"] - row["R_batched"]) / span
        row["iterations batched"] = out["batched"]["iterations"][b]
        if "gradient" in out:
            row["iterations gradient"] = out["gradient"][b]["iterations"]
        row["batch ok"] = out["batched"]["success"][b]
        rows.append(row)
    out["rows"] = rows
    times = [{"path": "batched (one program)", "wall_s": out["batched"]["wall_s"], "cpu_s": out["batched"]["cpu_s"],
              "compile_s": out["batched"]["compile_s"], "load": out["load"]["batched"]}]
    for name in ("gradient", "casadi"):
        if name in out:
            times.append({"path": f"{name} (sum of episodes)", "wall_s": sum(r["wall_s"] for r in out[name]),
                          "cpu_s": sum(r["cpu_s"] for r in out[name]),
                          "compile_s": sum(r.get("compile_s", 0.0) for r in out[name]), "load": out["load"][name]})
    out["times"] = times
    out["load_end"] = load_average()
    out["markdown"] = "\n".join([markdown_table(rows, title=f"{a.suite}: native returns from the best constant "
                                                            f"command, {STEP * 1e3:g} ms control", floatfmt=".5g"),
                                 markdown_table(times, title="Time per path (s; compilation included in wall and "
                                                             "CPU, shown apart)", floatfmt=".4g")])
    write_json(a.out, out, indent=1)
    print(out["markdown"])
    if "gradient" in out:
        short = max(r["batch short of gradient (share of range)"] for r in rows)
        print(f"largest shortfall of the batch from the per-episode gradient path: {short:.2e} of the range "
              f"(tolerance {TOLERANCE:g})")
    print(f"load {out['load_start']} -> {out['load_end']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
