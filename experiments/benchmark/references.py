"""The reference values of a benchmark suite (:mod:`mrd_env.suites`; docs/suites.md), computed once by a fixed
procedure and shipped in the plant's folder.

``python -m experiments.benchmark.references --suite car-comfort-v1 [--jobs N] [--episodes K] [--out FILE]``

The procedure (:data:`PROCEDURE`), per episode, on the episode's plant (the suite's options, the scenario's and a
robustness twin's draw, without the sensor options, which do not change an open-loop command sequence's return):

* **R_p**, the best constant command: a grid of 17 commands from v_min to v_max (a user's yardstick tries 9), each
  re-simulated in the environment;
* **R_c**, the clairvoyant return (:func:`mrd_env.optimal.clairvoyant`, L-BFGS-B on the smoothed model at 1 ms,
  10 ms blocks first): warm-started from the plant's ``warm_laws`` at 1 ms and the best constant command — never
  from a shipped agent, so the references do not depend on what is shipped —, the optimiser run from the **two**
  best warm starts and the better kept (a user's yardstick runs from the best one only), and from the four best
  when both runs fail (a user's: three); re-simulated in the environment;
* **R_b**, the active bound (:func:`mrd_env.optimal.active_bound`) with the force limit the yardstick uses: the
  largest damper force of passive-on, every warm start and the clairvoyant on the episode.

Each episode is cached (``suite_reference`` in :mod:`mrd_env.optimal.cache`), so an interrupted run resumes. The
suite file is written (atomically, with its digest, :func:`mrd_env.suites.write_suite`) only when every episode
has its references; ``--episodes K`` computes the first K episodes and writes only with ``--out`` (a trial, never
the shipped file). A shipped file is never overwritten: a suite whose definition or references change gets a new
version (``--overwrite`` replaces a file of the same definition, before it is shipped). A suite with
``references_of`` (the same episodes, other sensors) copies that suite's shipped references.
"""
from __future__ import annotations

import argparse
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: Bumped when the procedure changes what it computes (part of each episode's cache key and of the suite file).
PROCEDURE_VERSION = 1
#: Constant commands tried for R_p (fractions of the command range): 17 (the yardstick's 9, and the midpoints).
PASSIVE_GRID = np.linspace(0.0, 1.0, 17)
#: Warm starts the optimiser always runs from (the best by environment return), and when every one of them fails.
N_STARTS = 2
FALLBACK_STARTS = 4
#: The clairvoyant's control step (s): the yardstick's.
STEP = 1e-3

PROCEDURE = {
    "version": PROCEDURE_VERSION,
    "best_constant": f"grid of {len(PASSIVE_GRID)} constant commands from v_min to v_max, re-simulated",
    "clairvoyant": f"mrd_env.optimal.clairvoyant at {STEP:g} s (L-BFGS-B, command blocks of 10 ms then 1 ms, "
                   f"max_iter 1000, tol 1e-5), warm-started from the plant's warm_laws at 1 ms and the best constant "
                   f"command (no agent); the optimiser run from the {N_STARTS} best warm starts, the best kept; from "
                   f"the {FALLBACK_STARTS} best if all {N_STARTS} fail; re-simulated",
    "bound": "mrd_env.optimal.active_bound with f_max the largest damper force of passive-on, every warm start "
             "and the clairvoyant on the episode",
    "sensors": "the references are computed without the sensor options (sensors, sensor_noise, sensor_delay, "
               "history, preview), which do not change an open-loop command sequence's return",
}


def best_constant(problem) -> tuple[float, float]:
    """(return, command) of the best constant command of :data:`PASSIVE_GRID` on the problem's episode (the first
    of equal returns)."""
    best = (-math.inf, math.nan)
    for f in PASSIVE_GRID:
        v = float(problem.v_min + f * (problem.v_max - problem.v_min))
        r = float(problem.replay(np.full((problem.n_steps, problem.nd), v)).ret)
        if r > best[0]:
            best = (r, v)
    return best


def episode_problem(env_id: str, options: dict, seed: int):
    from mrd_env.optimal import episode_problem as build

    return build(env_id, seed=int(seed), control_dt=STEP, **options)


def episode_references(env_id: str, options: dict, label: str, seed: int, warm_laws, *, cache: bool = True) -> dict:
    """The references of one episode by the fixed procedure (see the module docstring): {"reference": {passive,
    passive_command, clairvoyant, bound, f_max}, "wall": {...}, "source": ...}. A plain function of picklable
    inputs (the executor's workers run it)."""
    from experiments.benchmark.yardstick import force_peak, warm_starts
    from mrd_env.optimal import active_bound, clairvoyant
    from mrd_env.optimal import cache as store
    from mrd_env.optimal.full_knowledge import problem_digest

    problem = episode_problem(env_id, options, seed)
    key = {**problem.key(), "problem_digest": problem_digest(problem), "label": label,
           "warm_laws": list(warm_laws), "procedure": PROCEDURE}
    hit = store.load("suite_reference", key) if cache else None
    if hit is not None:
        return hit
    t0 = time.perf_counter()
    rp, vp = best_constant(problem)
    starts = warm_starts(problem, warm_laws, agents=())
    starts["best constant"] = np.full((problem.n_steps, problem.nd), vp)
    t1 = time.perf_counter()
    cv = clairvoyant(problem, warm_starts=starts, n_starts=N_STARTS, cache=cache, progress=False)
    if cv.failed:
        cv = clairvoyant(problem, warm_starts=starts, n_starts=FALLBACK_STARTS, cache=cache, progress=False)
    t2 = time.perf_counter()
    on = np.full((problem.n_steps, problem.nd), problem.v_max)
    f_max = max(force_peak(problem, U) for U in [on, *starts.values(), cv.commands])
    b = active_bound(problem, f_max=f_max)
    t3 = time.perf_counter()
    out = {"reference": {"passive": float(rp), "passive_command": float(vp), "clairvoyant": float(cv.ret),
                         "bound": float(b.bound), "f_max": float(f_max)},
           "source": str(cv.source), "solves": [{"start": s.start, "status": s.status, "success": bool(s.success),
                                                 "seconds": round(float(s.seconds), 2), "return": float(s.ret)}
                                                for s in cv.solves],
           "wall": {"passive_and_warm_starts_s": round(t1 - t0, 2), "clairvoyant_s": round(t2 - t1, 2),
                    "bound_s": round(t3 - t2, 2), "total_s": round(t3 - t0, 2)},
           "load_average": [round(x, 2) for x in os.getloadavg()]}
    if cache:
        store.store("suite_reference", key, out)
    return out


def _git_commit() -> str:
    try:
        root = Path(__file__).resolve().parents[2]
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
        return head or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _shipped_check(path: Path, new, overwrite: bool) -> None:
    """``SystemExit`` (one line) if ``path`` holds a suite this run must not replace."""
    from mrd_env.suites import read_suite

    if not path.exists():
        return
    try:
        old = read_suite(path)
    except ValueError as exc:  # a trial file under a shipped id, or a damaged one: say so, one line
        raise SystemExit(f"{path}: {exc}") from None
    if old.definition_json() != new.definition_json():
        raise SystemExit(f"{path} holds suite {old.id} with another definition: a changed suite is a new version "
                         f"(bump the version of {new.name} in the plant's suites/)")
    if not overwrite:
        raise SystemExit(f"{path} exists: its references are frozen (recomputed references are a new version; "
                         "--overwrite replaces a file that was never shipped)")


def copy_references(plant: str, env_id: str, definition, command: str):
    """The suite of ``definition`` with the shipped references of the suite it shares them with
    (``references_of``): the same plant and episodes, checked."""
    from dataclasses import replace

    from mrd_env.suites import draws, suites

    sources = sorted((s.version, s) for s in suites().values() if s.name == definition.references_of)
    if not sources:
        raise SystemExit(f"suite {definition.id} takes the references of {definition.references_of}, which has no "
                         "shipped file yet: compute it first")
    src = sources[-1][1]
    new = definition.suite(plant, env_id, draws(definition, env_id))  # a twin's episodes include its draws
    for (a, sa), (b, sb) in zip(new.episodes(), src.episodes()):
        if a.label(sa) != b.label(sb) or new.reference_options(a, sa) != src.reference_options(b, sb):
            raise SystemExit(f"suite {definition.id}: episode {a.label(sa)} is not {src.id}'s {b.label(sb)} on the "
                             "same plant: it cannot share its references")
    if len(new.episodes()) != len(src.episodes()) or not src.complete():
        raise SystemExit(f"suite {definition.id}: {src.id} does not have the same episodes, or lacks references")
    return replace(new, references=dict(src.references),
                   procedure={"references_of": src.id, "references_of_digest": src.digest,
                              "note": f"the same episodes on the same plant as {src.id}: its references, "
                                      "computed by its procedure", "source_procedure": src.procedure,
                              "command": command})


def table(s) -> str:
    """Markdown: per scenario of the shipped suite ``s``, the mean over its episodes of R_p, R_c, R_b, the bracket
    (R_b − R_c)/(R_b − R_p) and the wall times of the procedure (mean and largest clairvoyant, mean total)."""
    from statistics import mean

    rows = ["| scenario | episodes | R_p best constant | R_c clairvoyant | R_b active bound | bracket | "
            "clairvoyant s (mean / max) | episode s (mean) |", "|---|---|---|---|---|---|---|---|"]
    eps = s.procedure.get("source_procedure", s.procedure).get("episodes", {})
    for sc in s.scenarios:
        refs = [s.reference(sc.label(seed)) for seed in sc.seeds]
        walls = [eps[sc.label(seed)]["wall"] for seed in sc.seeds if sc.label(seed) in eps]
        br = [(r.bound - r.clairvoyant) / (r.bound - r.passive) for r in refs if r.bound > r.passive]
        cw = [w["clairvoyant_s"] for w in walls]
        rows.append(f"| {sc.name} | {len(refs)} | {mean(r.passive for r in refs):.4f} | "
                    f"{mean(r.clairvoyant for r in refs):.4f} | {mean(r.bound for r in refs):.4f} | "
                    f"{mean(br) if br else math.nan:.2f} | "
                    + (f"{mean(cw):.0f} / {max(cw):.0f} | {mean(w['total_s'] for w in walls):.0f} |" if walls
                       else "– | – |"))
    return "\n".join(rows)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.benchmark.references", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--suite", required=True, help="a suite's id (car-comfort-v1) or name (its latest version)")
    p.add_argument("--jobs", type=int, default=1, help="episodes solved at once (process pool; default 1)")
    p.add_argument("--episodes", type=int, default=None, help="only the first K episodes (a trial: needs --out)")
    p.add_argument("--out", type=Path, default=None, help="write here instead of the plant's suites/ folder")
    p.add_argument("--overwrite", action="store_true", help="replace a file of the same definition (not shipped)")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the per-episode cache")
    p.add_argument("--table", action="store_true", help="print the shipped suite's references per scenario")
    args = p.parse_args(argv)
    if args.table:
        from mrd_env.suites import suite

        print(table(suite(args.suite)))
        return 0

    from dataclasses import replace

    from mrd_env.executor import Task, run_tasks
    from mrd_env.plants import plant as plant_spec
    from mrd_env.plants import suite_definition
    from mrd_env.suites import Reference, draws, suite_path, write_suite

    plant, env_id, d = suite_definition(args.suite)
    command = f"python -m experiments.benchmark.references --suite {d.id}"
    path = args.out or suite_path(plant, d)
    if args.episodes is not None and args.out is None:
        raise SystemExit("--episodes computes a trial of a suite: give --out (a suite file is shipped complete)")
    if d.references_of:
        new = copy_references(plant, env_id, d, command)
        _shipped_check(path, new, args.overwrite)
        print(f"{d.id}: {len(new.references)} references of {new.procedure['references_of']} -> "
              f"{write_suite(new, path)}")
        _list_shipped(args.out)
        return 0
    profile = plant_spec(plant).profile
    if not profile.warm_laws:
        raise SystemExit(f"suite {d.id}: the {profile.title} has no warm_laws (no yardstick)")
    new = d.suite(plant, env_id, draws(d, env_id))
    _shipped_check(path, new, args.overwrite)
    episodes = new.episodes()[: args.episodes]
    tasks = [Task(episode_references, (env_id, new.reference_options(sc, seed), sc.label(seed), seed,
                                       tuple(profile.warm_laws)), {"cache": not args.no_cache},
                  label=sc.label(seed)) for sc, seed in episodes]
    t0 = time.perf_counter()
    print(f"{d.id}: {len(tasks)} episodes on {args.jobs} job(s); load average {os.getloadavg()}", flush=True)
    results = run_tasks(tasks, backend="serial" if args.jobs <= 1 else "pool", jobs=args.jobs, progress=True,
                        desc=d.id)
    wall = time.perf_counter() - t0
    refs, per_episode = {}, {}
    for (sc, seed), r in zip(episodes, results):
        label = sc.label(seed)
        refs[label] = Reference(**r["reference"])
        per_episode[label] = {"source": r["source"], "solves": r["solves"], "wall": r["wall"],
                              "load_average": r["load_average"]}
        ref = refs[label]
        print(f"  {label}: R_p {ref.passive:.6g} (v = {ref.passive_command:.4g}), R_c {ref.clairvoyant:.6g}, "
              f"R_b {ref.bound:.6g}; clairvoyant {r['wall']['clairvoyant_s']:.1f} s, total "
              f"{r['wall']['total_s']:.1f} s", flush=True)
    procedure = {**PROCEDURE, "warm_laws": list(profile.warm_laws), "command": command, "git_commit": _git_commit(),
                 "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                             "platform": platform.platform()},
                 "jobs": args.jobs, "run_wall_s": round(wall, 1), "episodes": per_episode}
    out = replace(new, references=refs, procedure=procedure)
    if args.episodes is None and not out.complete():
        raise SystemExit(f"{d.id}: references missing for {sorted(set(out.labels()) - set(refs))}")
    print(f"{d.id}: {len(refs)} episodes in {wall:.0f} s -> {write_suite(out, path)}")
    _list_shipped(args.out)
    return 0


def _list_shipped(out) -> None:
    """A suite written into its plant's folder is shipped: its digest joins the list that binds each shipped id to
    its content (:func:`mrd_env.suites.write_shipped_digests`); a trial written elsewhere (``--out``) does not."""
    from mrd_env.suites import write_shipped_digests

    if out is None:
        print(f"shipped digests -> {write_shipped_digests()}")


if __name__ == "__main__":
    sys.exit(main())
