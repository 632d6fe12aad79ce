"""The JAX twin of the quarter car (:mod:`mrd_env.jax`) against the numba kernel, the Radau references and the
native vector environment (issue 41's must-show figures).

Run: ``nice -n 10 python -m experiments.measurements.speed.jax_quarter_car [--sizes 1024 4096] [--repeats 5] [--episodes 4]
[--out results/bench]`` (CPU; needs ``pip install mrd-env[jax]``). Writes ``<out>/jax.json`` and prints a table.

1. exact scheme vs the numba kernel: held-out 10 s class-C episodes (road seeds 1000+), a random command per
   10 ms period, both damper families: the largest difference of each state over the episode relative to that
   state's peak, the largest relative difference of the forces, and of the rewards against the native
   ``QuarterCar-v1`` on the same road and actions.
2. differentiable scheme vs Radau on the stepping page's accuracy cases (the rig, 1.5 cm at 2.5 and 25 Hz,
   15 cm at 2.5 Hz; worst force NRMSE over 0, 0.75, 1.5, 2.25 V), 1 and 2 sub-steps; and vs the exact scheme on
   the car episodes of 1 (force NRMSE).
3. ``jax.grad`` of an episode's cost (−Σ rewards, 10 s, 1 000 commands, differentiable scheme) vs fourth-order
   central finite differences (h = 1e-4) on 8 random commands: the relative error of those components (norm-wise
   and worst); the time of one gradient.
4. throughput at 10 ms control: env-steps/s of ``jax.vmap`` of the step (autoreset included) called once per
   step from Python (as a VectorEnv would) and of a ``lax.scan`` of 100 steps inside one jitted call (as a
   PureJaxRL loop), next to ``gymnasium.make_vec("mrd_env/QuarterCar-v1", num_envs=N,
   vectorization_mode="vector_entry_point")`` in the same run, interleaved, median of ``--repeats``; actions
   alternate between −1 and 1 every 50 steps (as ``bench_vector_speed``) and, second pattern, uniform random.
   The load average is recorded around each section.

Compile times are those of a cold compilation (JAX's persistent cache is switched off here).
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np


def load_average() -> float:
    """The 1-minute load average, as the benchmarks record it."""
    return round(os.getloadavg()[0], 2)


def compiled(fn, *args):
    """(compiled function, seconds to compile it)."""
    import jax

    t0 = time.perf_counter()
    c = jax.jit(fn).lower(*args).compile()
    return c, time.perf_counter() - t0


def exact_vs_numba(episodes: int) -> tuple[list[dict], dict]:
    import gymnasium as gym
    import jax
    import jax.numpy as jnp

    from mrd_env.disturbances import iso8608_road
    from mrd_env.envs import options as opt
    from mrd_env.plants.quarter_car import jax_twin as qc
    from mrd_env.mechanics import CoupledPlant
    from mrd_env.plants.quarter_car.physics import quarter_car

    rows, compile_s = [], {}
    roads = [iso8608_road("C", 20.0, 10.0, 1e-3, rng=1000 + i, method="fft") for i in range(episodes)]
    for damper in ("spencer_dyke", "bouc_wen"):
        p = {s: qc.make_params(roads=roads, damper=damper, scheme=s, substeps=k, action_mode="physical")
             for s, k in (("exact", 1), ("differentiable", 1))}
        p["differentiable2"] = qc.make_params(roads=roads, damper=damper, scheme="differentiable", substeps=2,
                                              action_mode="physical")

        def episode(params, state, cmds):
            def body(s, a):
                obs, s, r, te, tr, info = qc.step(None, s, a, params)
                return s, (s.Y, s.F, r, info["substeps"])
            return jax.lax.scan(body, state, cmds)[1]

        d = opt.make_env_damper(damper, None, None, "automotive")
        for e, rec in enumerate(roads):
            rng = np.random.default_rng(2000 + e)
            cmds = rng.uniform(d.command.v_min, d.command.v_max, p["exact"].n_steps)
            out = {}
            for label, params in p.items():
                _, s0 = qc.reset(None, params, record=e)
                fn = jax.jit(episode)
                if e == 0:
                    fn, compile_s[f"episode scan, {label}, {damper}"] = compiled(episode, params, s0,
                                                                                 jnp.asarray(cmds))
                out[label] = [np.asarray(a) for a in fn(params, s0, jnp.asarray(cmds))]
            # the numba kernel, one call per control period (as the environment)
            params = p["exact"]
            cp = CoupledPlant(quarter_car("set_a").plant(), d, N=1, n_steps=params.n_sub)
            road = np.asarray(params.W[e, :, :2])
            cp.reset(np.array([road[0, 0], road[0, 0], road[0, 1], road[0, 1]]))
            Yn, Fn = [], []
            for k in range(params.n_steps):
                F, Y = cp.step(np.full((1, params.n_sub, 1), cmds[k]),
                               road[None, k * params.n_sub:(k + 1) * params.n_sub + 1])
                Yn.append(Y[0, -1, :out["exact"][0].shape[1]].copy())
                Fn.append(F[0, -1, 0])
            Yn, Fn = np.array(Yn), np.array(Fn)
            Yj, Fj = out["exact"][0], out["exact"][1][:, 0]
            # the native environment's rewards on the same road and commands
            env = gym.make("mrd_env/QuarterCar-v1", road=rec, damper=damper, action_mode="physical")
            env.reset(seed=0)
            rn = np.array([env.step(np.array([c], np.float32))[1] for c in cmds.astype(np.float32)])
            env.close()
            _, s0 = qc.reset(None, params, record=e)
            rj = np.asarray(jax.jit(episode)(params, s0, jnp.asarray(cmds.astype(np.float32), jnp.float64))[2])
            peak = np.maximum(np.abs(Yn).max(axis=0), 1e-300)
            row = {"damper": damper, "episode": e,
                   "exact_vs_numba_states_rel_to_peak": float((np.abs(Yj - Yn) / peak).max()),
                   "exact_vs_numba_force_rel": float(np.abs(Fj - Fn).max() / np.abs(Fn).max()),
                   "exact_vs_native_reward_rel": float(np.abs(rj - rn).max() / np.abs(rn).max()),
                   "exact_substeps_per_step": float(np.mean(out["exact"][3]))}
            for label in ("differentiable", "differentiable2"):
                Fd = out[label][1][:, 0]
                row[f"{label}_vs_exact_force_nrmse"] = float(np.sqrt(np.mean((Fd - Fj) ** 2) / np.mean(Fj ** 2)))
                row[f"{label}_vs_exact_force_peak_rel"] = float(np.abs(Fd - Fj).max() / np.abs(Fj).max())
            rows.append(row)
            print(row, flush=True)
    return rows, compile_s


def accuracy_vs_radau() -> list[dict]:
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tests.reference_models import bouc_wen_reference, nrmse, spencer_dyke_reference  # the tests' references

    from mrd_env.dampers import make_damper
    from mrd_env.jax.simulate import run
    from mrd_env.stepping import SystemMatrices

    dt = 1e-3
    rows = []
    for model, reference in (("spencer_dyke", spencer_dyke_reference), ("bouc_wen", bouc_wen_reference)):
        d = make_damper(model, "spencer1997")
        for X, f, T in ((0.015, 2.5, 2.0), (0.015, 25.0, 0.4), (0.15, 2.5, 2.0)):
            worst: dict[str, float] = {}
            for V in (0.0, 0.75, 1.5, 2.25):
                n = int(round(T / dt))
                t = np.arange(n + 1) * dt
                w = 2 * np.pi * f
                W = np.stack([X * np.sin(w * t), X * w * np.cos(w * t), -X * w * w * np.sin(w * t)], axis=1)
                _, F_ref = reference(d.params, d.command.eta, X, f, V, T, dt, "Radau")
                for label, opts in (("exact", {"scheme": "exact"}),
                                    ("differentiable_1_substep", {"scheme": "differentiable", "substeps": 1}),
                                    ("differentiable_2_substeps", {"scheme": "differentiable", "substeps": 2})):
                    F = np.asarray(run(d, SystemMatrices.displacement_driven(), d.initial_state(), np.zeros(1),
                                       np.full((n, 1), V), W, dt, **opts)[0][:, 0])
                    worst[label] = max(worst.get(label, 0.0), nrmse(F, F_ref))
            row = {"model": model, "case": f"{100 * X:g} cm @ {f:g} Hz",
                   **{f"{k}_nrmse_pct": 100 * v for k, v in worst.items()}}
            rows.append(row)
            print(row, flush=True)
    return rows


def gradient_check() -> dict:
    import jax
    import jax.numpy as jnp

    from mrd_env.plants.quarter_car import jax_twin as qc

    params = qc.make_params(n_roads=1, seed=3000, scheme="differentiable")
    _, s0 = qc.reset(None, params, record=0)

    def cost(a):
        return -jnp.sum(qc.rollout(params, s0, a)[2])

    rng = np.random.default_rng(3)
    a = jnp.asarray(rng.uniform(-0.8, 0.8, params.n_steps))
    g, t_compile = compiled(jax.grad(cost), a)
    c, t_compile_cost = compiled(cost, a)
    t0 = time.perf_counter()
    gv = np.asarray(g(a))
    t_grad = time.perf_counter() - t0
    t0 = time.perf_counter()
    float(c(a))
    t_cost = time.perf_counter() - t0
    h = 1e-4
    idx = rng.choice(params.n_steps, 8, replace=False)
    fd = []
    for i in idx:
        e = np.zeros(params.n_steps)
        e[i] = h
        f = [float(c(a + k * e)) for k in (-2, -1, 1, 2)]
        fd.append((f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h))
    fd = np.array(fd)
    return {"commands": params.n_steps, "components": idx.tolist(), "grad": gv[idx].tolist(), "fd": fd.tolist(),
            "rel_error_normwise": float(np.linalg.norm(gv[idx] - fd) / np.linalg.norm(fd)),
            "rel_error_worst_component": float(np.max(np.abs(gv[idx] - fd) / np.abs(fd))),
            "grad_seconds": t_grad, "cost_seconds": t_cost, "grad_compile_seconds": t_compile,
            "cost_compile_seconds": t_compile_cost, "load": load_average()}


def throughput(sizes, repeats: int, seconds: float) -> tuple[list[dict], dict]:
    import gymnasium as gym
    import jax
    import jax.numpy as jnp

    import mrd_env  # noqa: F401
    from mrd_env.plants.quarter_car import jax_twin as qc

    rows, compile_s = [], {}
    for N in sizes:
        load0 = load_average()
        native = gym.make_vec("mrd_env/QuarterCar-v1", num_envs=N, vectorization_mode="vector_entry_point")
        native.reset(seed=0)
        cases = {}
        for scheme, substeps in (("differentiable", 1), ("differentiable", 2), ("exact", 1)):
            params = qc.make_params(n_roads=16, scheme=scheme, substeps=substeps)
            keys = jax.random.split(jax.random.PRNGKey(0), N)
            obs, states = jax.vmap(qc.reset, in_axes=(0, None))(keys, params)

            def vstep(key, states, actions, params=params):
                keys = jax.random.split(key, N)
                return jax.vmap(qc.step_autoreset, in_axes=(0, 0, 0, None))(keys, states, actions, params)[1:3]

            def vscan(key, states, actions, params=params):
                def body(c, a):
                    k, s = c
                    k, sub = jax.random.split(k)
                    s, r = vstep(sub, s, a)
                    return (k, s), r.sum()
                return jax.lax.scan(body, (key, states), actions)

            label = f"{scheme}" + (f", {substeps} sub-steps" if scheme == "differentiable" else "")
            a1 = jnp.zeros((N, 1))
            step_fn, compile_s[f"vmapped step, {label}, N={N}"] = compiled(vstep, jax.random.PRNGKey(1), states, a1)
            scan_fn, compile_s[f"scan of 100 vmapped steps, {label}, N={N}"] = compiled(
                vscan, jax.random.PRNGKey(1), states, jnp.zeros((100, N, 1)))
            cases[label] = (step_fn, scan_fn, states)
        for pattern in ("alternating", "random"):
            rng = np.random.default_rng(0)

            def actions(k, pattern=pattern, rng=rng):
                if pattern == "alternating":
                    return np.full((N, 1), 1.0 if (k // 50) % 2 else -1.0)
                return rng.uniform(-1, 1, (N, 1))

            acts = [actions(k) for k in range(400)]
            jacts = [jnp.asarray(a) for a in acts]
            seq = jnp.asarray(np.stack(acts[:100]))

            def time_native(n):
                t0 = time.perf_counter()
                for k in range(n):
                    native.step(acts[k % 400])
                return N * n / (time.perf_counter() - t0)

            def time_step(fn, states, n):
                key = jax.random.PRNGKey(2)
                t0 = time.perf_counter()
                s = states
                for k in range(n):
                    s, r = fn(key, s, jacts[k % 400])
                r.block_until_ready()
                return N * n / (time.perf_counter() - t0), s

            def time_scan(fn, states):
                t0 = time.perf_counter()
                (_, s), r = fn(jax.random.PRNGKey(3), states, seq)
                r.block_until_ready()
                return N * 100 / (time.perf_counter() - t0), s

            n_native = max(10, int(seconds * time_native(10) / N))
            rates: dict[str, list] = {"native": []}
            n_jax = {}
            for label, (fs, _, st) in cases.items():
                n_jax[label] = max(10, int(seconds * time_step(fs, st, 5)[0] / N))
            for _ in range(repeats):
                rates["native"].append(time_native(n_native))
                for label, (fs, fsc, st) in cases.items():
                    r, st = time_step(fs, st, n_jax[label])
                    rates.setdefault(f"jax {label}, one call per step", []).append(r)
                    r, st = time_scan(fsc, st)
                    rates.setdefault(f"jax {label}, scan of 100 steps in one call", []).append(r)
                    cases[label] = (fs, fsc, st)
            ref = float(np.median(rates["native"]))
            for label, rs in rates.items():
                rows.append({"N": N, "actions": pattern, "environment": label,
                             "env_steps_per_s": float(np.median(rs)), "x_native": float(np.median(rs)) / ref,
                             "load_before": load0, "load_after": load_average()})
                print(rows[-1], flush=True)
        native.close()
    return rows, compile_s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024, 4096])
    ap.add_argument("--repeats", type=int, default=5, help="timing runs per row; the median is reported")
    ap.add_argument("--seconds", type=float, default=1.0, help="length of one timing run")
    ap.add_argument("--episodes", type=int, default=4, help="held-out car episodes per damper (part 1)")
    ap.add_argument("--parts", nargs="+", default=["exact", "radau", "grad", "speed"],
                    choices=["exact", "radau", "grad", "speed"])
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    import jax

    jax.config.update("jax_enable_compilation_cache", False)  # cold compile times
    import mrd_env.jax  # noqa: F401  (float64)
    from mrd_env.report import markdown_table
    from mrd_env.stepping.first_use import set_mode
    from mrd_env.storage import write_json, write_text

    set_mode("wait")  # the compiled numba kernel, never the interpreted one of a first use
    out = {"jax": jax.__version__, "device": str(jax.devices()[0]), "cpus": os.cpu_count(),
           "machine": platform.platform(), "xla_flags": os.environ.get("XLA_FLAGS", ""), "load_start": load_average(),
           "compile_seconds": {}}
    md = []
    if "exact" in args.parts:
        rows, cs = exact_vs_numba(args.episodes)
        out["exact_vs_numba"], out["load_after_exact"] = rows, load_average()
        out["compile_seconds"].update(cs)
        md.append(markdown_table(rows, title="Exact scheme vs the numba kernel (and differentiable vs exact)",
                                 floatfmt=".3g"))
    if "radau" in args.parts:
        out["accuracy_vs_radau"] = accuracy_vs_radau()
        md.append(markdown_table(out["accuracy_vs_radau"], title="Force NRMSE against Radau (%)", floatfmt=".3g"))
    if "grad" in args.parts:
        out["gradient"] = gradient_check()
        g = {k: v for k, v in out["gradient"].items() if not isinstance(v, list)}
        md.append(markdown_table([g], title="jax.grad vs finite differences", floatfmt=".3g"))
    if "speed" in args.parts:
        rows, cs = throughput(args.sizes, args.repeats, args.seconds)
        out["throughput"] = rows
        out["compile_seconds"].update(cs)
        md.append(markdown_table(rows, title="Env-steps/s at 10 ms control (median of repeats)", floatfmt=".3g"))
    md.append(markdown_table([{"function": k, "seconds": v} for k, v in out["compile_seconds"].items()],
                             title="Cold compile times", floatfmt=".3g"))
    out["load_end"] = load_average()
    args.out.mkdir(parents=True, exist_ok=True)
    suffix = "" if set(args.parts) == {"exact", "radau", "grad", "speed"} else "_" + "_".join(args.parts)
    write_json(args.out / f"jax{suffix}.json", out, indent=1)
    text = "\n\n".join(md)
    write_text(args.out / f"jax{suffix}.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
