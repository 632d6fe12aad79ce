"""First use: a fresh Python process that makes, resets and steps an environment, with an empty and with a warm
kernel cache, next to the same first use of CartPole-v1 in the same run (issue: speed where users wait).

Run: ``python -m experiments.measurements.speed.first_use [--env-id mrd_env/QuarterCarPhysical-v0] [--damper spencer_dyke]
[--repeats 2] [--out results/bench]``.

Each row is a new interpreter (``python -c``) timed from its spawn to the end of its first ``env.step``, wall
and CPU seconds (the child's own). "empty cache": ``MRD_ENV_CACHE_DIR`` and ``NUMBA_CACHE_DIR`` point at a new
empty folder (what a user meets after ``pip install``, before any ``mrd-env warmup``). By default the first use
steps the interpreted kernel while a background process compiles (:mod:`mrd_env.stepping.first_use`); the child
steps on until the compiled kernel takes over (``compiled_after_s``, the background compilation sharing the
machine with the stepping). With ``MRD_ENV_FIRST_USE=wait`` numba compiles in the process before the first step.
"warm cache": a second process on the folders the default row filled. The CartPole row (Python start-up, the
gymnasium import, make, reset, step) is the floor any environment pays.
Figures are medians over ``--repeats`` (each repeat with its own empty folder); the 1-minute load average is
printed with the table.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mrd_env.report import write_table

_CHILD = """
import time, resource, json, warnings
t0 = time.perf_counter()
warnings.filterwarnings("ignore")
import gymnasium as gym
{imports}
env = gym.make({env_id!r}{kwargs})
env.reset(seed=0)
env.step(env.action_space.sample())
r = resource.getrusage(resource.RUSAGE_SELF)
out = {{"in_process_s": time.perf_counter() - t0, "cpu_s": r.ru_utime + r.ru_stime}}
kernel = getattr(getattr(env.unwrapped, "core", None), "driver", None)
kernel = getattr(kernel, "kernel", None)
n = 0
while not getattr(kernel, "compiled", True):  # a first use stepping on until the compiled kernel takes over
    *_, terminated, truncated, _ = env.step(env.action_space.sample())
    n += 1
    if terminated or truncated:
        env.reset()
if n:
    out.update(compiled_after_s=time.perf_counter() - t0, interpreted_steps=n)
print(json.dumps(out))
"""


def first_use(env_id: str, kwargs: str, imports: str, cache: Path | None, mode: str = "interpret") -> dict:
    """Wall seconds (from the parent's spawn to the end of the child's first step) and the child's CPU seconds;
    with the interpreted first use, the seconds until the compiled kernel took over."""
    env = dict(os.environ, MRD_ENV_FIRST_USE=mode)
    if cache is not None:
        env["MRD_ENV_CACHE_DIR"] = str(cache)
        env["NUMBA_CACHE_DIR"] = str(cache / "numba")
    code = _CHILD.format(env_id=env_id, kwargs=kwargs, imports=imports)
    t0 = time.time()
    out = subprocess.run([sys.executable, "-c", code.replace("t0 = time.perf_counter()", f"t0 = {t0!r}")
                          .replace("time.perf_counter()", "time.time()")],
                         env=env, capture_output=True, text=True, check=True)
    child = json.loads(out.stdout.strip().splitlines()[-1])
    return {"wall_s": child["in_process_s"], "cpu_s": child["cpu_s"],
            "compiled_after_s": child.get("compiled_after_s", float("nan"))}


def _wait_for_background_compilers(timeout: float = 600.0) -> None:
    """Until no ``python -m mrd_env.warmup`` runs (the interpreted first use's compiler finishing its cache)."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        busy = subprocess.run(["pgrep", "-f", "mrd_env.warmup"], capture_output=True).returncode == 0
        if not busy:
            return
        time.sleep(0.5)


def _median(xs):
    xs = sorted(xs)
    n = len(xs)
    return xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env-id", default="mrd_env/QuarterCarPhysical-v0")
    ap.add_argument("--damper", default="spencer_dyke", help="damper model of the environment")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be >= 1")
    kwargs = f", damper={args.damper!r}"
    runs = {"empty": [], "empty_wait": [], "warm": [], "cartpole": []}
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory(prefix="mrd-env-first-use-") as d:
            runs["empty"].append(first_use(args.env_id, kwargs, "import mrd_env", Path(d)))
            _wait_for_background_compilers()
            runs["warm"].append(first_use(args.env_id, kwargs, "import mrd_env", Path(d)))
        with tempfile.TemporaryDirectory(prefix="mrd-env-first-use-") as d:
            runs["empty_wait"].append(first_use(args.env_id, kwargs, "import mrd_env", Path(d), mode="wait"))
        runs["cartpole"].append(first_use("CartPole-v1", "", "", None))
    load = os.getloadavg()[0]
    cp = _median([r["wall_s"] for r in runs["cartpole"]])
    names = {"empty": f"{args.env_id} ({args.damper}), empty kernel cache (interpreted first use, the default)",
             "empty_wait": f"{args.env_id} ({args.damper}), empty kernel cache, MRD_ENV_FIRST_USE=wait",
             "warm": f"{args.env_id} ({args.damper}), warm kernel cache",
             "cartpole": "CartPole-v1 (the floor: start-up, gymnasium, make, reset, step)"}
    rows = [{"first use": names[k], "wall_s": _median([r["wall_s"] for r in v]),
             "cpu_s": _median([r["cpu_s"] for r in v]),
             "x_cartpole": _median([r["wall_s"] for r in v]) / cp,
             "compiled_after_s": _median([r["compiled_after_s"] for r in v]), "load_1min": load}
            for k, v in runs.items()]
    md, _ = write_table(rows, args.out / "first_use", title="First use in a fresh process (make + reset + step)",
                        floatfmt=".3g")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
