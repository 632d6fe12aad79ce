"""``mrd-env score``'s wall time per backend on shipped suites (a script, not a test): the figures behind the score
command's default backend (:data:`experiments.benchmark.scoring.POOL_MIN_SECONDS`, docs/your-controller.md).

    python -m experiments.measurements.speed.score_backends [--repeats 3] [--out results/bench/score_backends]

Each run is a fresh ``python -m experiments.cli score --suite S --controller C --no-progress`` process, timed from
its start to its end (imports, worker start-up and the episodes: what a user waits for), with ``--backend serial``,
``--backend pool`` and no ``--backend`` (the command's default). The cases: a law and a shipped agent on
``car-comfort-v1`` and on ``building-seismic-v1``. The backends alternate within each repeat; reported: the median
per backend, its ratio to serial (the reference of the same run), and the load average (``os.getloadavg``) before
and after.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

CASES = (("car-comfort-v1", "skyhook_continuous"), ("car-comfort-v1", "controllers/agents/quarter_car_cmaes"),
         ("building-seismic-v1", "clipped_optimal"), ("building-seismic-v1", "controllers/agents/building_cmaes"))
BACKENDS = ("serial", "pool", None)  # None: the command's default


def one_run(suite: str, controller: str, backend: str | None, out: str) -> float:
    """Wall seconds of one ``score`` process."""
    cmd = [sys.executable, "-m", "experiments.cli", "score", "--suite", suite, "--controller", controller, "--out",
           out, "--no-progress"]
    if backend is not None:
        cmd += ["--backend", backend]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=None, help="write <out>.md and <out>.csv")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for suite, controller in CASES:
            times: dict = {b: [] for b in BACKENDS}
            for k in range(args.repeats):
                for b in BACKENDS:
                    times[b].append(one_run(suite, controller, b, os.path.join(tmp, f"{k}-{b}")))
            med = {b: statistics.median(v) for b, v in times.items()}
            rows.append({"suite": suite, "controller": controller.rsplit("/", 1)[-1],
                         "serial (s)": med["serial"], "pool (s)": med["pool"], "default (s)": med[None],
                         "pool / serial": med["pool"] / med["serial"], "default / serial": med[None] / med["serial"]})
            print(rows[-1], flush=True)
    load1 = os.getloadavg()
    from mrd_env.executor import default_jobs
    from mrd_env.report import csv_text, markdown_table

    title = (f"mrd-env score wall time per backend (median of {args.repeats} fresh processes; {default_jobs()} cores; "
             f"load average {load0[0]:.2f} before, {load1[0]:.2f} after)")
    md = markdown_table([{k: f"{v:.2f}" if isinstance(v, float) else v for k, v in r.items()} for r in rows],
                        title=title)
    print(md)
    if args.out:
        from pathlib import Path

        from mrd_env import storage

        storage.write_texts({Path(f"{args.out}.md"): md, Path(f"{args.out}.csv"): csv_text(rows)})


if __name__ == "__main__":
    main()
