"""``mrd-env suite``: your own benchmark suite.

``mrd-env suite build SPEC [--out FILE] [--backend serial|pool|ray] [--jobs N] [--address ADDR]`` turns a suite spec
(a small JSON definition: the plant and its options, the control step, the scenarios — the plant's disturbance kinds
with their parameters, or your own record files beside the spec —, seeds per scenario, criteria; docs/suites.md,
"Your own suite") into a suite file with every episode's references, its digest and the procedure, and a build
record beside it (``<id>.build.json``: wall times, load, machine). The episodes are solved on a process pool or Ray
with a progress bar; an interrupted build (Ctrl-C, SIGTERM) keeps its solved episodes in ``<out>.partial/`` and the
same command resumes it. A suite built serially, on the pool or on Ray is the same file, byte for byte
(:mod:`experiments.benchmark.references`). The shipped suites are built by the same command from their specs
(``mrd_env/plants/<plant>/suites/specs/<id>.json``).

``mrd-env suite show SUITE`` prints a suite's episodes and its references per scenario (a shipped suite's id or
name, or a suite file).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path


def add_arguments(p: argparse.ArgumentParser) -> None:
    from experiments.common import sweep

    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(p))
    b = sub.add_parser("build", help="build a suite file (references, digest, procedure) from a spec",
                       description="build a suite file from a suite spec (docs/suites.md, 'Your own suite')")
    b.add_argument("spec", type=Path, metavar="SPEC", help="the suite spec (.json); its record files beside it")
    b.add_argument("--out", type=Path, default=None,
                   help="the suite file to write (default: <id>.json in the current folder; a shipped spec: its "
                        "plant's suites/ folder); its build record is written beside it (<id>.build.json)")
    b.add_argument("--overwrite", action="store_true", help="replace an existing suite file")
    b.add_argument("--no-resume", action="store_true",
                   help="solve every episode again (default: the episodes an interrupted build kept in "
                        "<out>.partial/ are used)")
    sweep.add_arguments(b)
    s = sub.add_parser("show", help="print a suite's episodes and references per scenario",
                       description="print a suite's episodes and references per scenario")
    s.add_argument("suite", metavar="SUITE", help="a shipped suite's id or name, or a suite file (.json)")


def run(args: argparse.Namespace) -> int:
    return _build(args) if args.action == "build" else _show(args)


def _build(args: argparse.Namespace) -> int:
    from experiments.benchmark.references import build_suite, partial_folder, spec_command
    from experiments.common import sweep
    from mrd_env.plants import suite_spec
    from mrd_env.suites import PLANTS_FOLDER, shipped_digests, suite_path

    executor = sweep.options(args)
    plant, env_id, d = suite_spec(args.spec)
    shipped = PLANTS_FOLDER in args.spec.resolve().parents
    taken = sorted({sid.rsplit("-v", 1)[0] for sid in shipped_digests()})
    if not shipped and d.name in taken:  # a shipped suite's name means the shipped content
        raise ValueError(f"suite spec {args.spec}: name must be a name of your own, not a shipped suite's {taken}; "
                         f"got {d.name!r}")
    out = args.out or (suite_path(plant, d) if shipped else Path(f"{d.id}.json"))
    if out.resolve() == args.spec.resolve():
        raise ValueError(f"--out {out} is the spec itself: give another file")
    try:
        b = build_suite(d, plant, env_id, out, **executor, resume=not args.no_resume, overwrite=args.overwrite,
                        command=spec_command(args.spec))
    except KeyboardInterrupt:
        kept = partial_folder(out)
        n = len(list(kept.glob("episode-*.json"))) if kept.is_dir() else 0
        print(f"mrd-env suite: {n} solved episode(s) kept in {kept}: the same command resumes the build",
              file=sys.stderr)
        raise
    r = b.record
    print(f"{b.suite.id}: {len(b.suite.labels())} episodes ({r['episodes_solved']} solved, {r['episodes_kept']} "
          f"kept from an interrupted build) on {r['backend']} in {r['wall_s']:.1f} s; load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} -> {b.path} (build record {b.record_path})")
    if shipped and args.out is None:
        from mrd_env.suites import write_shipped_digests

        print(f"shipped digests -> {write_shipped_digests()}")
    return 0


def _show(args: argparse.Namespace) -> int:
    from experiments.benchmark.references import read_record, table
    from mrd_env.suites import suite, suite_path

    s = suite(args.suite)
    path = Path(args.suite) if args.suite.endswith(".json") else suite_path(s.plant, s)
    print(f"{s.id} ({s.plant}, {s.env_id}, control every {s.control_dt:g} s; digest {s.digest[:12]}...)")
    print(s.description)
    print(f"\n{len(s.labels())} episodes:")
    for sc in s.scenarios:
        print(f"  {sc.name}: seeds {', '.join(map(str, sc.seeds))}; options {sc.options}")
    print()
    print(table(s, read_record(path)))
    return 0
