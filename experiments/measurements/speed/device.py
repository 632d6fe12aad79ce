"""The device benchmark (issue 52, item 4): env-steps/s of every plant's JAX environment at N = 1 024 … 65 536 and
the batched clairvoyant on a few episodes of a suite, on whatever device JAX finds (CPU, GPU), recorded with it.

``python -m experiments.measurements.speed.device [--plants quarter_car,...] [--schemes differentiable,exact]
[--n 1024,4096,16384,65536] [--steps 100] [--repeats 3] [--max-seconds 300] [--exact-max-n 4096]
[--parts speed,clairvoyant] [--episodes 1] [--quick] [--out results/bench/device.json]``
(needs ``pip install mrd-env[jax]``; on a GPU machine, JAX's CUDA build). Runs unchanged on any backend: nothing
assumes a CPU. ``--quick``: a smoke run (the quarter car, N = 64, 5 steps, one repeat, two 0.3 s episodes).

1. **Speed**, per plant and scheme (``experiments.measurements.speed.jax_plants``' plants and schemes, 10 ms
   control, a bank of 16 episodes): ``--steps`` control periods of ``jax.vmap(step_autoreset)`` over N
   environments inside one compiled ``lax.scan``, uniform random actions drawn on the device, timed after a warm-up
   run (median of ``--repeats``): the device's own rate, with no transfer to the host per step (a VectorEnv's
   per-step round trip is ``jax_plants``' figure). A size whose memory estimate
   (:func:`mrd_env.jax.env.check_bank`, ``MRD_ENV_MEMORY_LIMIT``) is refused is left out with the reason, as is one
   after a plant's sizes have taken ``--max-seconds``; the exact scheme is timed up to ``--exact-max-n`` (its
   vmapped adaptive loops wait for the slowest environment).
2. **The batched clairvoyant** (:func:`mrd_env.jax.clairvoyant.batched_clairvoyant`) on the first ``--episodes``
   episodes of each scenario of ``car-comfort-v1`` at 10 ms from their best constant command
   (``experiments.measurements.accuracy.batched_clairvoyant``): wall time, compilation, iterations, the native
   returns.

Writes the JSON and a Markdown table beside it (``.md``), together and atomically; records ``jax.devices()``, the
backend, the CPU count, the platform and the load average.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from experiments.common.plants import default_plant
from experiments.measurements.speed.jax_plants import PLANTS, SCHEMES
from experiments.measurements.speed.jax_quarter_car import compiled, load_average

SIZES = (1024, 4096, 16384, 65536)
#: Episodes in each plant's bank (the records the environments draw from at every reset).
BANK = 16
QUICK = {"plants": default_plant(), "n": "64", "steps": 5, "repeats": 1, "schemes": "differentiable",
         "episodes": 1, "seconds": 0.3}


def device_record() -> dict:
    """What ran the benchmark: JAX's version, backend and devices, the host's CPUs, platform and load."""
    import jax

    devices = jax.devices()
    return {"jax": jax.__version__, "backend": jax.default_backend(), "devices": [str(d) for d in devices],
            "device_kind": devices[0].device_kind, "device_count": len(devices), "cpus": os.cpu_count(),
            "platform": platform.platform(), "python": sys.version.split()[0],
            "xla_flags": os.environ.get("XLA_FLAGS", ""), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def rate(name: str, scheme: str, N: int, steps: int, repeats: int) -> dict:
    """Env-steps/s of ``steps`` periods of N environments in one compiled scan (module docstring, part 1), or the
    reason it was left out."""
    import jax
    import jax.numpy as jnp

    from mrd_env.jax import env as je

    env_id, options = PLANTS[name]
    row = {"plant": name, "scheme": scheme, "N": N}
    try:
        row["memory_estimate_bytes"] = je.check_bank(je.assembly_of(env_id, options)[0], seeds=range(BANK),
                                                     num_envs=N)
    except ValueError as exc:
        return {**row, "skipped": str(exc)}
    params = je.make_params(env_id, seeds=range(BANK), **SCHEMES[scheme], **options)
    nd = params.nd
    _, states = jax.vmap(je.reset, in_axes=(0, None))(jax.random.split(jax.random.PRNGKey(0), N), params)

    def run(key, states, params):
        def period(carry, _):
            key, states = carry
            key, ka, ks = jax.random.split(key, 3)
            actions = jax.random.uniform(ka, (N, nd), jnp.float64, -1.0, 1.0)
            out = jax.vmap(je.step_autoreset, in_axes=(0, 0, 0, None))(jax.random.split(ks, N), states, actions,
                                                                         params)
            return (key, out[1]), out[2].sum()

        (key, states), rewards = jax.lax.scan(period, (key, states), None, length=steps)
        return key, states, rewards.sum()

    key = jax.random.PRNGKey(1)
    fn, row["compile_s"] = compiled(run, key, states, params)
    load0 = load_average()
    key, states, _ = jax.block_until_ready(fn(key, states, params))  # warm-up
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        key, states, total = jax.block_until_ready(fn(key, states, params))
        rates.append(N * steps / (time.perf_counter() - t0))
    if not np.isfinite(float(total)):
        raise RuntimeError(f"{name} ({scheme}, N={N}): the rewards are not finite")
    return {**row, "env_steps_per_s": float(np.median(rates)), "runs": rates, "steps": steps,
            "load_before": load0, "load_after": load_average()}


def speed(plants, schemes, sizes, steps: int, repeats: int, max_seconds: float, exact_max_n: int) -> list[dict]:
    rows = []
    for name in plants:
        t0 = time.perf_counter()
        for scheme in schemes:
            for N in sizes:
                if scheme == "exact" and N > exact_max_n:
                    continue
                if time.perf_counter() - t0 > max_seconds:
                    rows.append({"plant": name, "scheme": scheme, "N": N,
                                 "skipped": f"the plant's runs took over --max-seconds={max_seconds:g} s"})
                else:
                    rows.append(rate(name, scheme, N, steps, repeats))
                print(rows[-1], flush=True)
    return rows


def clairvoyant(per_scenario: int, seconds: float | None) -> dict:
    """The batched clairvoyant on ``car-comfort-v1``'s first ``per_scenario`` episodes of each scenario (module
    docstring, part 2)."""
    from experiments.measurements.accuracy.batched_clairvoyant import SUITE, solve_batched, suite_problems

    episodes = suite_problems(SUITE, per_scenario, seconds=seconds)
    load0 = load_average()
    res = solve_batched(episodes)
    return {"suite": SUITE, "episodes": [e[0] for e in episodes], "steps": [e[1].n_steps for e in episodes],
            "R_p": [e[2] for e in episodes], **res, "load_before": load0, "load_after": load_average()}


def markdown(out: dict) -> str:
    from mrd_env.report import markdown_table

    d = out["device"]
    parts = [f"Device: {d['device_kind']} ({d['backend']}, {d['device_count']} device(s)); host {d['cpus']} CPUs, "
             f"load {out['load_start']} -> {out['load_end']}; JAX {d['jax']}; {d['date']}."]
    if out.get("speed"):
        parts.append(markdown_table([{"plant": r["plant"], "scheme": r["scheme"], "N": r["N"],
                                      "env-steps/s": r.get("env_steps_per_s", float("nan")),
                                      "compile (s)": r.get("compile_s", float("nan")),
                                      "note": r.get("skipped", "")} for r in out["speed"]],
                                    title="Env-steps/s at 10 ms control, random actions, one compiled scan",
                                    floatfmt=".3g"))
    c = out.get("clairvoyant")
    if c:
        parts.append(markdown_table([{"episodes": len(c["episodes"]), "wall (s)": c["wall_s"],
                                      "of it compiling (s)": c["compile_s"],
                                      "iterations (max)": max(c["iterations"]),
                                      "all converged": all(c["success"]),
                                      "mean R_c - R_p": float(np.mean(np.subtract(c["returns"], c["R_p"])))}],
                                    title=f"Batched clairvoyant, {c['suite']}, 10 ms control", floatfmt=".4g"))
    return "\n\n".join(parts) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", default=",".join(PLANTS), help=f"comma-separated, among {', '.join(PLANTS)}")
    ap.add_argument("--schemes", default="differentiable,exact", help=f"comma-separated, among {', '.join(SCHEMES)}")
    ap.add_argument("--n", default=",".join(map(str, SIZES)), help="numbers of environments (comma-separated)")
    ap.add_argument("--steps", type=int, default=100, help="control periods of one timed run")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per figure (the median is reported)")
    ap.add_argument("--max-seconds", type=float, default=300.0, help="a plant's sizes after this many seconds are "
                                                                      "left out")
    ap.add_argument("--exact-max-n", type=int, default=4096, help="largest N the exact scheme is timed at")
    ap.add_argument("--parts", default="speed,clairvoyant", help="comma-separated, among speed, clairvoyant")
    ap.add_argument("--episodes", type=int, default=1, help="episodes per scenario of the batched clairvoyant")
    ap.add_argument("--quick", action="store_true", help="a smoke run: " + ", ".join(f"--{k} {v}" for k, v in
                                                                                    QUICK.items() if k != "seconds")
                    + ", 0.3 s episodes (explicit options still win)")
    ap.add_argument("--out", type=Path, default=Path("results/bench/device.json"))
    given = {a.split("=")[0].lstrip("-").replace("-", "_") for a in (argv if argv is not None else sys.argv[1:])
             if a.startswith("--")}
    a = ap.parse_args(argv)
    seconds = None
    if a.quick:
        for k, v in QUICK.items():
            if k != "seconds" and k not in given:
                setattr(a, k, v)
        seconds = QUICK["seconds"]

    def fail(msg: str):
        ap.exit(2, f"device: {msg}\n")

    plants = [p for p in a.plants.split(",") if p]
    schemes = [s for s in a.schemes.split(",") if s]
    parts = [p for p in a.parts.split(",") if p]
    if not plants or set(plants) - set(PLANTS):
        fail(f"--plants must name plants among {', '.join(PLANTS)}, got {a.plants!r}")
    if not schemes or set(schemes) - set(SCHEMES):
        fail(f"--schemes must name schemes among {', '.join(SCHEMES)}, got {a.schemes!r}")
    if not parts or set(parts) - {"speed", "clairvoyant"}:
        fail(f"--parts must name parts among speed, clairvoyant, got {a.parts!r}")
    try:
        sizes = [int(x) for x in str(a.n).split(",") if x]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1:
        fail(f"--n must be comma-separated integers >= 1, got {a.n!r}")
    for k in ("steps", "repeats", "episodes", "exact_max_n"):
        if getattr(a, k) < 1:
            fail(f"--{k.replace('_', '-')} must be >= 1, got {getattr(a, k)}")
    if not a.max_seconds > 0:
        fail(f"--max-seconds must be > 0, got {a.max_seconds}")
    if a.out.suffix != ".json":
        fail(f"--out must name a .json file, got {str(a.out)!r}")
    import mrd_env  # noqa: F401  (registers the environments)
    import mrd_env.jax  # noqa: F401  (float64)
    from mrd_env.stepping.first_use import set_mode
    from mrd_env.storage import writable_folder, write_texts

    try:
        writable_folder(a.out.parent)
    except (ValueError, OSError) as exc:
        fail(str(exc))
    set_mode("wait")  # the native environments' compiled kernels (the clairvoyant's re-simulations)
    out = {"device": device_record(), "load_start": load_average(), "options": {
        "plants": plants, "schemes": schemes, "n": sizes, "steps": a.steps, "repeats": a.repeats, "bank": BANK,
        "max_seconds": a.max_seconds, "exact_max_n": a.exact_max_n, "episodes": a.episodes, "quick": a.quick},
        "speed": [], "clairvoyant": None}
    if "speed" in parts:
        out["speed"] = speed(plants, schemes, sizes, a.steps, a.repeats, a.max_seconds, a.exact_max_n)
    if "clairvoyant" in parts:
        out["clairvoyant"] = clairvoyant(a.episodes, seconds)
    out["load_end"] = load_average()
    md = markdown(out)
    import json

    write_texts({a.out: json.dumps(out, indent=1), a.out.with_suffix(".md"): md})
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
