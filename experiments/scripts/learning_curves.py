"""Learning curves of trained agents with their references: the laws' validation returns at the agents' control
step and sensors, and the clairvoyant optimum on the same validation episodes (the yardstick's full-knowledge
command sequence, :mod:`experiments.benchmark.yardstick`; cached, so a second call draws at once).

    python -m experiments.scripts.learning_curves --plant shear_building \
        --agents results/agents/shear_building_ppo-residual-paired_s* --out docs/building_ppo_learning_curves.png

The curves are the ``validation.csv`` of each agent folder (the seeds' own lines and their mean).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from experiments.common.plants import PlantProfile, plant_choices, plant_name, profile


def clairvoyant_reference(plant: PlantProfile, episodes: int = 8, progress: bool = True) -> float:
    """The mean clairvoyant return over the validation episodes the agents are selected on."""
    from experiments.common.scenarios import validation
    from experiments.benchmark.yardstick import yardsticks

    ys = yardsticks(plant, validation(plant, episodes), bound=False, progress=progress)
    return float(np.mean([y.clairvoyant for y in ys]))


def draw(plant: PlantProfile, agents: list[Path], out: Path, clairvoyant: bool = True, episodes: int = 8,
         title: str | None = None) -> Path | None:
    """The figure ``out`` for the agent folders ``agents`` (one plant, one set-up)."""
    from controllers.agents import OBSERVATION_OPTIONS, agent_files

    from experiments.commands.train import law_references, plot_seed_curves
    from experiments.training.trainers import env_options

    # the training distribution as the trainer defines it, with what the agent sees (agent.json stores ranges as
    # JSON lists, which the environments read as choices); the metadata alone: no policy is loaded
    meta = agent_files(agents[0])[1]
    env_kwargs = {**env_options(plant), **{k: v for k, v in meta["env_kwargs"].items() if k in OBSERVATION_OPTIONS}}
    # a residual agent's own law is drawn too (its validation at step 0)
    own = [meta["residual"]["law"]] if meta.get("residual") else []
    refs = law_references(plant, env_kwargs, episodes, extra_laws=own)
    if clairvoyant:
        refs["clairvoyant (full knowledge, 1 ms)"] = clairvoyant_reference(plant, episodes)
    return plot_seed_curves(agents, out, refs, title=title)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--plant", type=plant_name, choices=plant_choices(), required=True)
    p.add_argument("--agents", type=Path, nargs="+", required=True, help="agent folders written by mrd-env train")
    p.add_argument("--out", type=Path, required=True, help="the PNG to write")
    p.add_argument("--no-clairvoyant", action="store_true", help="laws only (no optimal-control solves)")
    p.add_argument("--title", help="the figure's title (default: the agents' common name and the seed count)")
    args = p.parse_args(argv)
    try:
        path = draw(profile(args.plant), args.agents, args.out, clairvoyant=not args.no_clairvoyant, title=args.title)
    except ValueError as exc:
        print(f"learning_curves: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
