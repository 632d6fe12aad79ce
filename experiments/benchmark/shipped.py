"""Every shipped controller scored on every shipped benchmark suite, as ``mrd-env score`` scores it (a script, not a
test): the suites' tables, the robustness table and the constraint-cost totals of docs/suites.md.

    python -m experiments.benchmark.shipped [--suite ID ...] [--out results/score_suites] \\
        [--scores docs/suites-scores.json] [--update-docs] [--backend serial|pool --jobs N]

For each shipped suite (:func:`mrd_env.suites.suites`; ``--suite`` for some) it runs
:func:`experiments.benchmark.run.run_benchmark` — the code path of ``mrd-env benchmark``: every law of the suite's
plant, its MPC rows at the suite's control step and every shipped agent trained on the suite's environment, each
scored by :func:`experiments.benchmark.scoring.score` against the suite's stored references (solving nothing); one
that does not fit the suite is listed as not applicable, with the reason.

It writes, under ``--out``, the result files (``results/``) and each suite's leaderboard (``leaderboards/<suite
id>/``), ``score_suites.md`` (the
tables: shares with 95 % intervals per scenario, the robustness table — each controller's share on a nominal suite
and on its randomised twin ``<name>-robust`` and the drop —, the cost totals, the wall times) and
``score_suites.json``; and it updates ``--scores`` (default ``docs/suites-scores.json``: the figures docs/suites.md
shows, per suite scored, which ``tests/experiments/test_suite_scores.py`` re-scores); ``--update-docs`` rewrites the
marked tables of docs/suites.md and README.md from it. Wall times are per controller (the whole ``score`` call) and
per suite, with the load average (``os.getloadavg``) at the start and end of each.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

#: The robustness twin of suite ``<name>-vN`` is ``<name>-robust-vN`` (its episodes, on plants drawn per episode).
TWIN = "-robust"
#: What the machine-readable file is.
FORMAT = "mrd-env-suite-scores"
#: The shares' tolerance of the reproduction check (tests/experiments/test_suite_scores.py).
TOLERANCE = 0.005


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def score_suite(suite, out: Path, executor: dict) -> dict:
    """Score every shipped controller that fits ``suite`` (:func:`experiments.benchmark.run.run_benchmark`, the code
    path of ``mrd-env benchmark``); the suite's entry of ``score_suites.json``."""
    from experiments.benchmark.run import run_benchmark

    entry = {"id": suite.id, "digest": suite.digest, "plant": suite.plant, "episodes": len(suite.episodes()),
             "scenarios": [sc.name for sc in suite.scenarios], "controllers": [], "not_applicable": [],
             "load_start": _load()}
    t_suite = time.perf_counter()
    part = run_benchmark([suite], out=out, **executor).suites[0]
    entry["not_applicable"] = [{"name": n, "reason": why} for n, why in part.not_applicable]
    for n, why in part.not_applicable:
        print(f"{suite.id}: {n}: not applicable ({why})", flush=True)
    for s in part.scored:
        result, spec = s.result, s.spec
        summ = {r["scenario"]: r for r in result.summary()}
        costs = {k: float(sum(e["criteria"][k] for e in result.episodes if math.isfinite(e["criteria"].get(k, 0))))
                 for k in result.criteria if k == "cost" or k.startswith("cost_")}
        entry["controllers"].append({
            "name": spec.name, "kind": spec.kind,
            # an agent's folder relative to the repository (controllers/agents/<name>), the same on every machine
            "spec": _relative(spec.description["spec"]) if spec.kind == "agent" else spec.description.get("spec"),
            "options": spec.description.get("options"),
            "shares": {sc: [_r(r["share"]), _r(r["share lo95"]), _r(r["share hi95"])] for sc, r in summ.items()},
            "pooled": {sc: [_r(r["pooled share"]), _r(r["pooled share lo95"]), _r(r["pooled share hi95"])]
                       for sc, r in summ.items()},
            "episode_shares": {e["label"]: _r(e["share"]) for e in result.episodes},
            "terminated": sum(1 for e in result.episodes if e.get("terminated")),
            "cost_totals": {k: _r(v) for k, v in costs.items()},
            "wall_s": round(s.wall_s, 2), "load": s.load})
        print(f"{suite.id}: {spec.name}: share {summ['all scenarios']['share']:.3f} over {len(result.episodes)} "
              f"episodes, {s.wall_s:.1f} s (load {s.load[1][0]:.2f})", flush=True)
    entry["wall_s"] = round(time.perf_counter() - t_suite, 2)
    entry["load_end"] = _load()
    return entry


def _relative(folder: str) -> str:
    import controllers

    root = Path(controllers.__file__).resolve().parent.parent
    try:
        return Path(folder).resolve().relative_to(root).as_posix()
    except ValueError:
        return str(folder)


def _primary(c: dict) -> dict:
    """A controller's primary figures per scenario: the pooled shares (the leaderboards' ranking figure), the mean
    shares for an entry scored before they were stored."""
    return c.get("pooled") or c["shares"]


def _rank(c: dict) -> float:
    """Sort key: best pooled share over all scenarios first, no number last."""
    m = _primary(c)["all scenarios"][0]
    return math.inf if m is None else -m


def _r(x: float, digits: int = 4):
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


# ---------------------------------------------------------------------------------------------- the tables


def _cell(v) -> str:
    m, lo, hi = v
    if m is None:
        return "n/a"
    if lo is None or hi is None:
        return f"{m:.3f}"
    return f"{m:.3f} [{lo:.3f}, {hi:.3f}]"


def share_table(entry: dict) -> str:
    """A suite's shares: one row per controller (best first over all scenarios), the pooled share and its 95 %
    interval per scenario and over all, the mean share over all, the episodes that ended early and the wall time."""
    head = ["controller", "kind", *entry["scenarios"], "all scenarios", "mean share", "ended early", "wall s"]
    rows = sorted(entry["controllers"], key=_rank)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in rows:
        cells = [c["name"], c["kind"], *(_cell(_primary(c)[s]) for s in entry["scenarios"]),
                 _cell(_primary(c)["all scenarios"]), _cell(c["shares"]["all scenarios"]), str(c["terminated"]),
                 f"{c['wall_s']:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def robustness_table(nominal: dict, twin: dict) -> str:
    """Each controller scored on both: its share over all scenarios on the nominal suite and on the twin, and the
    drop (nominal − twin)."""
    have = {c["name"]: c for c in twin["controllers"]}
    head = ["controller", f"{nominal['id']}", f"{twin['id']}", "drop"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in sorted(nominal["controllers"], key=_rank):
        if c["name"] not in have:
            continue
        a, b = _primary(c)["all scenarios"], _primary(have[c["name"]])["all scenarios"]
        drop = "n/a" if a[0] is None or b[0] is None else f"{a[0] - b[0]:+.3f}"
        lines.append(f"| {c['name']} | {_cell(a)} | {_cell(b)} | {drop} |")
    return "\n".join(lines)


def cost_table(entries: list[dict]) -> str:
    """The constraint costs of suites of one plant: per controller (rows) and suite (columns), ``cost`` summed over
    the suite's episodes and, in brackets, each of its terms (seconds in violation)."""
    terms = sorted({k for e in entries for c in e["controllers"] for k in c["cost_totals"] if k != "cost"})
    names = list(dict.fromkeys(c["name"] for e in entries for c in e["controllers"]))
    head = ["controller", *(e["id"] for e in entries)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in names:
        cells = [name]
        for e in entries:
            c = next((c for c in e["controllers"] if c["name"] == name), None)
            if c is None or c["cost_totals"].get("cost") is None:
                cells.append("–")
                continue
            parts = " / ".join(f"{c['cost_totals'][k]:.3f}" if c["cost_totals"].get(k) is not None else "n/a"
                               for k in terms)
            cells.append(f"{c['cost_totals']['cost']:.3f}" + (f" ({parts})" if terms else ""))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def timing_table(entries: list[dict]) -> str:
    head = ["suite", "episodes", "controllers", "wall s", "slowest controller (s)", "load start", "load end"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in entries:
        slow = max(e["controllers"], key=lambda c: c["wall_s"]) if e["controllers"] else None
        lines.append(f"| {e['id']} | {e['episodes']} | {len(e['controllers'])} | {e['wall_s']:.1f} | "
                     + (f"{slow['name']} ({slow['wall_s']:.1f})" if slow else "") + " | "
                     + " / ".join(f"{x:.2f}" for x in e["load_start"]) + " | "
                     + " / ".join(f"{x:.2f}" for x in e["load_end"]) + " |")
    return "\n".join(lines)


def ordered(ids) -> list[str]:
    """``ids`` in the shipped order, each robustness twin right after its nominal suite."""
    ids = list(ids)

    def key(sid: str):
        name, _, version = sid.rpartition("-v")
        nominal = f"{name[:-len(TWIN)]}-v{version}" if name.endswith(TWIN) else sid
        return (ids.index(nominal) if nominal in ids else ids.index(sid), nominal != sid)

    return sorted(ids, key=key)


def twins(entries: dict) -> list[tuple[dict, dict]]:
    """(nominal, twin) pairs among the suites' entries (``<name>-vN`` and ``<name>-robust-vN``)."""
    out = []
    for sid, e in entries.items():
        name, _, version = sid.rpartition("-v")
        other = f"{name}{TWIN}-v{version}"
        if not name.endswith(TWIN) and other in entries:
            out.append((e, entries[other]))
    return out


def summary_table(data: dict) -> str:
    """The README's summary: per suite, the best law, the best MPC row and the best agent by their pooled share over
    all scenarios ([bootstrap 95 % interval]), and the wall time of all its controllers."""
    head = ["suite", "episodes", "best law", "MPC", "best agent", "wall s (controllers)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def best(entry, which) -> str:
        rows = sorted((c for c in entry["controllers"] if which(c)), key=_rank)
        return f"{rows[0]['name']}: {_cell(_primary(rows[0])['all scenarios'])}" if rows else "–"

    for sid in ordered(data["suites"]):
        e = data["suites"][sid]
        lines.append(f"| `{sid}` | {e['episodes']} | "
                     + best(e, lambda c: c["kind"] == "law" and c["spec"] != "mpc") + " | "
                     + best(e, lambda c: c["kind"] == "law" and c["spec"] == "mpc") + " | "
                     + best(e, lambda c: c["kind"] == "agent") + f" | {e['wall_s']:.0f} ({len(e['controllers'])}) |")
    return "\n".join(lines)


def markdown(data: dict) -> str:
    """Every table of ``data`` (the ``--scores`` file's content), as docs/suites.md shows them."""
    entries = {k: data["suites"][k] for k in ordered(data["suites"])}
    parts = []
    for sid, e in entries.items():
        parts.append(f"**`{sid}`** ({e['episodes']} episodes; pooled share of the achievable gain "
                     f"Σ(R − R_p)/Σ(R_c − R_p) [bootstrap 95 % interval], and the mean of the episodes' shares; "
                     f"{e['wall_s']:.0f} s for its {len(e['controllers'])} controllers):\n\n"
                     + share_table(e))
        if e["not_applicable"]:
            parts.append("Not applicable: " + "; ".join(f"{n['name']} ({n['reason']})" for n in e["not_applicable"]))
    for a, b in twins(entries):
        parts.append(f"**Robustness: `{a['id']}` against `{b['id']}`** (pooled share over all scenarios; drop = nominal − "
                     "randomised):\n\n" + robustness_table(a, b))
    for plant in dict.fromkeys(e["plant"] for e in entries.values()):
        mine = [e for e in entries.values() if e["plant"] == plant]
        terms = sorted({k[len("cost_"):] for e in mine for c in e["controllers"] for k in c["cost_totals"]
                        if k != "cost"})
        parts.append(f"**Constraint costs, {plant}** (`info[\"cost\"]` summed over each suite's episodes, seconds "
                     f"in violation; in brackets its terms: {' / '.join(terms)}):\n\n" + cost_table(mine))
    parts.append("**Wall times** (each controller's whole `score` call, serially in one process; load average "
                 "1 / 5 / 15 min):\n\n" + timing_table(list(entries.values())))
    return "\n\n".join(parts) + "\n"


#: The marked blocks of the docs that ``--update-docs`` rewrites: (file, marker, what goes in).
DOC_BLOCKS = (("docs/suites.md", "score_suites tables", markdown), ("README.md", "score_suites summary", summary_table))


def update_docs(data: dict, root: Path) -> list[Path]:
    """Rewrite the marked blocks (``<!-- MARKER: begin -->`` … ``<!-- MARKER: end -->``) of :data:`DOC_BLOCKS` with the
    tables of ``data``; ``ValueError`` where a file lacks its markers."""
    from mrd_env import storage

    done = []
    for name, marker, make in DOC_BLOCKS:
        path = root / name
        text = path.read_text(encoding="utf-8")
        begin, end = f"<!-- {marker}: begin -->", f"<!-- {marker}: end -->"
        if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
            raise ValueError(f"{path}: needs one {begin} and one {end} around the block to rewrite")
        head, rest = text.split(begin)
        _, tail = rest.split(end)
        storage.write_texts({path: f"{head}{begin}\n{make(data).strip()}\n{end}{tail}"})
        done.append(path)
    return done


# ---------------------------------------------------------------------------------------------- main


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def save_scores(path: Path, entries: dict, run: dict, shipped: list[str], docs: bool) -> None:
    """Merge ``entries`` (suite id → figures) into the scores file ``path`` (shipped suites only, in order) and, with
    ``docs``, rewrite the docs' tables from it."""
    from mrd_env import storage

    old = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    merged = {"format": FORMAT, "tolerance": TOLERANCE, "runs": {**old.get("runs", {}), **{k: run for k in entries}},
              "suites": {**old.get("suites", {}), **entries}}
    order = ordered(k for k in shipped if k in merged["suites"])
    merged["suites"] = {k: merged["suites"][k] for k in order}
    merged["runs"] = {k: merged["runs"][k] for k in order}
    storage.write_json(path, merged, indent=1, allow_nan=False)
    if docs:
        update_docs(merged, Path.cwd())


def main(argv: list[str] | None = None) -> int:
    from experiments.common import sweep
    from mrd_env import storage
    from mrd_env.suites import suites

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--suite", action="append", default=None, help="a shipped suite's id (default: every one)")
    p.add_argument("--out", type=Path, default=Path("results/score_suites"))
    p.add_argument("--scores", default="docs/suites-scores.json",
                   help="the machine-readable figures of the docs, updated per suite scored ('' to leave it)")
    p.add_argument("--update-docs", action="store_true",
                   help="rewrite the marked tables of docs/suites.md and README.md from --scores")
    sweep.add_arguments(p)
    args = p.parse_args(argv)
    executor = sweep.options(args)
    shipped = suites()
    chosen = args.suite or list(shipped)
    unknown = [s for s in chosen if s not in shipped]
    if unknown:
        p.error(f"--suite: unknown {unknown}; shipped: {sorted(shipped)}")
    args.out.mkdir(parents=True, exist_ok=True)
    run = {"command": ["python", "-m", "experiments.benchmark.shipped", *(argv or sys.argv[1:])],
           "created": datetime.now(timezone.utc).isoformat(timespec="seconds"), "git_commit": _git_commit(),
           "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
           "executor": {k: v for k, v in executor.items() if v is not None}, "load_start": _load()}
    t0 = time.perf_counter()
    entries = {}
    for sid in chosen:   # each suite's figures are saved as soon as it is scored (a later failure keeps them)
        entries[sid] = score_suite(shipped[sid], args.out, executor)
        print(f"{sid}: {entries[sid]['wall_s']:.1f} s for {len(entries[sid]['controllers'])} controllers "
              f"(load {entries[sid]['load_start']} -> {entries[sid]['load_end']})", flush=True)
        run.update(wall_s=round(time.perf_counter() - t0, 2), load_end=_load())
        data = {"format": FORMAT, "run": run, "suites": entries}
        storage.write_json(args.out / "score_suites.json", data, indent=1, allow_nan=False)
        storage.write_texts({args.out / "score_suites.md": markdown(data)})
        if args.scores:
            save_scores(Path(args.scores), {sid: entries[sid]}, run, list(shipped), args.update_docs)
    print(markdown(data))
    print(summary_table(data))
    print(f"wrote {args.out / 'score_suites.md'}, {args.out / 'score_suites.json'}"
          + (f", {args.scores}" if args.scores else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
