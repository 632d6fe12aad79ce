"""Every plant's JAX environment (:mod:`mrd_env.jax.env`) against its native one (issue 41's must-show figures,
for all the plants).

Run: ``nice -n 10 python -m experiments.measurements.speed.jax_plants [--plants quarter_car,half_car,...]
[--episodes 4] [--seconds 10] [--n 1024,4096] [--repeats 3] [--window 1.5] [--exact-max-n 1024]
[--parts accuracy,speed] [--out results/bench_jax_plants.json]``
(CPU; needs ``pip install mrd-env[jax]``). Writes the JSON (atomically) and prints Markdown tables.

1. Accuracy, per plant: held-out episodes (seeds 1000, 1001, …; the training seeds start at 0), a uniform random
   action per control period, the same for both: the native scalar environment (``gymnasium.make(id, **options)``,
   ``reset(seed=s)``) against the JAX exact scheme on the same record (the bank ``make_params(id, seeds=[1000,
   …])``, ``reset(record=i)``), ``--seconds`` of each episode. Figures per episode, the worst kept: the rewards'
   largest difference over the largest |reward|; the state's (the driver's float64 Y: plant and damper states)
   largest difference of each component over that component's peak, worst component; the same for the damper
   forces; the observations (the native ones are float32, so this one is float32 rounding). The differentiable
   scheme (2 Newton iterations; 1 and 2 sub-steps) against the exact one on the same episode: NRMSE of the rewards,
   of each state component (worst) and of the forces, and the state's largest difference over its peak (worst
   component, named; and over the plant's coordinates and rates alone, without the dampers' internal states).
2. Cold compile time of the jitted step (``jax.jit(step).lower(...).compile()``, JAX's persistent cache off) per
   plant and scheme, and of the vmapped step at each N.
3. Throughput at 10 ms control: env-steps/s of the jitted ``jax.vmap`` of ``step_autoreset`` (one call per step
   from Python, observations and rewards brought back to numpy each step, as a VectorEnv does) for each scheme, and
   of ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``, interleaved in the same
   run, median of ``--repeats`` runs of about ``--window`` s each; uniform random actions every step (the native
   step's adaptive work is largest on command transients). The load average is recorded around each plant.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from experiments.measurements.speed.jax_quarter_car import compiled, load_average

def _plants() -> dict:
    """name -> (environment id, options): every registered plant's RL id (10 ms control, normalised actions), and
    the six-storey building (its preset on the physical-level id, 4 dampers) as an extra case."""
    from mrd_env.plants import plants

    out = {name: (f"mrd_env/{spec.id_name}-v1", {}) for name, spec in plants().items()}
    out["six_storey"] = ("mrd_env/ShearBuildingPhysical-v0",
                         {"plant_preset": "six_storey", "control_dt": 0.01, "action_mode": "normalized"})
    return out


PLANTS = _plants()

#: label -> make_params options of the schemes compared.
SCHEMES = {
    "exact": {"scheme": "exact"},
    "differentiable": {"scheme": "differentiable", "substeps": 1, "newton_iterations": 2},
    "differentiable_2sub": {"scheme": "differentiable", "substeps": 2, "newton_iterations": 2},
}

#: The first held-out seed (training and tuning draw from 0 upwards).
HELD_OUT = 1000


def _peak_rels(x, ref) -> np.ndarray:
    """The largest difference of each column over that column's peak in ``ref`` (0 where both are 0 throughout)."""
    d = np.abs(x - ref).max(axis=0)
    peak = np.abs(ref).max(axis=0)
    return np.where(d == 0, 0.0, d / np.where(peak > 0, peak, 1e-300))


def _peak_rel(x, ref) -> float:
    """:func:`_peak_rels`' worst column."""
    return float(np.max(_peak_rels(x, ref)))


def state_labels(env_id: str, options: dict) -> list[str]:
    """Names of the state Y's components: the plant's coordinates, their rates, each damper's internal states."""
    from mrd_env.jax import env as jenv

    asm, _ = jenv.assembly_of(env_id, options)
    dofs = list(asm.linear_plant.dof_names)
    return dofs + [f"{q}_dot" for q in dofs] + [f"{s}[{j}]" for j in range(asm.coupled.system.nd)
                                                 for s in asm.damper.state_names]


def _nrmse(x, ref) -> float:
    """RMS difference over the RMS of ``ref``, per column, worst column."""
    x, ref = np.atleast_2d(x.T).T, np.atleast_2d(ref.T).T
    e = np.sqrt(np.mean((x - ref) ** 2, axis=0))
    s = np.sqrt(np.mean(ref ** 2, axis=0))
    return float(np.max(np.where(e == 0, 0.0, e / np.where(s > 0, s, 1e-300))))


def native_episode(env_id: str, options: dict, seed: int, actions: np.ndarray) -> dict:
    """The native scalar environment's episode under ``actions`` (one row per control period; it stops early if
    the episode ends): rewards, the driver's float64 states Y and forces, the observations."""
    import gymnasium as gym

    env = gym.make(env_id, **options)
    u = env.unwrapped
    obs0, _ = u.reset(seed=seed)
    out = {"reward": [], "Y": [], "F": [], "obs": [], "ended": None}
    Y = u.core.driver.state("Y")
    for k, a in enumerate(actions):
        obs, r, term, trunc, _ = u.step(np.asarray(a, np.float64))
        out["reward"].append(r)
        out["Y"].append(Y[0].copy())
        out["F"].append(u.damper_force)
        out["obs"].append(obs)
        if term or trunc:
            out["ended"] = (k, bool(term))
            break
    env.close()
    return {k: (np.array(v) if isinstance(v, list) else v) for k, v in out.items()}


def jax_episode(step_fn, params, record: int, actions: np.ndarray, key) -> dict:
    """The JAX twin's episode on the bank's ``record`` under ``actions`` (one compiled step per period)."""
    import jax

    from mrd_env.jax import env as jenv

    _, state = jenv.reset(key, params, record=record)
    out = {"reward": [], "Y": [], "F": [], "obs": [], "ended": None}
    for k, a in enumerate(actions):
        key, sub = jax.random.split(key)
        obs, state, r, term, trunc, _ = step_fn(sub, state, np.asarray(a, np.float64), params)
        out["reward"].append(float(r))
        out["Y"].append(np.asarray(state.Y))
        out["F"].append(np.asarray(state.F))
        out["obs"].append(np.asarray(obs))
        if bool(term) or bool(trunc):
            out["ended"] = (k, bool(term))
            break
    return {k: (np.array(v) if isinstance(v, list) else v) for k, v in out.items()}


def accuracy(name: str, episodes: int, seconds: float, schemes=tuple(SCHEMES)) -> tuple[list[dict], dict]:
    """Per held-out episode of plant ``name``: the exact scheme vs the native environment and each other scheme
    vs the exact one (module docstring, part 1); and the cold compile time of the jitted step per scheme."""
    import jax

    from mrd_env.jax import env as jenv

    env_id, options = PLANTS[name]
    seeds = [HELD_OUT + i for i in range(episodes)]
    params = {label: jenv.make_params(env_id, seeds=seeds, **SCHEMES[label], **options) for label in schemes}
    nd = params["exact"].nd
    key = jax.random.PRNGKey(0)
    steps, compile_s = {}, {}
    for label, p in params.items():
        _, s0 = jenv.reset(key, p, record=0)
        steps[label], compile_s[label] = compiled(jenv.step, key, s0, np.zeros(nd), p)
    n = int(round(seconds / params["exact"].control_dt))
    labels = state_labels(env_id, options)
    n2 = 2 * len(jenv.assembly_of(env_id, options)[0].linear_plant.dof_names)  # the plant's [q, q̇]
    rows = []
    for i, seed in enumerate(seeds):
        m = min(n, int(params["exact"].steps[i]))
        actions = np.random.default_rng(2 * HELD_OUT + seed).uniform(-1.0, 1.0, (m, nd))
        nat = native_episode(env_id, options, seed, actions)
        out = {label: jax_episode(steps[label], p, i, actions, jax.random.PRNGKey(seed)) for label, p in params.items()}
        ex = out["exact"]
        k = min(len(nat["reward"]), len(ex["reward"]))
        row = {"plant": name, "seed": seed, "steps": k, "same_end": nat["ended"] == ex["ended"],
               "exact_reward_rel": float(np.abs(ex["reward"][:k] - nat["reward"][:k]).max()
                                         / np.abs(nat["reward"][:k]).max()),
               "exact_state_rel_peak": _peak_rel(ex["Y"][:k], nat["Y"][:k]),
               "exact_force_rel_peak": _peak_rel(ex["F"][:k], nat["F"][:k]),
               "obs_rel_peak_float32": _peak_rel(ex["obs"][:k].astype(np.float32).astype(np.float64),
                                                 nat["obs"][:k].astype(np.float64))}
        for label in schemes:
            if label == "exact":
                continue
            o = out[label]
            j = min(k, len(o["reward"]))
            row[f"{label}_same_end"] = o["ended"] == ex["ended"]
            row[f"{label}_reward_nrmse"] = _nrmse(o["reward"][:j], ex["reward"][:j])
            row[f"{label}_state_nrmse"] = _nrmse(o["Y"][:j], ex["Y"][:j])
            rel = _peak_rels(o["Y"][:j], ex["Y"][:j])
            row[f"{label}_state_rel_peak"] = float(rel.max())
            row[f"{label}_state_rel_peak_at"] = labels[int(np.argmax(rel))] if len(labels) == len(rel) else ""
            row[f"{label}_plant_state_rel_peak"] = float(rel[:n2].max())
            row[f"{label}_force_nrmse"] = _nrmse(o["F"][:j], ex["F"][:j])
        rows.append(row)
        print(row, flush=True)
    return rows, compile_s


def throughput(name: str, sizes, repeats: int, window: float, schemes=("differentiable", "exact"),
               bank: int = 16, exact_max_n: int | None = None) -> tuple[list[dict], dict]:
    """Env-steps/s of the vmapped JAX step per scheme and of the native vector environment at each N, interleaved
    (module docstring, part 3); and the cold compile time of each vmapped step. The exact scheme is timed up to
    ``exact_max_n`` environments (its vmapped while-loops make every environment wait for the slowest one: minutes
    per run for the full car at 4 096). A native vector environment that cannot be made (its memory limit,
    ``MRD_ENV_MEMORY_LIMIT``) leaves its figure out, with the reason."""
    import gymnasium as gym
    import jax

    from mrd_env.jax import env as jenv

    env_id, options = PLANTS[name]
    rows, compile_s = [], {}
    for N in sizes:
        load0 = load_average()
        try:
            native = gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **options)
            native.reset(seed=0)
            refused = None
        except ValueError as exc:
            native, refused = None, str(exc)
        nd = jenv.assembly_of(env_id, options)[0].coupled.system.nd
        rng = np.random.default_rng(N)
        pool = [rng.uniform(-1.0, 1.0, (N, nd)) for _ in range(32)]
        cases = {}
        for label in schemes:
            if label == "exact" and exact_max_n is not None and N > exact_max_n:
                continue
            params = jenv.make_params(env_id, seeds=range(bank), **SCHEMES[label], **options)
            keys = jax.random.split(jax.random.PRNGKey(0), N)
            _, states = jax.vmap(jenv.reset, in_axes=(0, None))(keys, params)

            def vstep(key, states, actions, params):
                out = jax.vmap(jenv.step_autoreset, in_axes=(0, 0, 0, None))(jax.random.split(key, N), states,
                                                                             actions, params)
                return out[0], out[1], out[2]

            fn, compile_s[f"{label}, N={N}"] = compiled(vstep, jax.random.PRNGKey(1), states, pool[0], params)
            cases[label] = [fn, states, params, jax.random.PRNGKey(2)]

        def run_native(n):
            t0 = time.perf_counter()
            for k in range(n):
                native.step(pool[k % len(pool)])
            return N * n / (time.perf_counter() - t0)

        def run_jax(case, n):
            fn, states, params, key = case
            t0 = time.perf_counter()
            for k in range(n):
                key, sub = jax.random.split(key)
                obs, states, r = fn(sub, states, pool[k % len(pool)], params)
                obs, r = np.asarray(obs), np.asarray(r)  # as a VectorEnv hands them back
            case[1], case[3] = states, key
            return N * n / (time.perf_counter() - t0)

        # a warm-up step, then a short run sizes each timed run to about `window` seconds (a first call's one-off
        # costs in the sizing run made the timed runs a few steps long)
        counts = {}
        if native is not None:
            run_native(1)
            counts["native"] = max(2, int(window * run_native(2) / N))
        for label, case in cases.items():
            run_jax(case, 1)
            counts[label] = max(2, int(window * run_jax(case, 2) / N))
        rates: dict[str, list] = {k: [] for k in counts}
        for _ in range(repeats):
            if native is not None:
                rates["native"].append(run_native(counts["native"]))
            for label, case in cases.items():
                rates[label].append(run_jax(case, counts[label]))
        threads = None
        if native is not None:
            threads = native.unwrapped.core.driver.threads
            native.close()
        ref = float(np.median(rates["native"])) if native is not None else None
        row = {"plant": name, "N": N, "native": ref}
        for label in schemes:
            row[f"jax_{label}"] = float(np.median(rates[label])) if label in rates else None
            row[f"x_{label}"] = row[f"jax_{label}"] / ref if label in rates and ref else None
        row.update(steps_timed=counts, native_threads=threads, load_before=load0, load_after=load_average())
        if refused:
            row["native_refused"] = refused
        rows.append(row)
        print(row, flush=True)
    return rows, compile_s


def _worst(rows: list[dict]) -> dict:
    """One row per plant: the worst (largest) figure over its episodes."""
    out = {"plant": rows[0]["plant"], "episodes": len(rows)}
    for k, v in rows[0].items():
        if k in ("plant", "seed"):
            continue
        vals = [r[k] for r in rows]
        if isinstance(v, str):
            out[k] = rows[int(np.argmax([r[k.removesuffix("_at")] for r in rows]))][k]
        else:
            out[k] = all(vals) if isinstance(v, bool) else (min(vals) if k == "steps" else max(vals))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plants", default=",".join(PLANTS), help=f"comma-separated, among {', '.join(PLANTS)}")
    ap.add_argument("--episodes", type=int, default=4, help="held-out episodes per plant")
    ap.add_argument("--seconds", type=float, default=10.0, help="seconds of each episode compared")
    ap.add_argument("--n", default="1024,4096", help="batch sizes of the throughput runs (comma-separated; '' for "
                                                     "none)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per figure; the median is reported")
    ap.add_argument("--window", type=float, default=1.5, help="seconds of one timed run")
    ap.add_argument("--exact-max-n", type=int, default=1024, help="largest N the exact scheme's speed is timed at")
    ap.add_argument("--parts", default="accuracy,speed", help="comma-separated, among accuracy, speed")
    ap.add_argument("--out", type=Path, default=Path("results/bench_jax_plants.json"))
    args = ap.parse_args(argv)
    plants = [p for p in args.plants.split(",") if p]
    unknown = sorted(set(plants) - set(PLANTS))
    if unknown or not plants:
        ap.error(f"--plants must name plants among {', '.join(PLANTS)}, got {unknown or args.plants!r}")
    if args.episodes < 1 or args.seconds <= 0 or args.repeats < 1 or args.window <= 0:
        ap.error("--episodes and --repeats must be >= 1, --seconds and --window > 0")
    try:
        sizes = [int(x) for x in args.n.split(",") if x]
    except ValueError:
        ap.error(f"--n must be comma-separated integers, got {args.n!r}")
    if any(s < 1 for s in sizes):
        ap.error(f"--n must be >= 1, got {args.n!r}")
    parts = set(args.parts.split(","))
    if not parts or parts - {"accuracy", "speed"}:
        ap.error(f"--parts must name parts among accuracy, speed, got {args.parts!r}")
    if "speed" not in parts:
        sizes = []
    import jax

    import mrd_env  # noqa: F401  (registers the environments)
    import mrd_env.jax  # noqa: F401  (float64)

    jax.config.update("jax_enable_compilation_cache", False)  # cold compile times
    from mrd_env.report import markdown_table
    from mrd_env.stepping.first_use import set_mode
    from mrd_env.storage import writable_folder, write_json

    set_mode("wait")  # the compiled numba kernel, never the interpreted one of a first use
    writable_folder(args.out.parent)
    out = {"jax": jax.__version__, "device": str(jax.devices()[0]), "cpus": os.cpu_count(),
           "machine": platform.platform(), "xla_flags": os.environ.get("XLA_FLAGS", ""), "load_start": load_average(),
           "episodes": args.episodes, "seconds": args.seconds, "held_out_seeds_from": HELD_OUT,
           "accuracy": [], "compile_seconds": [], "throughput": []}
    for name in plants:
        crow = {"plant": name}
        if "accuracy" in parts:
            rows, cs = accuracy(name, args.episodes, args.seconds)
            out["accuracy"] += rows
            crow.update({f"step_{k}": v for k, v in cs.items()})
        if sizes:
            trows, tcs = throughput(name, sizes, args.repeats, args.window, exact_max_n=args.exact_max_n)
            out["throughput"] += trows
            crow.update({f"vmapped_{k}": v for k, v in tcs.items()})
        out["compile_seconds"].append(crow)
        print(crow, flush=True)
        out["load_end"] = load_average()
        write_json(args.out, out, indent=1)  # after each plant: a partial run keeps what it measured
    md = []
    if "accuracy" in parts:
        worst = [_worst([r for r in out["accuracy"] if r["plant"] == p]) for p in plants]
        md.append(markdown_table(worst, title=f"Worst over {args.episodes} held-out episodes of {args.seconds:g} s: "
                                              f"exact vs native; differentiable vs exact", floatfmt=".2g"))
        md.append(markdown_table([{"plant": r["plant"], **{k: v for k, v in r.items() if k.startswith("step_")}}
                                  for r in out["compile_seconds"]], title="Cold compile of the jitted step (s)",
                                 floatfmt=".3g"))
    if sizes:
        md.append(markdown_table([{k: v for k, v in r.items() if k not in ("steps_timed", "native_refused")}
                                  for r in out["throughput"]],
                                 title="Env-steps/s at 10 ms control, random actions (median of "
                                       f"{args.repeats})", floatfmt=".3g"))
        md.append(markdown_table([{"plant": r["plant"], **{k: v for k, v in r.items() if k.startswith("vmapped_")}}
                                  for r in out["compile_seconds"]], title="Cold compile of the vmapped step (s)",
                                 floatfmt=".3g"))
    out["markdown"] = "\n".join(md)
    write_json(args.out, out, indent=1)
    print(out["markdown"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
