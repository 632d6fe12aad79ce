"""The memory estimate's new terms against what is measured (issue 48): the number of dampers of the shear building
(the signal map, the step matrices, the kernel's Newton scratch: :func:`mrd_env.resources.plant_parts`) and a
road's low speed (the full car's FFT grid and the half car's generated road both hold the rear wheels' delay
wheelbase/speed: :meth:`mrd_env.resources.Budget.check_generation`).

    python -m experiments.measurements.memory.estimate            # a few seconds
    python -m experiments.measurements.memory.estimate --rss      # also the resident memory, one process a case

Each case builds the environment and resets it once (the kernels loaded first, outside the measure); the measure is
tracemalloc's peak (what numpy and Python allocate) and, with ``--rss``, the peak resident memory of a fresh
process above its size after the imports and the warm-up (which also counts scipy's FFT buffers, which tracemalloc
does not see). Prints one line a case: the size, the estimate, the measure and their ratio (the estimate is meant
to be within a factor of about 1.5 of what the arrays take, above it where it can be).
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tracemalloc
import warnings

#: (label, environment id, options): dampers of the building and low speeds of the cars.
CASES = [
    *[(f"building, {k} dampers", "mrd_env/ShearBuildingPhysical-v0",
       {"damper_floors": [1, 2, 3] * (k // 3) + [1] * (k % 3), "episode_seconds": 1.0}) for k in (10, 40, 100)],
    *[(f"full car, iso8608 at {v:g} m/s", "mrd_env/FullCar-v1",
       {"road": "iso8608", "road_params": {"speed": v}, "episode_seconds": 1.0}) for v in (0.02, 0.005, 0.002)],
    *[(f"half car, iso8608 at {v:g} m/s", "mrd_env/HalfCar-v1",
       {"road": "iso8608", "road_params": {"speed": v}, "episode_seconds": 1.0}) for v in (0.02, 0.005, 0.002)],
    # sizes where the resident memory is above the noise of the heap the warm-up left (--rss)
    ("full car, iso8608 at 0.0005 m/s", "mrd_env/FullCar-v1",
     {"road": "iso8608", "road_params": {"speed": 0.0005}, "episode_seconds": 1.0}),
    ("half car, iso8608 at 0.0005 m/s", "mrd_env/HalfCar-v1",
     {"road": "iso8608", "road_params": {"speed": 0.0005}, "episode_seconds": 1.0}),
]


def _estimate(env_id: str, options: dict) -> float:
    """The estimate the checks use: the environment's parts plus the record's generation (the largest check made
    while the road was built, recomputed here)."""
    import gymnasium as gym

    from mrd_env import resources

    seen = []
    check = resources.check

    def spy(parts, cause):
        seen.append(sum(parts.values()))
        return check(parts, cause)

    resources.check = spy
    try:
        import mrd_env.envs.core as core_module
        core_module.check_memory = spy
        env = gym.make(env_id, **options)
    finally:
        resources.check = check
        core_module.check_memory = check
    env.close()
    return max(seen)


def measure(env_id: str, options: dict, rss: bool) -> dict:
    """{"estimate", "tracemalloc", "rss"} of one case, in bytes (rss: None unless asked)."""
    import gymnasium as gym

    import mrd_env  # noqa: F401

    warnings.simplefilter("ignore")
    gym.make(env_id, episode_seconds=0.1).reset(seed=0)  # the kernels loaded
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    tracemalloc.start()
    env = gym.make(env_id, **options)
    env.reset(seed=0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - base
    env.close()
    del env
    return {"estimate": _estimate(env_id, options), "tracemalloc": peak, "rss": grown if rss else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rss", action="store_true", help="also the peak resident memory, a fresh process per case")
    ap.add_argument("--case", type=int, help=argparse.SUPPRESS)  # one case in this process (--rss)
    args = ap.parse_args(argv)
    if args.case is not None:
        label, env_id, options = CASES[args.case]
        print(json.dumps(measure(env_id, options, rss=True)))
        return 0
    print(f"{'case':36s} {'estimate':>10s} {'tracemalloc':>12s} {'ratio':>6s}" + (f" {'RSS':>9s} {'ratio':>6s}"
                                                                                   if args.rss else ""))
    for i, (label, env_id, options) in enumerate(CASES):
        if args.rss:
            out = subprocess.run([sys.executable, "-m", "experiments.measurements.memory.estimate", "--case", str(i)],
                                 capture_output=True, text=True, check=True, timeout=300)
            m = json.loads(out.stdout.strip().splitlines()[-1])
        else:
            m = measure(env_id, options, rss=False)
        line = (f"{label:36s} {m['estimate'] / 2**20:8.1f} MiB {m['tracemalloc'] / 2**20:8.1f} MiB "
                f"{m['estimate'] / m['tracemalloc']:6.2f}")
        if m["rss"] is not None:
            line += f" {m['rss'] / 2**20:5.1f} MiB {m['estimate'] / max(m['rss'], 1):6.2f}"
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
