"""The JAX twin's memory estimate (:func:`mrd_env.jax.env.check_bank`) against what it takes: for each plant, the
bank of ``make_params`` (per seed) and the batch of the ``JaxVectorEnv`` (per environment).

Each measurement runs in a fresh process, its peak resident memory reset just before the call (Linux:
``/proc/self/clear_refs``, then ``VmHWM`` less the ``VmRSS`` before). What is compared
is the growth per seed or per environment, the slope between two sizes, so that the imports, the compiler's own
memory and the fixed parts cancel:

- ``make_params`` with ``--seeds`` a and b seeds: Δ peak RSS / Δ seeds against Δ estimate / Δ seeds;
- ``JaxVectorEnv`` of ``--envs`` a and b environments (reset and 3 steps, the compiles included: large batches, so
  that the compiler's few hundred MB, about the same at both sizes, stay small beside them): Δ peak RSS / Δ N
  against the batch estimate per environment; and XLA's own figure for the compiled step (``memory_analysis()``: arguments, outputs
  and temporaries per environment), and the live arrays after a step (``jax.live_arrays()``) per environment.

``python -m experiments.measurements.memory.jax_bank [--plants quarter_car,...] [--seeds 40,200] [--envs 2000,20000]``
prints one table (Markdown). Ratios are estimate / measured: above 1, the estimate is the larger.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys



def _plants() -> dict[str, str]:
    """Every plant's RL id by its name (the registry's: no plant named here)."""
    from mrd_env.plants import plants

    return {name: s.rl_id for name, s in plants().items()}


def _rss_mark() -> int:
    """The resident memory now (bytes), its peak reset to it (Linux)."""
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    return _status("VmRSS")


def _status(field: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def _child(kind: str, env_id: str, size: int, randomise: bool) -> dict:
    """One measurement in this process (the child): peak RSS growth and the estimate."""
    import numpy as np

    import mrd_env  # noqa: F401
    import mrd_env.jax  # noqa: F401
    import jax
    from mrd_env.jax import env as je
    from mrd_env.jax import vector as jv

    bands = None
    if randomise:
        from mrd_env.plants.quarter_car.suites import ROBUST_BANDS
        bands = ROBUST_BANDS
    asm, _ = je.assembly_of(env_id, {})
    if kind == "bank":
        je.make_params(env_id, seeds=[0], randomise=bands)  # warm: the first draw's imports and caches
        before = _rss_mark()
        je.make_params(env_id, seeds=range(size), randomise=bands)
        peak = _status("VmHWM")
        est = sum(je.bank_parts(asm, size, je.record_samples(asm, [0]), drawn=randomise).values())
        return {"peak": peak - before, "estimate": est}
    env = jv.JaxVectorEnv(env_id, size, randomise=bands)
    before = _rss_mark()
    live0 = sum(x.nbytes for x in jax.live_arrays())
    env.reset(seed=0)
    a = np.zeros(env.action_space.shape)
    for _ in range(3):
        env.step(a)
    peak = _status("VmHWM")
    live = sum(x.nbytes for x in jax.live_arrays()) - live0
    ma = jv._advance_all.lower(env._keys, env._state, env._P, env._lag, jax.numpy.asarray(a),
                               jax.numpy.asarray(env._ended), env.params, env.bands).compile().memory_analysis()
    xla = ma.argument_size_in_bytes + ma.output_size_in_bytes + ma.temp_size_in_bytes
    est = sum(je.batch_parts(asm, size, drawn=False).values())
    return {"peak": peak - before, "estimate": est, "live": live, "xla": xla,
            "xla_fixed": ma.argument_size_in_bytes}


def _run(kind, env_id, size, randomise) -> dict:
    out = subprocess.run([sys.executable, "-m", "experiments.measurements.memory.jax_bank", "--child", kind, env_id,
                          str(size), str(int(randomise))], capture_output=True, text=True, timeout=900,
                         env={**os.environ, "MRD_ENV_MEMORY_LIMIT": "none"})
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", default=",".join(_plants()))
    ap.add_argument("--seeds", default="100,500", help="two bank sizes (seeds)")
    ap.add_argument("--envs", default="30000,150000", help="two batch sizes (num_envs)")
    ap.add_argument("--randomised", action="store_true", help="also the quarter car's robustness bank (drawn plants)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        kind, env_id, size, randomise = args.child
        print(json.dumps(_child(kind, env_id, int(size), bool(int(randomise)))))
        return
    s1, s2 = (int(x) for x in args.seeds.split(","))
    n1, n2 = (int(x) for x in args.envs.split(","))
    print("| plant | what | estimate per unit | measured per unit (peak RSS slope) | estimate / measured | "
          "XLA step per env (args + out + temp) | estimate / XLA | live arrays per env |")
    print("|---|---|---|---|---|---|---|---|")
    from mrd_env.plants.quarter_car import SPEC as ROBUST  # the plant whose robustness bands the bank draws

    cases = [(p, False) for p in args.plants.split(",")] + ([(ROBUST.name, True)] if args.randomised else [])
    for plant, randomise in cases:
        env_id = _plants()[plant]
        label = plant + (" (randomised bank)" if randomise else "")
        a, b = _run("bank", env_id, s1, randomise), _run("bank", env_id, s2, randomise)
        est, meas = (b["estimate"] - a["estimate"]) / (s2 - s1), (b["peak"] - a["peak"]) / (s2 - s1)
        print(f"| {label} | bank, per seed | {est / 1e3:.0f} kB | {meas / 1e3:.0f} kB | {est / meas:.2f} | | | |",
              flush=True)
        if randomise:
            continue
        a, b = _run("batch", env_id, n1, False), _run("batch", env_id, n2, False)
        est, meas = (b["estimate"] - a["estimate"]) / (n2 - n1), (b["peak"] - a["peak"]) / (n2 - n1)
        xla = (b["xla"] - a["xla"]) / (n2 - n1)
        print(f"| {label} | batch, per environment | {est:.0f} B | {meas:.0f} B | {est / meas:.2f} | {xla:.0f} B | "
              f"{est / xla:.2f} | {b['live'] / n2:.0f} B |", flush=True)


if __name__ == "__main__":
    main()
