"""Training throughput of PPO inside one jit on the JAX quarter car (:mod:`experiments.training.ppo_jax`) against
Stable-Baselines3's PPO on the native vector environment, in the same run (issue 41, item 3c).

Run: ``nice -n 10 python -m experiments.measurements.speed.ppo_jax [--sizes 64 256] [--num-steps 128] [--updates 3]
[--repeats 3] [--exact-size 64] [--out results/bench/ppo_jax]``; writes ``<out>.md`` and ``<out>.csv``.

For each N: the JAX training (``--updates`` updates of N × ``--num-steps`` env-steps, the differentiable scheme
and, at ``--exact-size``, the exact one) compiled once (cold: JAX's persistent cache is switched off here; the
compile time is reported apart), then timed per seed; SB3's ``PPO("MlpPolicy")`` with the same settings (n_steps,
batch = N × n_steps / 4 minibatches, 4 epochs, γ, λ, clip, learning rate 3e-4, 64×64 tanh networks for the policy and the
value, the same initial log-std, observations normalised by ``VecNormalize``, rewards not) on
``make_sb3_vec_env("mrd_env/QuarterCar-v1", n_envs=N)`` (the bridge over ``gymnasium.make_vec``'s native vector
environment, its thread tuner on), torch on one thread, timed over ``model.learn`` of as many env-steps. The two
alternate ``--repeats`` times; the figure is the median env-steps/s (simulation and learning together), with the
load average before and after each row. Both train on 10 s ISO 8608 roads (JAX: a bank of 32 roads of classes
B, C, D at 10–30 m/s; native: its default road, a new class-C road at 20 m/s each episode).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from experiments.training import ppo_jax as pj

#: The PPO settings both trainers share here (SB3's learning rate, epochs and minibatch count; fixed, so that the
#: figures do not move with ppo_jax's defaults).
SETTINGS = {"update_epochs": 4, "num_minibatches": 4, "lr": 3e-4, "hidden": (64, 64)}


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def jax_runner(n: int, num_steps: int, updates: int, scheme: str):
    """(a function seed → seconds of one training, the compile time)."""
    import jax

    cfg = pj.Config(num_envs=n, num_steps=num_steps, total_timesteps=n * num_steps * updates, **SETTINGS)
    params = pj.env_params(seed=0, scheme=scheme)
    t0 = time.perf_counter()
    compiled = jax.jit(pj.make_train(cfg)).lower(jax.random.PRNGKey(0), params).compile()
    compile_s = time.perf_counter() - t0

    def one(seed: int) -> float:
        t = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.PRNGKey(seed), params))
        return time.perf_counter() - t

    return one, compile_s


def sb3_run(n: int, num_steps: int, updates: int, seed: int) -> float:
    """Seconds of SB3's ``model.learn`` over ``updates`` rollouts of N × ``num_steps`` env-steps."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from mrd_env.envs.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)
    cfg = pj.Config(**SETTINGS)
    venv = VecNormalize(make_sb3_vec_env(pj.ENV_ID, n_envs=n, seed=seed), norm_obs=True, norm_reward=False,
                        clip_obs=cfg.obs_clip)
    model = PPO("MlpPolicy", venv, n_steps=num_steps, batch_size=n * num_steps // cfg.num_minibatches,
                n_epochs=cfg.update_epochs, learning_rate=cfg.lr, gamma=cfg.gamma, gae_lambda=cfg.gae_lambda,
                clip_range=cfg.clip_eps, ent_coef=cfg.ent_coef, vf_coef=cfg.vf_coef, max_grad_norm=cfg.max_grad_norm,
                policy_kwargs={"net_arch": {"pi": list(cfg.hidden), "vf": list(cfg.hidden)},
                               "activation_fn": torch.nn.Tanh, "log_std_init": cfg.log_std_init},
                seed=seed, device="cpu", verbose=0)
    t = time.perf_counter()
    model.learn(total_timesteps=n * num_steps * updates)
    wall = time.perf_counter() - t
    venv.close()
    return wall


def bench(sizes, num_steps: int, updates: int, repeats: int, exact_size: int | None) -> list[dict]:
    import jax

    jax.config.update("jax_enable_compilation_cache", False)  # cold compile times
    rows = []
    for n in sizes:
        steps = n * num_steps * updates
        load0 = _load()
        schemes = ["differentiable"] + (["exact"] if n == exact_size else [])
        runners = {}
        for s in schemes:
            runners[s] = jax_runner(n, num_steps, updates, s)
            print(f"N={n} {s}: compiled in {runners[s][1]:.1f} s (load {_load()})", flush=True)
        walls = {s: [] for s in schemes} | {"sb3": []}
        for r in range(repeats):
            for s in schemes:
                walls[s].append(runners[s][0](r))
            walls["sb3"].append(sb3_run(n, num_steps, updates, r))
            print(f"N={n} repeat {r}: " + ", ".join(f"{k} {steps / w[-1]:.0f}" for k, w in walls.items())
                  + f" env-steps/s (load {_load()})", flush=True)
        sb3 = steps / statistics.median(walls["sb3"])
        for k, w in walls.items():
            rate = steps / statistics.median(w)
            rows.append({"N": n, "trainer": "SB3 PPO, native vector env" if k == "sb3" else f"PPO in jit, JAX {k}",
                         "env-steps per run": steps, "env-steps/s (median)": rate,
                         "each run": " ".join(f"{steps / x:.0f}" for x in w), "x SB3": rate / sb3,
                         "compile s": round(runners[k][1], 1) if k in runners else "",
                         "load before / after": f"{load0} / {_load()}"})
    return rows


def main(argv=None) -> int:
    from mrd_env.stepping.first_use import set_mode

    set_mode("wait")  # time the native compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 256])
    ap.add_argument("--num-steps", type=int, default=128)
    ap.add_argument("--updates", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--exact-size", type=int, default=64, help="N at which the exact scheme is timed too (0: none)")
    ap.add_argument("--out", type=Path, default=Path("results/bench/ppo_jax"))
    args = ap.parse_args(argv)
    if min(args.sizes) < 1 or args.num_steps < 1 or args.updates < 1 or args.repeats < 1:
        ap.error("--sizes, --num-steps, --updates and --repeats must be >= 1")
    import jax

    from mrd_env.report import markdown_table, write_table

    rows = bench(args.sizes, args.num_steps, args.updates, args.repeats, args.exact_size or None)
    title = (f"PPO training throughput, {args.num_steps} steps per rollout, {args.updates} updates per run, "
             f"median of {args.repeats}; {os.cpu_count()} cores, jax {jax.__version__} float64 on "
             f"{jax.devices()[0].platform}")
    print(markdown_table(rows, title=title))
    for path in write_table(rows, args.out, title=title):
        print("wrote", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
