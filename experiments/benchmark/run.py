"""The benchmark: every controller that fits a suite scored on it (``mrd-env benchmark``; the shipped scores of the
docs, :mod:`experiments.benchmark.shipped`, are this run over every shipped suite).

For each suite, :func:`run_benchmark` scores — through :func:`experiments.benchmark.scoring.score`, the code path of
``mrd-env score``, against the suite's stored references, solving nothing —

* with ``shipped=True``, the controllers the project ships for it (:func:`shipped_controllers`): every law of the
  suite's plant (its profile's ``laws`` and ``benchmark_laws``); the plant's MPC rows at the suite's control step (a
  row with preview only on a suite that grants the road-preview sensor, a row without only on one that does not);
  every shipped agent trained on the suite's environment;
* every controller the caller adds: a law's name, a shipped agent's name, an agent folder, ``module:attribute`` or
  a Python object (what :func:`~experiments.benchmark.scoring.score` takes).

A controller that does not fit a suite (an agent trained on other sensors, a law that misses a sensor) is listed
with the reason, not scored; one of the caller's that fits none of the suites is refused (``ValueError``). Every
(suite, controller) pair is one task of :mod:`mrd_env.executor` (serially, on a process pool or on Ray; a Python
object of the caller's runs in this process); the shares are the same on every backend. With ``out``, it writes
``<out>/results/<suite id>__<controller>.json`` (each as its task ends: an interrupted run keeps the finished ones)
and one leaderboard per suite, ``<out>/leaderboards/<suite id>/`` (:func:`~experiments.benchmark.ranking.
write_leaderboards`: tables and figure, every share checked against the suite's references), and
``<out>/benchmark.md``, the summary (``benchmark.json``: what was scored and what did not fit, as data).
"""
from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

#: The folders of ``out``: the result files, and the leaderboards (one folder per suite).
RESULTS, LEADERBOARDS, SUMMARY, RECORD = "results", "leaderboards", "benchmark.md", "benchmark.json"


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


# ---------------------------------------------------------------------------------------------- what is scored


def agent_folders() -> list[Path]:
    """The shipped agents' folders (``controllers/agents/*/agent.json``), in name order."""
    import controllers

    root = Path(controllers.__file__).resolve().parent / "agents"
    return sorted(p for p in root.iterdir() if (p / "agent.json").is_file())


def has_preview(suite) -> bool:
    """Whether the suite grants the road-preview sensor."""
    return "road_preview" in suite.options.get("sensors", ())


def shipped_controllers(suite) -> list[dict]:
    """[{name, controller, options}] of the controllers the project ships for ``suite`` (see the module docstring):
    its plant's laws, its MPC rows at the suite's control step, and the shipped agents trained on its environment
    (whether each fits is checked when scoring)."""
    from experiments.common.plants import profile

    prof = profile(suite.plant)
    laws = dict.fromkeys((*prof.laws, *prof.benchmark_laws))
    out = [{"name": law, "controller": law, "options": None} for law in laws]
    dt = suite.control_dt
    for label, step, options, preview in prof.mpc:
        if bool(preview) != has_preview(suite):
            continue
        if step is not None and abs(step - dt) > 1e-12:
            continue  # a row tuned for another control step
        if step is None and any(other == label and s is not None and abs(s - dt) < 1e-12
                                for other, s, _, _ in prof.mpc):
            continue  # the row tuned for this very step stands for it
        out.append({"name": label, "controller": "mpc", "options": dict(options) or None})
    for folder in agent_folders():   # agent.json read as data: which environment the agent was trained on
        if json.loads((folder / "agent.json").read_text(encoding="utf-8")).get("env_id") == suite.env_id:
            out.append({"name": folder.name, "controller": str(folder), "options": None})
    return out


def choose_suites(suites=None, plants=None) -> list:
    """The suites to score: ``suites`` (Suites, shipped suites' names, suite files; default every shipped suite),
    those of ``plants`` only (plant names; None: every plant). ``ValueError`` for an unknown suite, a suite given
    twice, or a choice that leaves none."""
    from mrd_env.suites import suites as shipped

    from experiments.benchmark.scoring import check_references, resolve_suite

    given = list(shipped().values()) if suites is None else [resolve_suite(s) for s in suites]
    ids = [s.id for s in given]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ValueError(f"suite {twice[0]} is given twice: give each suite once")
    if plants is not None:
        kept = [s for s in given if s.plant in plants]
        if not kept:
            raise ValueError(f"none of the suites {ids} is of the plant(s) {sorted(plants)}: make one of your own "
                             "with mrd-env suite build SPEC")
        given = kept
    for s in given:
        check_references(s)
    return given


@dataclass
class Scored:
    """One controller's score on one suite: the result, where it was written, and its wall time (s) with the load
    average (1/5/15 min) at its start and end."""

    result: object        #: :class:`~experiments.benchmark.scoring.SuiteResult`
    spec: object          #: :class:`~experiments.benchmark.scoring.ControllerSpec`
    shipped: bool         #: one of the controllers the project ships for the suite (else the caller's)
    path: Path | None = None
    wall_s: float = math.nan
    load: list = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass
class SuiteBenchmark:
    """A suite's part of the benchmark: the controllers scored, those that do not fit it (name, reason) and its
    leaderboard folder (None without ``out``, or with nothing scored)."""

    suite: object
    scored: list[Scored] = field(default_factory=list)
    not_applicable: list[tuple[str, str]] = field(default_factory=list)
    leaderboard: Path | None = None


@dataclass
class Benchmark:
    """What :func:`run_benchmark` scored, per suite; ``wall_s`` and the load averages of the whole run."""

    suites: list[SuiteBenchmark]
    wall_s: float = math.nan
    load_start: list = field(default_factory=list)
    load_end: list = field(default_factory=list)

    def summary_rows(self) -> list[dict]:
        """One row per suite: its episodes, the controllers scored (and not applicable), and the best law, MPC row,
        shipped agent and controller of the caller's by the pooled share over all scenarios, the leaderboards' figure
        (:meth:`~experiments.benchmark.scoring.SuiteResult.pooled_shares`: value [95 % bootstrap interval])."""
        from experiments.benchmark.scoring import ALL, interval_cell

        def best(entry: SuiteBenchmark, which) -> str:
            rows = [s for s in entry.scored if which(s)]
            if not rows:
                return "–"
            b = max(rows, key=lambda s: _pooled(s.result))
            m, lo, hi = b.result.pooled_shares()[ALL]
            partial = "" if b.result.complete else f" (partial: {len(b.result.episodes)} episodes)"
            return f"{b.name}: {interval_cell(m, lo, hi)}{partial}"

        def is_law(s, mpc: bool) -> bool:
            return s.shipped and s.spec.kind == "law" and (s.spec.ref == "mpc") == mpc

        mine = any(not s.shipped for e in self.suites for s in e.scored)
        out = []
        for e in self.suites:
            row = {"suite": e.suite.id, "episodes": len(e.suite.episodes()),
                   "scored (not applicable)": f"{len(e.scored)} ({len(e.not_applicable)})",
                   "best law": best(e, lambda s: is_law(s, False)), "MPC": best(e, lambda s: is_law(s, True)),
                   "best agent": best(e, lambda s: s.shipped and s.spec.kind == "agent")}
            if mine:
                row["yours"] = best(e, lambda s: not s.shipped)
            out.append(row)
        return out

    def to_json(self) -> dict:
        """What was scored, as plain data (``benchmark.json``): per suite its id and digest, each controller scored
        (name, kind, whether shipped, result file, wall time, load) and each not applicable with the reason; the
        run's wall time and load."""
        return {"format": "mrd-env-benchmark", "wall_s": round(self.wall_s, 2), "load_start": self.load_start,
                "load_end": self.load_end,
                "suites": [{"id": e.suite.id, "digest": e.suite.digest,
                            "scored": [{"name": s.name, "kind": s.spec.kind, "shipped": s.shipped,
                                        "result": None if s.path is None else s.path.name,
                                        "complete": s.result.complete, "wall_s": round(s.wall_s, 2), "load": s.load}
                                       for s in e.scored],
                            "not_applicable": [{"name": n, "reason": why} for n, why in e.not_applicable],
                            "leaderboard": None if e.leaderboard is None else e.leaderboard.name}
                           for e in self.suites]}

    def markdown(self) -> str:
        """The summary table and, per suite, the controllers that do not fit it with the reason."""
        from mrd_env.report import markdown_table

        text = markdown_table(self.summary_rows(), title="The benchmark: per suite, the best controller of each kind "
                                                         "by its pooled share of the achievable gain Σ(R − R_p) / "
                                                         "Σ(R_c − R_p) over all scenarios [95 % bootstrap interval]; "
                                                         "each suite's leaderboard has every controller")
        for e in self.suites:
            if e.not_applicable:
                text += (f"\n{e.suite.id}, not applicable: "
                         + "; ".join(f"{n} ({why})" for n, why in e.not_applicable) + "\n")
        return text


def _pooled(result) -> float:
    from experiments.benchmark.scoring import ALL

    m = result.pooled_shares()[ALL][0]
    return m if math.isfinite(m) else -math.inf


# ---------------------------------------------------------------------------------------------- scoring


def score_task(suite, spec, episodes: int | None = None, path: str | Path | None = None,
               caller: int | None = None) -> tuple:
    """One (suite, controller) pair, scored in this process (a plain function of picklable inputs, for
    :mod:`mrd_env.executor`): (result, wall time in s, load average at start and end). ``path``: the result file,
    written here, as soon as it is scored. ``caller``: the process id of :func:`run_benchmark`'s caller; in another
    process (the executor's worker) torch runs on one thread (:func:`~experiments.benchmark.scoring.
    one_torch_thread`)."""
    from experiments.benchmark.scoring import one_torch_thread, score

    if caller is not None and os.getpid() != caller:
        one_torch_thread(spec)
    load0, t0 = _load(), time.perf_counter()
    result = score(suite, spec, episodes=episodes, backend="serial")
    wall = time.perf_counter() - t0
    if path is not None:
        result.write(path)
    return result, wall, [load0, _load()]


def _named(controllers) -> list[tuple[str | None, object]]:
    """[(name or None, controller)] of ``controllers``: a list, or a dict {name: controller}."""
    if isinstance(controllers, dict):
        return list(controllers.items())
    if isinstance(controllers, (str, Path)):
        return [(None, controllers)]
    return [(None, c) for c in controllers]


def _plan(suites, controllers, shipped: bool, only, trust_agent: bool, converted,
          own_process: bool) -> list[SuiteBenchmark]:
    """Per suite, the controllers that fit it (their specs, checked on the suite's scenarios) and those that do
    not; ``ValueError`` for a controller of the caller's that fits no suite, a name of ``only`` that names no
    shipped controller, or two controllers of one name."""
    from experiments.benchmark.scoring import (bounded, check_controller, controller_spec, one_torch_thread,
                                               result_filename)

    user = _named(controllers)
    plans, fits, why = [], {i: False for i in range(len(user))}, {}
    offered = set()
    for suite in suites:
        entry = SuiteBenchmark(suite)
        candidates = []
        if shipped:
            for c in shipped_controllers(suite):
                offered.add(c["name"])
                if only is None or c["name"] in only:
                    candidates.append((True, None, c))
        candidates += [(False, i, {"name": n, "controller": c, "options": None}) for i, (n, c) in enumerate(user)]
        for is_shipped, i, c in candidates:
            try:
                spec = controller_spec(c["controller"], name=c["name"], options=c["options"], trust_agent=trust_agent,
                                       converted=converted, suite=suite)
                if own_process:
                    one_torch_thread(spec)  # before its first environment: an SB3 policy on every core is 10x slower
                check_controller(spec, suite)
            except ValueError as exc:
                name = c["name"] or (c["controller"] if isinstance(c["controller"], (str, Path)) else
                                     getattr(c["controller"], "__name__", type(c["controller"]).__name__))
                entry.not_applicable.append((str(name), str(exc)))
                if i is not None:
                    why.setdefault(i, f"{suite.id}: {exc}")
                continue
            if i is not None:
                fits[i] = True
            same = next((s for s in entry.scored if s.name == spec.name), None)
            if same is not None:
                if same.spec.description == spec.description:
                    continue  # the same controller named twice (a shipped law given as --controller too)
                raise ValueError(f"two controllers are named {bounded(spec.name)} on suite {suite.id}: give yours "
                                 "another name")
            files = {result_filename(suite.id, s.name) for s in entry.scored}
            if result_filename(suite.id, spec.name) in files:
                raise ValueError(f"controller {bounded(spec.name)}: another controller's result on suite {suite.id} "
                                 f"would be written to the same file {result_filename(suite.id, spec.name)}; rename it")
            entry.scored.append(Scored(None, spec, is_shipped))
        plans.append(entry)
    unknown = sorted(set(only or ()) - offered)
    if unknown:
        raise ValueError(f"only: {bounded(unknown[0])} is none of the shipped controllers of the chosen suites "
                         f"({', '.join(sorted(offered)) or 'none'})")
    for i, ok in fits.items():
        if not ok:  # refused on every suite: on one, its reason as it is
            name, c = user[i]
            raise ValueError(why[i].split(": ", 1)[1] if len(suites) == 1 else
                             f"controller {bounded(name or c)} fits none of the chosen suites ({why[i]})")
    return plans


def run_benchmark(suites=None, controllers=(), *, shipped: bool = True, only=None, plants=None, out=None,
                  episodes: int | None = None, backend: str = "auto", jobs: int | None = None,
                  address: str | None = None, trust_agent: bool = False, progress: bool = False,
                  own_process: bool = False) -> Benchmark:
    """Score every controller that fits each of ``suites`` (see the module docstring).

    ``suites``: Suites, shipped suites' names or suite files (default: every shipped suite), of ``plants`` only
    (plant names; default every plant). ``controllers``: the caller's (a list, or {name: controller}), each what
    :func:`~experiments.benchmark.scoring.score` takes. ``shipped``: also the controllers the project ships for each
    suite; ``only``: of those, the ones of these names (``["passive_off", "mpc (reward)"]``). ``out``: the folder of
    the result files, leaderboards and summary (None: nothing is written). ``episodes``: the first ``episodes`` of
    each scenario only (a smoke run: every result partial). ``backend``/``jobs``/``address``: one task per suite and
    controller on :mod:`mrd_env.executor` (``"pool"`` from a script needs its calls under ``if __name__ ==
    "__main__":``). ``trust_agent``: also load agents that only have SB3's pickled ``model.zip`` (converted once into
    ``<out>/converted-agents``). ``own_process``: this process is a command's own (``mrd-env benchmark``), where torch
    may be set to one thread (:func:`~experiments.benchmark.scoring.one_torch_thread`; never in a caller's Python
    process: a process-wide setting). Everything is checked before any episode runs and before ``out`` is made:
    ``ValueError`` (one line)."""
    from mrd_env.executor import Task, TaskFailed, run_tasks

    from experiments.benchmark.ranking import check_out_folder, leaderboards
    from experiments.benchmark.scoring import result_filename

    if episodes is not None and (isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1):
        raise ValueError(f"episodes must be a whole number >= 1 (per scenario), got {episodes!r}")
    if only is not None and not shipped:
        raise ValueError("only chooses among the shipped controllers: it needs shipped=True")
    out = None if out is None else Path(out)
    if out is not None:
        check_out_folder(out / LEADERBOARDS)
    chosen = choose_suites(suites, plants)
    converted = None if out is None else out / "converted-agents"
    plans = _plan(chosen, controllers, shipped, None if only is None else set(only), trust_agent, converted,
                  own_process)
    if not any(p.scored for p in plans):
        raise ValueError("nothing to score: no controller fits the chosen suites")
    if out is not None:
        from mrd_env import storage

        storage.writable_folder(out / RESULTS)
    pairs = [(p, s) for p in plans for s in p.scored]
    for p, s in pairs:
        s.path = None if out is None else out / RESULTS / result_filename(p.suite.id, s.name)
    load_start, t0 = _load(), time.perf_counter()

    def task(p, s) -> Task:
        return Task(score_task, (p.suite, s.spec), {"episodes": episodes, "path": s.path, "caller": os.getpid()},
                    label=f"{p.suite.id} / {s.name}")

    # a Python object of the caller's stays in the caller's process; the rest is one sweep
    remote = [(p, s) for p, s in pairs if s.spec.picklable]
    local = [(p, s) for p, s in pairs if not s.spec.picklable]
    try:
        done = run_tasks([task(p, s) for p, s in remote], backend=backend, jobs=jobs, address=address,
                         progress=progress, desc="benchmark", retry=False)
        done += run_tasks([task(p, s) for p, s in local], backend="serial", progress=progress, desc="benchmark",
                          retry=False)
    except TaskFailed as exc:
        if isinstance(exc.error, ValueError):
            raise ValueError(f"{exc.task.label}: {exc.error}") from exc.error
        raise
    for (p, s), (result, wall, load) in zip(remote + local, done):
        s.result, s.wall_s, s.load = result, wall, load
        if s.path is not None:
            result.write(s.path)  # again, here: a worker of a Ray cluster wrote it on its own machine
    bench = Benchmark(plans, time.perf_counter() - t0, load_start, _load())
    if out is not None:
        from mrd_env import storage

        for p in plans:  # one suite at a time: a leaderboard's bounds are per suite
            if p.scored:
                leaderboards([s.path for s in p.scored], out=out / LEADERBOARDS,
                             suites=() if _is_shipped(p.suite) else [p.suite], html=True)
                p.leaderboard = out / LEADERBOARDS / p.suite.id
        storage.write_texts({out / SUMMARY: bench.markdown(),
                             out / RECORD: json.dumps(bench.to_json(), indent=1, allow_nan=False) + "\n"})
    return bench


def _is_shipped(suite) -> bool:
    """Whether ``suite`` is the shipped suite of its id (its digest the shipped one's)."""
    from mrd_env.suites import suites

    s = suites().get(suite.id)
    return s is not None and s.digest == suite.digest
