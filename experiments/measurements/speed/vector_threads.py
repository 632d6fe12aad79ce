"""The native vector environment's threads on a shared machine: the default against one thread and every thread
of each numba threading layer, without and with a competing CPU-bound process, in one run (issue 36).

Run: ``python -m experiments.measurements.speed.vector_threads [--sizes 64 1024] [--repeats 7] [--seconds 0.5]
[--out results/bench]``.

Environment: ``gymnasium.make_vec("mrd_env/QuarterCar-v1", num_envs=N, vectorization_mode="vector_entry_point")``
(10 ms control), commands switched between the action bounds every 50 steps, episodes autoresetting inside the
timing (the timing loop of :mod:`experiments.measurements.speed.vector`). Rows:

* ``default``: no ``threads`` argument, numba's default threading layer (what a new user gets);
* ``threads=1``;
* ``all threads, <layer>``: ``threads=numba.get_num_threads()`` on each threading layer that loads (``omp``,
  ``tbb``, ``workqueue``).

A threading layer is chosen once per process, so each layer runs in its own worker process (spawned, idle while
another row is timed); the main process only orders the timings. Each figure is the median of ``--repeats``
timing runs of about ``--seconds`` each (their length set without a competitor), the rows interleaved so that
a change of the machine's load slows every row alike. The competitor is one process spinning in a Python loop,
started before the second pass and stopped after it. The load average (``os.getloadavg()``) is stated at the
start, between the passes and at the end: other processes on the machine are part of both passes.
Writes ``vector_threads.md`` and ``vector_threads.json`` to ``--out`` (atomically).
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import time
from pathlib import Path

import numpy as np

from experiments.measurements.speed.vector import rate

ENV_ID = "mrd_env/QuarterCar-v1"
LAYERS = ("omp", "tbb", "workqueue")
#: (label, threading layer, environment of the worker) of the "all threads" rows
ALL_THREADS = [(layer, layer, {}) for layer in LAYERS] + [("omp, OMP_WAIT_POLICY=PASSIVE", "omp",
                                                             {"OMP_WAIT_POLICY": "PASSIVE"})]


def _busy(stop) -> None:  # the competitor: one CPU-bound process
    while not stop.is_set():
        for _ in range(100_000):
            pass


def _worker(conn, layer: str | None, env: dict | None = None) -> None:
    """Builds and times vector environments on one threading layer (``None``: numba's default choice), with
    ``env`` set before the layer's library loads (OpenMP reads its settings then)."""
    os.environ.update(env or {})
    import gymnasium as gym
    import numba

    import mrd_env  # noqa: F401
    from mrd_env.stepping.first_use import set_mode

    if layer is not None:
        numba.config.THREADING_LAYER = layer  # read when numba first starts its threads
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    envs: dict = {}
    while True:
        msg = conn.recv()
        try:
            if msg[0] == "quit":
                break
            if msg[0] == "build":
                _, key, N, threads = msg
                kw = {} if threads is None else {"threads": numba.get_num_threads() if threads == "all" else threads}
                venv = gym.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point", **kw)
                lo, hi = venv.single_action_space.low, venv.single_action_space.high
                acts = (np.tile(lo, (N, 1)).astype(np.float64), np.tile(hi, (N, 1)).astype(np.float64))
                venv.reset(seed=0)
                rate(venv, 3, acts)  # load the kernels, start the threads
                envs[key] = (venv, acts)
                tuner = venv.unwrapped.thread_tuner
                n = tuner.many if tuner else venv.unwrapped.core.driver.threads
                conn.send((n, numba.threading_layer() if n > 1 else "-"))
            elif msg[0] == "calibrate":
                _, key, seconds = msg
                venv, acts = envs[key]
                conn.send(max(20, int(seconds * rate(venv, 20, acts) / venv.num_envs)))
            elif msg[0] == "time":
                _, key, steps = msg
                venv, acts = envs[key]
                conn.send((rate(venv, steps, acts), _threads(venv.unwrapped)))
        except Exception as e:  # a layer that does not load: reported, its rows dropped
            conn.send(e)
    for venv, _ in envs.values():
        venv.close()


def _threads(venv) -> str:
    """The thread count, or the default's choices so far: how many probes chose one thread and every thread."""
    tuner = venv.thread_tuner
    if tuner is None:
        return str(venv.core.driver.threads)
    one, many = tuner.choices
    return f"auto: 1 ({one}), {tuner.many} ({many})"


class _Worker:
    def __init__(self, ctx, layer, env=None):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, layer, env), daemon=True)
        self.proc.start()

    def ask(self, *msg):
        self.conn.send(msg)
        out = self.conn.recv()
        if isinstance(out, Exception):
            raise out
        return out

    def close(self):
        self.conn.send(("quit",))
        self.proc.join(30)


def _load() -> str:
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def bench(sizes=(64, 1024), repeats: int = 7, seconds: float = 0.5, log=print) -> dict:
    ctx = mp.get_context("spawn")
    info = {"cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
            "load_start": _load(), "date": time.strftime("%Y-%m-%d %H:%M")}
    log(f"load average (1/5/15 min) at the start: {info['load_start']}; {info['cpus']} CPUs")
    workers = {"default": _Worker(ctx, None)} | {label: _Worker(ctx, layer, env) for label, layer, env in ALL_THREADS}
    rows_of = [("default", "default", None), ("threads=1", "default", 1)] + \
              [(f"all threads, {label}", label, "all") for label, _, _ in ALL_THREADS]
    built: dict = {}  # (label, N) -> (worker, threads, layer, steps)
    skipped = []
    try:
        for N in sizes:
            for label, wname, threads in rows_of:
                w = workers[wname]
                try:
                    n, layer = w.ask("build", (label, N), N, threads)
                except Exception as e:  # noqa: BLE001 - a threading layer missing on this machine
                    if (label, str(e).splitlines()[0]) not in skipped:
                        skipped.append((label, str(e).splitlines()[0]))
                    continue
                built[label, N] = (w, n, layer, w.ask("calibrate", (label, N), seconds))
        info["skipped"] = [f"{label}: {why}" for label, why in skipped]
        for label, why in skipped:
            log(f"skipped {label}: {why}")
        results = []
        for competitor in (False, True):
            stop = ctx.Event()
            busy = ctx.Process(target=_busy, args=(stop,), daemon=True) if competitor else None
            if busy is not None:
                busy.start()
                time.sleep(1.0)  # let the scheduler see it
                info["load_between"] = _load()
            for N in sizes:
                keys = [k for k in built if k[1] == N]
                rates: dict = {k: [] for k in keys}
                threads: dict = {}
                for _ in range(repeats):
                    for k in keys:
                        w, _, _, steps = built[k]
                        rate, threads[k] = w.ask("time", k, steps)
                        rates[k].append(rate)
                group = []
                for (label, _), r in rates.items():
                    _, _, layer, _ = built[label, N]
                    group.append({"N": N, "competitor": "1 busy process" if competitor else "none",
                                  "setting": label, "threads": threads[label, N], "layer": layer,
                                  "env_steps_per_s": float(np.median(r)), "repeats": [float(x) for x in r]})
                best = max(g["env_steps_per_s"] for g in group)
                for g in group:
                    g["x_slower_than_best"] = best / g["env_steps_per_s"]
                    log(f"N={N:5d} competitor={g['competitor']:14s} {g['setting']:24s} "
                        f"{g['env_steps_per_s']:9.0f} env-steps/s  ×{g['x_slower_than_best']:.2f}")
                results += group
            if busy is not None:
                stop.set()
                busy.join(5)
                if busy.is_alive():
                    busy.terminate()
    finally:
        for w in workers.values():
            try:
                w.close()
            except Exception:  # noqa: BLE001
                w.proc.terminate()
    info["load_end"] = _load()
    log(f"load average at the end: {info['load_end']}")
    return {"info": info, "rows": results}


def table(out: dict) -> str:
    info = out["info"]
    lines = [f"# Vector-env threads on a shared machine ({ENV_ID}, 10 ms control)", "",
             f"{info['date']}; {info['cpus']} CPUs; load average (1/5/15 min) {info['load_start']} at the start, "
             f"{info.get('load_between', '?')} with the competitor running, {info['load_end']} at the end "
             "(other processes of the machine ran through both passes). Median env-steps/s of the repeats; "
             "'× best': the best row of the same N and competitor over this row. The default's threads: how many of "
             "its probes so far (both passes) chose one thread and every thread.", ""]
    if info.get("skipped"):
        lines += ["Not run: " + "; ".join(info["skipped"]), ""]
    lines += ["| N | competitor | setting | threads | layer | env-steps/s | × best |", "|---|---|---|---|---|---|---|"]
    for r in out["rows"]:
        lines.append(f"| {r['N']} | {r['competitor']} | {r['setting']} | {r['threads']} | {r['layer']} | "
                     f"{r['env_steps_per_s']:,.0f} | {r['x_slower_than_best']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    from mrd_env.storage import write_text

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 1024])
    ap.add_argument("--repeats", type=int, default=7, help="timing runs per row; the median is reported")
    ap.add_argument("--seconds", type=float, default=0.5, help="length of one timing run (without the competitor)")
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    if args.repeats < 3:
        ap.error("--repeats must be at least 3")
    out = bench(args.sizes, args.repeats, args.seconds)
    md = table(out)
    write_text(args.out / "vector_threads.md", md)
    write_text(args.out / "vector_threads.json", json.dumps(out, indent=1))
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
