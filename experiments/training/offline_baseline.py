"""The offline baseline of the preview suite, measured (issue 53 item 3): MPC with road preview recorded on the quarter
car's **training distribution** as a Minari dataset, behaviour cloning and TD3+BC trained on it, and both scored on
``car-preview-v1`` against the shipped SHAC and CMA-ES preview agents (and the MPC itself), paired on the same
episodes. Every step is the command a user would type, run in this process::

    python -m experiments.training.offline_baseline                    # ~25 min on one core
    python -m experiments.training.offline_baseline --episodes 20 --bc-steps 2000 --td3bc-steps 2000   # a smoke run

1. the training distribution as a reference-free suite file (:func:`~experiments.training.offline.write_training_suite`:
   seeds 0 … episodes − 1, training's seeds, never the suite's 1 000 000 …), with car-preview-v1's sensors and step;
2. ``mrd-env dataset --suite <that file> --controller "mpc+preview (reward)"``;
3. ``mrd-env train --plant quarter_car --algo bc --preview --dataset <it>`` and the same with ``--algo td3bc``;
4. the agents (the run folders' own, last agents: no selection on the environment) scored on car-preview-v1 with
   :func:`experiments.benchmark.scoring.score`, the pooled shares and the paired comparisons of
   :mod:`experiments.benchmark.aggregate`.

Writes ``<out>/offline_baseline.json`` and ``.md`` (the figures, wall times, loads, commands); ``<out>/datasets`` and
``<out>/agents`` hold the dataset and the agents.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import time
from pathlib import Path

#: The suite scored on, and what the baselines are compared with on its episodes.
SUITE = "car-preview-v1"
EXPERT = "mpc+preview (reward)"
REFERENCES = ("quarter_car_shac_preview", "quarter_car_cmaes_preview", EXPERT)


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else []


def _cli(argv: list[str]) -> tuple[float, list[float], list[float]]:
    """``mrd-env`` with ``argv`` in this process; its wall time (s) and the load average before and after."""
    from experiments.cli import main

    load0, t0 = _load(), time.perf_counter()
    code = main(argv)
    if code != 0:
        raise SystemExit(f"mrd-env {shlex.join(argv)} exited {code}")
    return time.perf_counter() - t0, load0, _load()


def _size(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=200, help="training episodes recorded (seeds 0 …; default 200)")
    p.add_argument("--seed", type=int, default=0, help="the agents' seed (default 0)")
    p.add_argument("--bc-steps", type=int, default=None, help="BC's gradient steps (default: bc.yml's)")
    p.add_argument("--td3bc-steps", type=int, default=None, help="TD3+BC's gradient steps (default: td3bc.yml's)")
    p.add_argument("--eval-freq", type=int, default=10_000, help="validation every so many gradient steps")
    p.add_argument("--out", type=Path, default=Path("results/offline"))
    args = p.parse_args(argv)

    from mrd_env import storage
    from mrd_env.report import markdown_table

    from experiments.benchmark.aggregate import ALL, paired_comparison
    from experiments.benchmark.dataset import resolve_controller
    from experiments.benchmark.scoring import resolve_suite, score
    from experiments.common.plants import profile
    from experiments.training.offline import write_training_suite

    out = args.out
    from mrd_env.suites import suite

    plant = profile(suite(SUITE).plant)  # the suite's plant
    suite_file = write_training_suite(out / "car-preview-training.json", plant, like=SUITE, episodes=args.episodes)
    data_root = out / "datasets"
    record = ["dataset", "--suite", str(suite_file), "--controller", EXPERT, "--out", str(data_root), "--overwrite",
              "--no-progress"]
    wall, l0, l1 = _cli(record)
    from experiments.benchmark.dataset import load
    from experiments.training.offline import dataset_folders

    folder = dataset_folders(data_root)[0]
    ds = load(str(folder.relative_to(data_root)), data_root)
    eps = list(ds.iterate_episodes())
    dataset = {"id": ds.spec.dataset_id, "folder": str(folder), "episodes": ds.total_episodes,
               "steps": ds.total_steps, "terminated_episodes": int(sum(bool(e.terminations[-1]) for e in eps)),
               "seeds": [0, args.episodes - 1], "size_bytes": _size(folder), "command_wall_s": wall,
               "load": [l0, l1], "command": ["mrd-env", *record],
               "mean_return": float(sum(float(e.rewards.sum()) for e in eps) / len(eps))}
    print(f"dataset {dataset['id']}: {dataset['episodes']} episodes, {dataset['steps']} steps, "
          f"{dataset['size_bytes'] / 1e6:.1f} MB, {wall:.1f} s", flush=True)

    agents = {}
    for algo, steps in (("bc", args.bc_steps), ("td3bc", args.td3bc_steps)):
        train = ["train", "--plant", suite(SUITE).plant, "--algo", algo, "--preview", "--dataset", str(data_root),
                 "--seeds", str(args.seed), "--eval-freq", str(args.eval_freq), "--out", str(out / "agents"),
                 "--no-progress", *(["--timesteps", str(steps)] if steps else [])]
        wall, l0, l1 = _cli(train)
        run_dir = out / "agents" / f"quarter_car_{algo}-preview_s{args.seed}"
        meta = json.loads((run_dir / "agent.json").read_text(encoding="utf-8"))
        agents[algo] = {"folder": str(run_dir), "name": meta["name"], "command_wall_s": wall, "load": [l0, l1],
                        "training_wall_s": meta["wall_time_s"], "gradient_steps": meta["gradient_steps"],
                        "command": ["mrd-env", *train]}
        print(f"{meta['name']}: {wall:.1f} s", flush=True)

    suite = resolve_suite(SUITE)
    results, timing = {}, {}
    for name, controller in [*((a["name"], a["folder"]) for a in agents.values()), *((r, r) for r in REFERENCES)]:
        t0, l0 = time.perf_counter(), _load()
        spec = resolve_controller(controller, suite, name=name if controller != EXPERT else None)
        results[name] = score(suite, spec, backend="serial")
        timing[name] = {"wall_s": time.perf_counter() - t0, "load": [l0, _load()]}
    pooled = {n: {s: list(v) for s, v in r.pooled_shares().items()} for n, r in results.items()}
    paired = {}
    for a in agents.values():
        for ref in REFERENCES:
            paired[f"{a['name']} vs {ref}"] = paired_comparison(results[a["name"]], results[ref], suite)

    report = {"suite": {"id": suite.id, "digest": suite.digest}, "dataset": dataset, "agents": agents,
              "pooled_share": pooled, "paired": paired, "scoring": timing,
              "command": ["python", "-m", "experiments.training.offline_baseline", *(argv or [])]}
    storage.write_json(out / "offline_baseline.json", report, indent=1)

    def cell(v):
        return f"{v[0]:.3f} [{v[1]:.3f}, {v[2]:.3f}]" if v[1] == v[1] else f"{v[0]:.3f}"

    scenarios = list(next(iter(pooled.values())))
    lines = [f"# Offline baselines on {suite.id}", "",
             f"Dataset {dataset['id']}: {dataset['episodes']} episodes ({dataset['terminated_episodes']} terminated), "
             f"{dataset['steps']} steps, {dataset['size_bytes'] / 1e6:.2f} MB, {dataset['command_wall_s']:.1f} s "
             f"(load {dataset['load'][0]} to {dataset['load'][1]}).", "",
             "Pooled share of the achievable gain [bootstrap 95 % interval]:", "",
             markdown_table([{"controller": n, **{s: cell(v[s]) for s in scenarios}} for n, v in pooled.items()]), "",
             "Paired on the same episodes (difference of pooled shares [paired 95 % interval], episodes won, verdict), "
             f"over {ALL}:", "",
             markdown_table([{"comparison": k, **{"difference": cell((r[-1]["difference"], r[-1]["lo95"], r[-1]["hi95"])),
                                                  "won": f"{r[-1]['won']}/{r[-1]['episodes']}",
                                                  "verdict": r[-1]["verdict"]}} for k, r in paired.items()]), "",
             "Training: " + "; ".join(f"{a['name']} {a['gradient_steps']} gradient steps, {a['training_wall_s']:.0f} s "
                                      f"(load {a['load'][0]} to {a['load'][1]})" for a in agents.values()), ""]
    storage.write_text(out / "offline_baseline.md", "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
