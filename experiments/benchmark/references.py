"""The reference values of a benchmark suite (:mod:`mrd_env.suites`; docs/suites.md): the fixed procedure
(:data:`PROCEDURE`) and the builder that runs it over a suite's episodes, :func:`build_suite` — what
``mrd-env suite build SPEC`` runs for a user's suite and for the shipped ones alike.

``python -m experiments.benchmark.references --suite car-comfort-v1 [--backend pool --jobs N] [--episodes K --out F]``
builds a shipped suite from its spec (``mrd_env/plants/<plant>/suites/specs/<id>.json``) into its plant's folder:
the same :func:`build_suite` as ``mrd-env suite build mrd_env/plants/<plant>/suites/specs/<id>.json``.

The procedure, per episode, on the episode's plant (the suite's options, the scenario's and a robustness twin's
draw, without the sensor options, which do not change an open-loop command sequence's return):

* **R_p**, the best constant command: a grid of 17 commands from v_min to v_max (a user's yardstick tries 9), each
  re-simulated in the environment;
* **R_c**, the clairvoyant return (:func:`mrd_env.optimal.clairvoyant`, L-BFGS-B on the smoothed model at 1 ms,
  10 ms blocks first): warm-started from the plant's ``warm_laws`` at 1 ms and the best constant command — never
  from a shipped agent, so the references do not depend on what is shipped —, the optimiser run from the **two**
  best warm starts and the better kept (a user's yardstick runs from the best one only), and from the four best
  when both runs fail (a user's: three); re-simulated in the environment;
* **R_b**, the active bound (:func:`mrd_env.optimal.active_bound`) with the force limit the yardstick uses: the
  largest damper force of passive-on, every warm start and the clairvoyant on the episode; null (not computed)
  where the conic solver does not solve the problem, the reason recorded with the episode.

The build (:func:`build_suite`): the episodes run on :func:`mrd_env.executor.run_tasks` (serial, a process pool
or Ray), one task each, with one progress bar. **Resumable**: each solved episode is kept at once, by the worker
that solved it, in ``<out>.partial/`` beside the output (one small JSON file per episode, keyed by the episode's
options, the record files' contents, the warm laws, the procedure and mrd-env's version); an interrupted build
(Ctrl-C, SIGTERM) run again solves only the episodes not kept; the folder is removed once the suite is written.
**Deterministic**: the suite file holds only what the procedure computes — references, per episode the optimiser
runs' statuses, iterations, function evaluations and returns, and the totals of iterations and evaluations as the
build's machine-independent cost — so that a suite built serially, on a pool or on Ray is the same file, byte for
byte; what the run cost in time (wall times per episode and in all, load averages, machine, backend, jobs, git
commit, the command line) goes to the build record beside it (``<id>.build.json``,
:func:`mrd_env.suites.build_record_path`), which differs from run to run. Both files are written atomically. A
record file a scenario names is copied beside the suite file, named by its content (``data-<sha256[:12]>-<name>``),
and the suite names the copy (a suite reads files from its own folder only); its full SHA-256 is in the procedure.

A shipped file is never overwritten: a suite whose definition or references change gets a new version
(``--overwrite`` replaces a file of the same definition, before it is shipped). A suite with ``references_of``
(the same episodes, other sensors) copies that shipped suite's references.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, replace
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
             "and the clairvoyant on the episode; null where its conic solver does not solve the problem (the "
             "reason in the episode's record)",
    "sensors": "the references are computed without the sensor options (sensors, sensor_noise, sensor_delay, "
               "history, preview), which do not change an open-loop command sequence's return",
}


#: Procedure 2 (issue 51): the clairvoyant in the suite's own action space, certified by two solution paths.
PROCEDURE_2 = {
    "version": 2,
    "best_constant": PROCEDURE["best_constant"] + ", at the suite's control step",
    "clairvoyant": "experiments.benchmark.certify.certified_clairvoyant at the suite's control step (one command per "
                   "step, held as the environment holds it): the CasADi path and the JAX gradient path, each from the "
                   f"{N_STARTS} best warm starts (the plant's warm_laws at the control step and the best constant "
                   "command, no agent); certified where their results agree within 0.5 % of the episode's range "
                   "R_c − R_p; otherwise again from the {more} best, CasADi with IPOPT, and each path from the other's "
                   "optimum; an episode still uncertified is not stored (the build fails naming it)".replace(
                       "{more}", str(FALLBACK_STARTS)),
    "bound": PROCEDURE["bound"] + ", at the suite's control step",
    "sensors": PROCEDURE["sensors"],
}
#: Procedure 3: procedure 2 with the gradient path's round 1 solved for each scenario's episodes together.
PROCEDURE_3 = {
    **PROCEDURE_2,
    "version": 3,
    "clairvoyant": PROCEDURE_2["clairvoyant"] + "; the gradient path's first round solved for all of a scenario's "
                   "episodes together (experiments.benchmark.certify.batched_gradient_paths: one compiled program, "
                   "a projected L-BFGS on the device; a scenario's batch is its episodes whatever was kept, so that "
                   "a resumed build computes what a fresh one does); round 2's gradient path by the same batched "
                   "solver, one episode's starts in one program (experiments.benchmark.certify.PATHS_3)",
}
PROCEDURE_4 = {
    **PROCEDURE_3,
    "version": 4,
    "clairvoyant": PROCEDURE_3["clairvoyant"] + "; round 2 first starts each path from the other's optimum by its "
                   "round-1 solver (experiments.benchmark.certify.certified_clairvoyant, cross_first) and runs the "
                   "more starts only if that does not certify",
}
PROCEDURE_5 = {
    **PROCEDURE_4,
    "version": 5,
    "clairvoyant": PROCEDURE_4["clairvoyant"] + "; the gradient path maximises the twin's return less the CasADi "
                   "path's exterior penalty on the limits that end an episode (mrd_env.optimal.full_knowledge."
                   "LIMIT_PENALTY from LIMIT_MARGIN of each limit; experiments.benchmark.certify.PATHS_5)",
}
#: The procedures by their number (a spec's ``procedure``, :data:`mrd_env.suites.PROCEDURES`).
PROCEDURES = {1: PROCEDURE, 2: PROCEDURE_2, 3: PROCEDURE_3, 4: PROCEDURE_4, 5: PROCEDURE_5}


class UncertifiedEpisode(ValueError):
    """The two solution paths of procedure 2 disagree on an episode: it is not stored as an optimum."""


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


def episode_problem(env_id: str, options: dict, seed: int, step: float = STEP):
    from mrd_env.optimal import episode_problem as build

    return build(env_id, seed=int(seed), control_dt=step, **options)


def episode_references(env_id: str, options: dict, label: str, seed: int, warm_laws, *, cache: bool = False,
                       keep: str | None = None, key: dict | None = None, procedure: int = 1,
                       control_dt: float = STEP, first: dict | None = None) -> dict:
    """The references of one episode by the fixed procedure (see the module docstring): {"reference": {passive,
    passive_command, clairvoyant, bound, f_max}, "source", "solves": [{start, status, success, iterations,
    evaluations, return, seconds}], "wall": {...}, "load_average": [...]}. A plain function of picklable inputs (the
    executor's workers run it). ``cache``: the clairvoyant's solve cache (:mod:`mrd_env.optimal.cache`; a build
    does not use it: its runs are timed); ``keep``, ``key``: the build's folder of kept episodes, where the result is
    written at once under ``key`` (:func:`keep_episode`); ``first``: procedure 3's batched round 1 of a path
    ({name: :class:`~experiments.benchmark.certify.PathResult`}, :func:`batched_round_1`)."""
    from experiments.benchmark.yardstick import force_peak
    from mrd_env.optimal import active_bound, clairvoyant

    problem = episode_problem(env_id, options, seed, STEP if procedure == 1 else control_dt)
    t0 = time.perf_counter()
    rp, vp, starts = episode_starts(problem, warm_laws)
    t1 = time.perf_counter()
    certificate = None
    if procedure == 1:
        cv = clairvoyant(problem, warm_starts=starts, n_starts=N_STARTS, cache=cache, progress=False)
        if cv.failed:
            cv = clairvoyant(problem, warm_starts=starts, n_starts=FALLBACK_STARTS, cache=cache, progress=False)
    else:
        from experiments.benchmark.certify import PATHS_3, PATHS_5, certified_clairvoyant

        paths = PATHS_5 if procedure >= 5 else PATHS_3 if procedure >= 3 else None
        cv = certified_clairvoyant(problem, starts, rp, n_starts=N_STARTS, more_starts=FALLBACK_STARTS, first=first,
                                   paths=paths, cross_first=procedure >= 4)
        if not cv.certified:  # returned, not raised: the build's other episodes go on (and are kept)
            return {"uncertified": f"{label}: the two solution paths disagree by {cv.disagreement:.2%} of its range "
                                   f"(at most 0.5 % certifies): "
                                   f"{', '.join(f'{k} {v.ret:.6g}' for k, v in cv.paths.items())}",
                    "wall_s": round(time.perf_counter() - t0, 2)}
        certificate = cv.to_json()
    t2 = time.perf_counter()
    on = np.full((problem.n_steps, problem.nd), problem.v_max)
    f_max = max(force_peak(problem, U) for U in [on, *starts.values(), cv.commands])
    try:
        bound, bound_status = float(active_bound(problem, f_max=f_max).bound), "solved"
    except RuntimeError as exc:  # the conic solver's failure on this episode: no bound, said so (R_b is optional)
        bound, bound_status = math.nan, f"not solved: {exc}"
    t3 = time.perf_counter()
    solves = ([{"start": s.start, "status": s.status, "success": bool(s.success), "iterations": int(s.iterations),
                "evaluations": int(s.evaluations), "return": float(s.ret), "seconds": round(float(s.seconds), 2)}
               for s in cv.solves] if certificate is None else
              [{**r, "path": name, "seconds": 0.0} for name, p in certificate["paths"].items() for r in p["runs"]])
    out = {"reference": {"passive": float(rp), "passive_command": float(vp), "clairvoyant": float(cv.ret),
                         "bound": bound, "f_max": float(f_max)},
           "source": str(cv.source) if certificate is None else certificate["path"], "bound": bound_status,
           **({"certificate": {k: v for k, v in certificate.items() if k != "paths"}} if certificate else {}),
           "solves": solves,
           "wall": {"passive_and_warm_starts_s": round(t1 - t0, 2), "clairvoyant_s": round(t2 - t1, 2),
                    "bound_s": round(t3 - t2, 2), "total_s": round(t3 - t0, 2)},
           "load_average": [round(x, 2) for x in os.getloadavg()]}
    if keep is not None:
        keep_episode(keep, key, out)
    return out


# ------------------------------------------------------------------------------------------ kept episodes

#: The kept episodes' files (``<out>.partial/episode-<hash>.json``): what a build run again does not solve again.
KEPT_FORMAT = "mrd-env-suite-episode"


def episode_starts(problem, warm_laws) -> tuple[float, float, dict]:
    """R_p, its constant command and the clairvoyant's warm starts {name: commands} of one episode: the warm laws'
    commands and the best constant command (never an agent's)."""
    from experiments.benchmark.yardstick import warm_starts

    rp, vp = best_constant(problem)
    starts = warm_starts(problem, warm_laws, agents=())
    starts["best constant"] = np.full((problem.n_steps, problem.nd), vp)
    return rp, vp, starts


def batched_round_1(env_id: str, episodes, warm_laws, control_dt: float, need=None, say=print, keep=None,
                    keys=None, limit_penalty: bool = False) -> dict:
    """Procedure 3's gradient path, round 1, per scenario: {label: PathResult} for the ``episodes`` [(label,
    options, seed, scenario name)] of every scenario that has a label in ``need`` (default: all). A scenario's batch
    is all its episodes, kept or not, so that what it computes does not depend on what an interrupted build kept.
    ``keep``, ``keys`` ({label: :func:`episode_key`}): each scenario's result is kept in the build's folder once it
    is solved, and used again by a build run again (the batch of a 20-episode building scenario took over 20 min).
    ``limit_penalty``: procedure 5's objective (:data:`experiments.benchmark.certify.PATHS_5`)."""
    from experiments.benchmark.certify import PathResult, batched_gradient_paths

    by_scenario: dict = {}
    for label, options, seed, scenario in episodes:
        by_scenario.setdefault(scenario, []).append((label, options, seed))
    out = {}
    for scenario, eps in by_scenario.items():
        if need is not None and not any(label in need for label, _, _ in eps):
            continue
        bkey = {"batched_round_1": [keys[label] for label, _, _ in eps]} if keep is not None and keys else None
        hit = kept_episode(keep, bkey) if bkey is not None else None
        if hit is not None:
            out.update({label: PathResult.from_kept(r) for label, r in hit["paths"].items()})
            say(f"  {scenario}: the gradient path's round 1 kept from an interrupted build")
            continue
        t0 = time.perf_counter()
        problems = [episode_problem(env_id, options, seed, control_dt) for _, options, seed in eps]
        starts = [episode_starts(p, warm_laws)[2] for p in problems]
        solved = dict(zip((label for label, _, _ in eps), batched_gradient_paths(problems, starts, N_STARTS,
                                                                                   limit_penalty=limit_penalty)))
        out.update(solved)
        if bkey is not None:
            keep_episode(keep, bkey, {"paths": {label: r.to_kept() for label, r in solved.items()}})
        say(f"  {scenario}: the gradient path's round 1 on its {len(eps)} episode(s) together in "
            f"{time.perf_counter() - t0:.1f} s")
    return out


def partial_folder(out: str | Path) -> Path:
    """Where a build of the suite file ``out`` keeps its solved episodes: ``<out>.partial/`` beside it."""
    out = Path(out)
    return out.with_name(out.name + ".partial")


def episode_key(env_id: str, options: dict, label: str, seed: int, warm_laws, procedure: int = 1,
                control_dt: float = STEP) -> dict:
    """What a kept episode must match to be used again: the environment, the episode's options (each file they
    name by its content's SHA-256, not its place), label and seed, the warm laws, the procedure and mrd-env's
    version."""
    from mrd_env.envs.build import map_files
    from mrd_env.resources import file_limit
    from mrd_env.storage import read_limited

    def content(value: str, where: str) -> str:
        return "sha256:" + hashlib.sha256(read_limited(value, file_limit(), what=where)).hexdigest()

    return {"env_id": env_id, "options": json.loads(json.dumps(map_files(options, content, label))),
            "label": label, "seed": int(seed), "warm_laws": list(warm_laws), "procedure": PROCEDURES[procedure],
            **({"control_dt": float(control_dt)} if procedure != 1 else {}),
            "mrd_env": _version()}


def suite_keys(suite, env_id: str, warm_laws, procedure: int, episodes=None) -> dict:
    """{label: :func:`episode_key`} of a suite's ``episodes`` ([(scenario, seed)], default all): the keys its build
    keeps them under (a measurement that computes part of a build keeps it under these, for the build to use)."""
    return {sc.label(seed): episode_key(env_id, suite.reference_options(sc, seed), sc.label(seed), seed, warm_laws,
                                        procedure, suite.control_dt)
            for sc, seed in (suite.episodes() if episodes is None else episodes)}


#: The kept files' name prefixes: a solved episode, and procedure 3's batched round 1 of a scenario.
KEPT_PREFIXES = ("episode-", "batch-")


def _kept_path(folder: str | Path, key: dict) -> Path:
    text = json.dumps(key, sort_keys=True, separators=(",", ":"))
    prefix = KEPT_PREFIXES[1] if "batched_round_1" in key else KEPT_PREFIXES[0]
    return Path(folder) / f"{prefix}{hashlib.sha256(text.encode()).hexdigest()[:24]}.json"


def _kept_digest(key: dict, result: dict) -> str:
    text = json.dumps({"key": key, "result": result}, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def keep_episode(folder: str | Path, key: dict, result: dict) -> Path:
    """Write an episode's result into the build's folder of kept episodes (atomically, with a digest)."""
    from mrd_env.storage import write_json

    Path(folder).mkdir(parents=True, exist_ok=True)
    record = json.loads(json.dumps({"key": key, "result": result}))  # as a reader will see them
    return write_json(_kept_path(folder, key), {"format": KEPT_FORMAT, **record,
                                                 "digest": _kept_digest(record["key"], record["result"])})


def kept_episode(folder: str | Path, key: dict) -> dict | None:
    """The kept result of the episode ``key``, or None (not kept, a file of another key, or damaged: its content
    does not match its digest — then it is solved again)."""
    from mrd_env.storage import read_limited

    path = _kept_path(folder, key)
    if not path.is_file():
        return None
    try:
        data = json.loads(read_limited(path, 1 << 22, what="kept episode").decode("utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != KEPT_FORMAT or not {"key", "result", "digest"} <= set(data):
        return None
    if json.dumps(data["key"], sort_keys=True) != json.dumps(json.loads(json.dumps(key)), sort_keys=True):
        return None
    if data["digest"] != _kept_digest(data["key"], data["result"]):
        return None
    return data["result"]


def _version() -> str:
    import importlib.metadata

    try:
        return importlib.metadata.version("mrd-env")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def _git_commit() -> str:
    try:
        root = Path(__file__).resolve().parents[2]
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
        return head or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _check_out(path: Path, new, overwrite: bool, *, shipped: bool | None = None) -> None:
    """``ValueError`` (one line) if ``path`` holds a file this build must not replace: a shipped suite (``shipped``,
    by default a file in a plant's folder: the same definition and ``overwrite`` only, before it ships), or any
    existing file without ``overwrite``."""
    from mrd_env.suites import PLANTS_FOLDER, read_suite

    if not path.exists() and not path.is_symlink():
        return
    if not path.is_file():
        raise ValueError(f"{path} exists and is not a file: refused")
    if not (PLANTS_FOLDER in path.resolve().parents if shipped is None else shipped):
        if not overwrite:
            raise ValueError(f"{path} exists: --overwrite replaces it")
        return
    old = read_suite(path)  # a damaged file or a trial under a shipped id: one line naming it
    if old.definition_json() != new.definition_json():
        raise ValueError(f"{path} holds suite {old.id} with another definition: a changed suite is a new version "
                         f"(bump the version in its spec, {new.name}-v<N>.json in the plant's suites/specs/)")
    if not overwrite:
        raise ValueError(f"{path} exists: its references are frozen (recomputed references are a new version; "
                         "--overwrite replaces a file that was never shipped)")


def copy_references(plant: str, env_id: str, definition, command: str):
    """The suite of ``definition`` with the shipped references of the suite it shares them with
    (``references_of``): the same plant and episodes, checked."""
    from mrd_env.suites import draws, suites

    shipped = suites()
    src = shipped.get(definition.references_id)
    if src is None:
        raise ValueError(f"suite {definition.id}: references_of must name a shipped suite at this suite's version, or "
                         f"a shipped suite's id (one of {sorted(shipped)}), got {definition.references_of!r} "
                         f"({definition.references_id} is not shipped)")
    new = definition.suite(plant, env_id, draws(definition, env_id))  # a twin's episodes include its draws
    for (a, sa), (b, sb) in zip(new.episodes(), src.episodes()):
        if a.label(sa) != b.label(sb) or new.reference_options(a, sa) != src.reference_options(b, sb):
            raise ValueError(f"suite {definition.id}: episode {a.label(sa)} is not {src.id}'s {b.label(sb)} on the "
                             "same plant: it cannot share its references")
    if len(new.episodes()) != len(src.episodes()) or not src.complete():
        raise ValueError(f"suite {definition.id}: {src.id} does not have the same episodes, or lacks references")
    return replace(new, references=dict(src.references),
                   procedure={"references_of": src.id, "references_of_digest": src.digest,
                              "note": f"the same episodes on the same plant as {src.id}: its references, "
                                      "computed by its procedure", "source_procedure": src.procedure,
                              "command": command})


def spec_command(spec_path: str | Path) -> str:
    """The command that builds a spec, as the suite file records it: the same whoever runs it, from wherever (a
    shipped spec by its place in the package, a user's by its file name), so that it never makes two builds
    differ."""
    from mrd_env.suites import PLANTS_FOLDER

    path = Path(spec_path).resolve()
    root = PLANTS_FOLDER.parents[1]
    shown = path.relative_to(root).as_posix() if PLANTS_FOLDER in path.parents else path.name
    return f"mrd-env suite build {shown}"


def check_episodes(suite) -> None:
    """Make each scenario's environment once (its first episode, with every option a controller gets), so that a
    bad option is refused — one ``ValueError`` naming the scenario — before anything is solved."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    for i, sc in enumerate(suite.scenarios):
        seed = sc.seeds[0]
        try:
            env = gym.make(suite.env_id, **suite.episode_options(sc, seed), control_dt=suite.control_dt)
            try:
                env.reset(seed=int(seed))
            finally:
                env.close()
        except (TypeError, ValueError, KeyError, OSError) as exc:
            raise ValueError(f"suite {suite.id}: scenarios[{i}] ({sc.name!r}): {exc}") from None


@dataclass(frozen=True)
class Build:
    """A finished build: the suite written, where, its build record and where."""

    suite: object
    path: Path
    record: dict
    record_path: Path


def build_suite(definition, plant: str, env_id: str, out: str | Path, *, backend: str = "serial",
                jobs: int | None = None, address: str | None = None, resume: bool = True, progress: bool = True,
                overwrite: bool = False, command: str = "", episodes: int | None = None, say=print) -> Build:
    """Build the suite of ``definition`` (a :class:`~mrd_env.suites.SuiteDefinition` on ``plant``'s ``env_id``)
    into the file ``out``, with its build record beside it (see the module docstring): every episode's references by
    :data:`PROCEDURE` on :func:`mrd_env.executor.run_tasks` (``backend``, ``jobs``, ``address``; ``progress``: one
    bar), the episodes already kept in ``<out>.partial/`` used again (``resume``; False: solved again), the suite
    written atomically once every episode has its references. ``command``: the command recorded in the suite file
    (:func:`spec_command`: the same for every backend); ``episodes``: only the first K (a trial); ``say``: where
    the lines on what is done go. A ``ValueError`` (one line) for a definition or output refused before anything
    is solved."""
    from mrd_env.executor import Task, resolve_backend, run_tasks
    from mrd_env.plants import plant as plant_spec
    from mrd_env.suites import Reference, build_record_path, draws, write_suite
    from mrd_env.storage import write_json

    out = Path(out)
    t0, load0, started = time.perf_counter(), [round(x, 2) for x in os.getloadavg()], time.time()
    if definition.references_of:
        new = copy_references(plant, env_id, definition, command)
        _check_out(out, new, overwrite)
        written = write_suite(new, out)
        record = _record(written, new, command, "none", None, {}, t0, load0, started, 0, 0)
        return Build(new, written, record, write_json(build_record_path(written), record, indent=1))
    profile = plant_spec(plant).profile
    if not profile.warm_laws:
        raise ValueError(f"suite {definition.id}: the {profile.title} has no warm_laws (the clairvoyant's warm "
                         "starts): no suite can be built on it")
    new = definition.suite(plant, env_id, draws(definition, env_id))
    _check_out(out, new, overwrite)
    check_episodes(new)
    chosen = new.episodes()[:episodes]
    keep = partial_folder(out)
    if not resume and keep.is_dir():
        _remove_kept(keep)
    warm = tuple(profile.warm_laws)
    results, tasks, slots = {}, [], []
    keys = suite_keys(new, env_id, warm, definition.procedure, chosen)
    for sc, seed in chosen:
        label, options = sc.label(seed), new.reference_options(sc, seed)
        key = keys[label]
        hit = kept_episode(keep, key) if resume else None
        if hit is not None:
            results[label] = {**hit, "kept": True}
        else:
            tasks.append(Task(episode_references, (env_id, options, label, seed, warm),
                              {"keep": str(keep), "key": key, "procedure": definition.procedure,
                               "control_dt": new.control_dt}, label=label))
            slots.append(label)
    used = resolve_backend(backend, len(tasks), jobs) if tasks else "none"
    say(f"{new.id}: {len(chosen)} episodes, {len(results)} kept in {keep}, {len(tasks)} to solve on {used}"
        + (f" ({jobs} jobs)" if jobs and used in ("pool", "ray") else "") + f"; load average {load0}")
    if definition.procedure >= 3 and tasks:  # the gradient path's round 1, each scenario's episodes together
        batched = batched_round_1(env_id, [(sc.label(seed), new.reference_options(sc, seed), seed, sc.name)
                                           for sc, seed in chosen], warm, new.control_dt, need=set(slots), say=say,
                                  keep=keep, keys=keys, limit_penalty=definition.procedure >= 5)
        for task in tasks:
            task.kwargs["first"] = {"gradient": batched[task.label]}
    with _one_thread_per_worker():
        solved = run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress, desc=new.id)
    results.update(zip(slots, solved))
    refused = [r["uncertified"] for r in results.values() if "uncertified" in r]
    if refused:  # every other episode is solved and kept: a build run again solves only these
        raise UncertifiedEpisode(f"{new.id}: {len(refused)} episode(s) not certified, not stored as optima (the "
                                 f"{len(results) - len(refused)} others are kept in {keep}): " + "; ".join(refused))
    refs, episodes_json, costs = {}, {}, {}
    for sc, seed in chosen:
        label = sc.label(seed)
        r = results[label]
        refs[label] = Reference(**r["reference"])
        episodes_json[label] = {"source": r["source"],
                                "solves": [{k: v for k, v in x.items() if k != "seconds"} for x in r["solves"]],
                                "bound": r["bound"], **({"certificate": r["certificate"]} if "certificate" in r else {})}
        costs[label] = {"wall": r["wall"], "load_average": r["load_average"],
                        "solves_s": [x["seconds"] for x in r["solves"]], "kept": bool(r.get("kept", False))}
    iterations = sum(x["iterations"] for e in episodes_json.values() for x in e["solves"])
    evaluations = sum(x["evaluations"] for e in episodes_json.values() for x in e["solves"])
    suite, files = _bundle_files(new, out.parent)
    procedure = {**PROCEDURES[definition.procedure], "warm_laws": list(warm), "command": command, "mrd_env": _version(),
                 "cost": {"solver_iterations": iterations, "function_evaluations": evaluations,
                          "note": "the optimiser's iterations and model evaluations (each a simulation with its "
                                  "gradient) over every episode: the build's cost independent of the machine; the "
                                  "wall times are in the build record"},
                 **({"files": files} if files else {}), "episodes": episodes_json}
    suite = replace(suite, references=refs, procedure=procedure)
    if episodes is None and not suite.complete():
        raise ValueError(f"{new.id}: references missing for {sorted(set(suite.labels()) - set(refs))}")
    written = write_suite(suite, out)
    record = _record(written, suite, command, used, jobs, costs, t0, load0, started, len(tasks), len(chosen) - len(tasks))
    record_path = write_json(build_record_path(written), record, indent=1)
    _remove_kept(keep)
    return Build(suite, written, record, record_path)


#: The thread counts of the numerical libraries a pool's worker would otherwise size to every core.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _one_thread_per_worker():
    """One BLAS/OpenMP thread in each worker the pool spawns meanwhile (a variable the user set is left as set), as
    Ray does for its workers: one worker per core, each with a thread per core, oversubscribed the cores — a
    4-episode build of 3 s car episodes on 2 workers took 51.7 s, 26.4 s with one thread each (load 4.5 on 2
    cores), the same bytes. The spawned workers read the variables when they start; this process is unchanged."""
    saved = {n: os.environ.get(n) for n in THREAD_VARIABLES}
    for n in THREAD_VARIABLES:
        os.environ.setdefault(n, "1")
    try:
        yield
    finally:
        for n, v in saved.items():
            if v is None:
                os.environ.pop(n, None)
            else:
                os.environ[n] = v


def _record(path: Path, suite, command: str, backend: str, jobs, costs: dict, t0: float, load0, started: float,
            solved: int, kept: int) -> dict:
    """The build record: what this run cost (see the module docstring)."""
    import datetime

    from mrd_env.suites import content_digest

    return {"format": "mrd-env-suite-build", "suite": suite.id, "suite_file": path.name,
            "digest": content_digest(suite.to_json()), "command_line": " ".join(sys.argv), "command": command,
            "backend": backend, "jobs": jobs, "git_commit": _git_commit(), "mrd_env": _version(),
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
            "started": datetime.datetime.fromtimestamp(started, datetime.timezone.utc).isoformat(timespec="seconds"),
            "wall_s": round(time.perf_counter() - t0, 1),
            "load_average": {"start": load0, "end": [round(x, 2) for x in os.getloadavg()]},
            "episodes_solved": solved, "episodes_kept": kept, "episodes": costs}


def _bundle_files(suite, folder: Path):
    """``suite`` with every record file its options name copied into ``folder`` (the suite file's), named by its
    content (``data-<sha256[:12]>-<name>``; an existing copy is the same content), and {copy's name: SHA-256}."""
    import re

    from mrd_env.envs.build import map_files
    from mrd_env.resources import file_limit
    from mrd_env.storage import read_limited, write_bytes
    from mrd_env.suites import confined_file

    files: dict[str, str] = {}

    def copy(value: str, label: str) -> str:
        source = confined_file(suite.folder, value, f"suite {suite.id}: {label}") if suite.folder else Path(value)
        content = read_limited(source, file_limit(), what=f"suite {suite.id}: {label}")
        digest = hashlib.sha256(content).hexdigest()
        name = f"data-{digest[:12]}-{re.sub(r'[^A-Za-z0-9_.-]+', '_', Path(value).name)[-80:]}"
        target = folder / name
        if not (target.is_file() and hashlib.sha256(target.read_bytes()).hexdigest() == digest):
            write_bytes(target, content)
        files[name] = digest
        return name

    options = map_files(suite.options, copy, "options")
    scenarios = tuple(replace(sc, options=map_files(sc.options, copy, f"scenarios ({sc.name!r}).options"))
                      for sc in suite.scenarios)
    return replace(suite, options=options, scenarios=scenarios, folder=""), dict(sorted(files.items()))


def _remove_kept(folder: Path) -> None:
    """Remove a build's folder of kept episodes (only its own files: a folder holding others is left)."""
    if not folder.is_dir():
        return
    for f in folder.iterdir():
        if f.name.startswith(KEPT_PREFIXES) and f.suffix == ".json" and f.is_file():
            f.unlink(missing_ok=True)
    try:
        folder.rmdir()
    except OSError:
        pass  # something else is in it: not ours to remove


def table(s, record: dict | None = None) -> str:
    """Markdown: per scenario of the suite ``s``, the mean over its episodes of R_p, R_c, R_b, the bracket
    (R_b − R_c)/(R_b − R_p) and the wall times of the procedure (mean and largest clairvoyant, mean total): from
    the build record ``record`` (:func:`read_record`), or from the procedure of a suite built before the records."""
    from statistics import mean

    rows = ["| scenario | episodes | R_p best constant | R_c clairvoyant | R_b active bound | bracket | "
            "clairvoyant s (mean / max) | episode s (mean) |", "|---|---|---|---|---|---|---|---|"]
    eps = (record or {}).get("episodes") or s.procedure.get("source_procedure", s.procedure).get("episodes", {})
    for sc in s.scenarios:
        refs = [s.reference(sc.label(seed)) for seed in sc.seeds]
        walls = [eps[sc.label(seed)]["wall"] for seed in sc.seeds if "wall" in eps.get(sc.label(seed), {})]
        br = [(r.bound - r.clairvoyant) / (r.bound - r.passive) for r in refs if r.bound > r.passive]
        cw = [w["clairvoyant_s"] for w in walls]
        bounds = [r.bound for r in refs if math.isfinite(r.bound)]  # null where the conic solver failed
        rb = (f"{mean(bounds):.4f}" + (f" ({len(bounds)} of {len(refs)})" if len(bounds) < len(refs) else "")
              if bounds else "–")
        rows.append(f"| {sc.name} | {len(refs)} | {mean(r.passive for r in refs):.4f} | "
                    f"{mean(r.clairvoyant for r in refs):.4f} | {rb} | "
                    f"{mean(br) if br else math.nan:.2f} | "
                    + (f"{mean(cw):.0f} / {max(cw):.0f} | {mean(w['total_s'] for w in walls):.0f} |" if walls
                       else "– | – |"))
    return "\n".join(rows)


def read_record(suite_path: str | Path) -> dict | None:
    """The build record beside the suite file ``suite_path`` (None if there is none, or it is not one)."""
    from mrd_env.storage import read_limited
    from mrd_env.suites import build_record_path

    path = build_record_path(suite_path)
    if not path.is_file():
        return None
    try:
        data = json.loads(read_limited(path, 1 << 24, what="build record").decode("utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("format") == "mrd-env-suite-build" else None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.benchmark.references", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--suite", required=True, help="a shipped suite's id (car-comfort-v1) or name (its latest version)")
    p.add_argument("--backend", choices=("serial", "pool", "ray"), default="serial",
                   help="where the episodes are solved (mrd_env.executor; default serial)")
    p.add_argument("--jobs", type=int, default=None, help="workers of the pool or Ray (default: the cores)")
    p.add_argument("--address", default=None, help="a Ray cluster's address (default: a local Ray instance)")
    p.add_argument("--episodes", type=int, default=None, help="only the first K episodes (a trial: needs --out)")
    p.add_argument("--out", type=Path, default=None, help="write here instead of the plant's suites/ folder")
    p.add_argument("--overwrite", action="store_true", help="replace a file of the same definition (not shipped)")
    p.add_argument("--no-resume", action="store_true", help="solve again the episodes an interrupted build kept")
    p.add_argument("--table", action="store_true", help="print the shipped suite's references per scenario")
    args = p.parse_args(argv)
    try:
        if args.table:
            from mrd_env.suites import suite, suite_path

            s = suite(args.suite)
            print(table(s, read_record(suite_path(s.plant, s))))
            return 0
        from mrd_env.plants import suite_definition
        from mrd_env.suites import suite_path

        plant, env_id, d = suite_definition(args.suite)
        if args.episodes is not None and args.out is None:
            raise ValueError("--episodes computes a trial of a suite: give --out (a suite file is shipped complete)")
        spec = Path(d.folder) / f"{d.id}.json"
        b = build_suite(d, plant, env_id, args.out or suite_path(plant, d), backend=args.backend, jobs=args.jobs,
                        address=args.address, resume=not args.no_resume, overwrite=args.overwrite,
                        command=spec_command(spec), episodes=args.episodes)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    print(f"{d.id}: {len(b.suite.references)} episodes in {b.record['wall_s']:.0f} s -> {b.path} (build record "
          f"{b.record_path})")
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
