"""``mrd-env train``: train agents on an mrd-env environment, following RL Zoo's conventions.

Hyperparameters per environment and algorithm come from YAML files shipped with the project
(``experiments/hyperparams/<algo>.yml``, RL Zoo's layout: ``n_envs``, ``n_timesteps``, ``policy``,
``normalize`` and the algorithm's own keyword arguments, keyed by environment id); ``--hyperparams`` names
another file, ``--set key=value`` overrides one entry. The agent trains on the training distribution of
:mod:`experiments.common.scenarios` (a new road or ground motion per episode) in the native vector environment through
the SB3 bridge, with observations (and rewards) normalised by ``VecNormalize``. During training it is evaluated
every ``--eval-freq`` steps on the validation scenarios (the training distribution on seeds training never
draws; the test scenarios are never seen), and the best agent is kept; checkpoints every ``--checkpoint-freq``
steps; learning curves as CSV (training episodes, validation) and PNG; TensorBoard logs with ``--tensorboard``;
several seeds in one command (``--seeds 0 1 2``); a progress bar. ``--algo cmaes`` trains a policy network with an
evolution strategy instead, on the same scenarios and with the same outputs (:mod:`.evolution`); ``--algo bc`` and
``--algo td3bc`` learn offline from recorded episodes (``--dataset FOLDER``: Minari datasets of ``mrd-env dataset``;
:mod:`experiments.training.offline`). Both are trainers
behind one interface (:mod:`.trainers`); the plant's environment, training distribution and validation come from its
profile (:mod:`.plants`).

Each run writes a folder ``<out>/<plant>_<algo>_s<seed>/`` holding the final agent (``agent.json``, the policy's
weights and the observation statistics, code-free: :func:`controllers.load_agent` reads them; SB3's ``model.zip``
to resume training), ``best/`` (the best validation agent), the checkpoints, ``training.monitor.csv``,
``validation.csv`` and ``learning_curve.png``; every agent save is atomic (:func:`controllers.agents.save_agent`).
``agent.json`` records the plant, the algorithm, the seed and budget, the environment options (``env_kwargs``), the
hyperparameters, the wall time and the command that reproduces the run.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

import numpy as np

from mrd_env.envs import RL_DEFAULTS

from ..common import sweep
from ..common.plants import (PlantProfile, add_plant_options, default_plant, plant_choices, plant_name, profile,
                             with_plant_options)
from experiments.training.sb3_trainer import check_laws, check_with_sb3
from experiments.training.trainers import (ALGOS, TRAINERS, available_algos, env_options, hyperparameters, residual_spec,
                               run_name, steps_label, train_one, validation_split)


def _parse_overrides(items) -> dict:
    import yaml

    out = {}
    for item in items or ():
        if "=" not in item:
            raise ValueError(f"--set expects key=value, got {item!r}")
        k, v = item.split("=", 1)
        value = yaml.safe_load(v)
        if isinstance(value, str):  # YAML 1.1 reads 1e-4 (no dot) as a string
            try:
                value = float(value)
            except ValueError:
                pass
        out[k.strip()] = value
    return out


#: One colour per reference, the same in every figure (the seeds are grey, their mean black).
REFERENCE_COLORS = {"passive_off": "C0", "passive_on": "C1", "skyhook_on_off": "C2", "skyhook_continuous": "C3",
                    "groundhook": "C4", "hybrid": "C5", "clipped_optimal": "C6", "clipped_optimal_reward": "C9",
                    "lyapunov": "C8", "clairvoyant": "darkgoldenrod"}
_OTHER_COLORS = ("navy", "teal", "maroon", "olive", "indigo")  # for references not named above


def _reference_color(name: str, fallback: int) -> str:
    return REFERENCE_COLORS.get(name.split(" ")[0], _OTHER_COLORS[fallback % len(_OTHER_COLORS)])


def plot_seed_curves(run_dirs, path: Path, references: dict[str, float] | None = None,
                     title: str | None = None) -> Path | None:
    """The validation returns of several seeds (each, and their mean) against environment steps, with
    horizontal ``references`` (e.g. the classical laws' validation returns). The y-axis spans the curves and
    the references near them; a reference far outside (the clairvoyant, usually) is named in the legend with
    its value instead of squeezing the curves flat."""
    import csv

    from mrd_env.report import figure, save_figure

    curves = []
    for d in run_dirs:
        val = Path(d) / "validation.csv"
        if val.exists():
            rows = list(csv.DictReader(val.open()))
            curves.append((Path(d).name, np.array([int(r["timesteps"]) for r in rows]),
                           np.array([float(r["validation_return"]) for r in rows])))
    if not curves:
        return None
    fig, ax = figure(figsize=(7, 4.3))
    styles = ("-", "--", ":", "-.")
    for i, (name, x, y) in enumerate(curves):
        ax.plot(x, y, lw=1.0, color="0.55", ls=styles[i % len(styles)], label=name)
    n = min(len(y) for _, _, y in curves)
    ax.plot(curves[0][1][:n], np.mean([y[:n] for _, _, y in curves], axis=0), "k-", lw=1.8, label="mean over seeds")
    ys = np.concatenate([y for _, _, y in curves])
    lo, hi = float(ys.min()), float(ys.max())
    span = max(hi - lo, 1e-9)
    shown = {k: v for k, v in (references or {}).items() if lo - 2 * span <= v <= hi + 2 * span}
    if shown:
        lo, hi = min(lo, *shown.values()), max(hi, *shown.values())
    pad = 0.08 * max(hi - lo, 1e-9)
    ax.set_ylim(lo - pad, hi + pad)
    for i, (name, value) in enumerate((references or {}).items()):
        if name in shown:
            ax.axhline(value, ls="--", lw=1.2, color=_reference_color(name, i), label=f"{name}: {value:.4g}")
        else:  # off the scale of the curves: named, not drawn
            ax.plot([], [], ls="none", label=f"{name}: {value:.4g} ({'above' if value > hi else 'below'}, off scale)")
    ax.set_xlabel(steps_label(Path(run_dirs[0])))
    ax.set_ylabel("validation return on unseen seeds (dimensionless)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    seeds = f"{len(curves)} seed{'s' if len(curves) > 1 else ''}"
    ax.set_title(title or f"{_common_name([c[0] for c in curves])}: {seeds}", fontsize=10)
    return save_figure(fig, path)


def _common_name(names: list[str]) -> str:
    """The agents' common name without the seed suffix (``shear_building_ppo-residual_s0`` →
    ``shear_building_ppo-residual``)."""
    import os
    import re

    common = re.sub(r"_s\d*$", "", os.path.commonprefix(names)).rstrip("_")  # the seed suffix, whole or partial
    return common or names[0]


def train(plant: PlantProfile, algo: str, seeds, *, backend: str = "serial", jobs: int | None = None,
          address: str | None = None, **kw) -> list[Path]:
    """One agent per seed on ``plant``, one task each (:mod:`mrd_env.executor`: serially, on a process pool or on
    Ray, whose workers get the profile by its plant's name; each seed's agent is the same on all of them); their
    folders, and with several seeds a figure of their validation curves
    (``<out>/<plant>_<algo>_learning_curves.png``)."""
    from mrd_env.executor import Task, resolve_backend, run_tasks

    seeds = [int(s) for s in seeds]
    parallel = resolve_backend(backend, len(seeds), jobs) != "serial"
    # in parallel, one progress bar over the seeds instead of one per run
    tasks = [Task(train_one, (plant, algo, s), {**kw, "progress": kw.get("progress", False) and not parallel},
                  label=f"{plant.name} {algo} seed {s}") for s in seeds]
    folders = run_tasks(tasks, backend=backend, jobs=jobs, address=address,
                        progress=kw.get("progress", False) and parallel, desc=f"train {plant.name} {algo}")
    if len(folders) > 1:
        hyper = kw.get("hyper") or {}
        env_kwargs = {**(kw.get("env_kwargs") or env_options(plant)), **(hyper.get("env_kwargs") or {})}
        refs = law_references(plant, env_kwargs, kw.get("eval_episodes", 8)) if kw.get("eval_freq") else None
        plot_seed_curves(folders, Path(kw["out"]) / f"{run_name(plant, algo, hyper, env_kwargs)}_learning_curves.png",
                         refs)
    return folders


def law_references(plant: PlantProfile, env_kwargs: dict | None = None, eval_episodes: int = 8,
                   extra_laws=()) -> dict[str, float]:
    """The validation return of each of the plant's reference laws (those drawn next to the agents' validation
    curves, :attr:`~experiments.common.plants.PlantProfile.reference_laws`) and of ``extra_laws`` (e.g. a residual
    agent's own law) on the agents' validation episodes, sensors and control step."""
    from controllers import make_controller

    from ..common.evaluation import evaluate_batch

    env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
    sc, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)
    out = {}
    for law in dict.fromkeys((*plant.reference_laws, *extra_laws)):
        eps = evaluate_batch(lambda v, n=law: make_controller(n, v), sc, "", **obs_kwargs)
        out[f"{law} @ {1000 * float(env_kwargs.get('control_dt', 1e-3)):g} ms"] = \
            float(np.mean([e.episode_return for e in eps]))
    return out


# --- CLI ----------------------------------------------------------------------------------------------------------

def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", type=plant_name, choices=plant_choices(), default=default_plant())
    p.add_argument("--algo", default="ppo", help=f"one of {', '.join(available_algos())} (shipped hyperparameters); "
                                                 f"{', '.join(sorted(set(ALGOS) - set(available_algos())))} with "
                                                 "--hyperparams")
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="one agent per seed (default 0)")
    p.add_argument("--timesteps", type=int, default=None, help="environment steps (default: the YAML's n_timesteps)")
    p.add_argument("--hyperparams", type=Path, default=None, help="YAML file (default experiments/hyperparams/<algo>.yml)")
    p.add_argument("--set", nargs="+", action="extend", default=[], metavar="KEY=VALUE",
                   help="override hyperparameters (YAML values; repeatable)")
    p.add_argument("--control-dt", type=float, default=RL_DEFAULTS["control_dt"],
                   help=f"agent step in s (a multiple of 1 ms; default {RL_DEFAULTS['control_dt']:g}, as the v1 ids)")
    p.add_argument("--sensors", nargs="+", default=None, help="sensor names (default: the plant's measured set)")
    p.add_argument("--history", type=int, default=1, help="control steps stacked in the observation (default 1)")
    p.add_argument("--preview", action="store_true",
                   help="quarter car: the agent also sees the road 10..100 ms ahead (the road_preview sensor)")
    p.add_argument("--residual", default=None, metavar="LAW",
                   help="the agent learns a correction to this law's command, starting exactly at the law "
                        "(default: the YAML's residual, if any; 'none' to switch it off)")
    p.add_argument("--residual-scale", type=float, default=None,
                   help="largest correction as a share of the command range, in (0, 1] (default 1)")
    p.add_argument("--residual-hold", type=int, default=None, metavar="K",
                   help="the law follows every control step, the agent's correction is held for K of them (with "
                        "--control-dt 0.001 and K 10: the law at 1 ms, the agent at 10 ms; default 1)")
    p.add_argument("--paired-baseline", default=None, metavar="LAW",
                   help="variance reduction: rewards relative to this law on the same disturbance "
                        "(default: the YAML's paired_baseline; 'none' to switch it off)")
    p.add_argument("--damper", default=None,
                   help="damper model name or preset file (fitted.json from mrd-env identify; default: the plant's)")
    p.add_argument("--disturbance", default=None,
                   help="training disturbance as JSON (default: the plant's training distribution), e.g. "
                        "'{\"kind\": \"iso8608\", \"road_class\": \"C\"}'")
    p.add_argument("--warm-start", default=None, metavar="LAW",
                   help="cmaes: begin as this classical law (behaviour cloning; default: the YAML's warm_start); "
                        "shac: begin as this agent (a folder, or 'cmaes': the shipped CMA-ES agent)")
    p.add_argument("--dataset", type=Path, default=None, metavar="FOLDER",
                   help="bc, td3bc: learn from the Minari dataset(s) in FOLDER (mrd-env dataset) instead of the "
                        "environment; --timesteps and --eval-freq then count gradient steps")
    p.add_argument("--eval-freq", type=int, default=20_000, help="validation every so many steps (0: never)")
    p.add_argument("--eval-episodes", type=int, default=8, help="validation episodes (unseen seeds)")
    p.add_argument("--checkpoint-freq", type=int, default=0, help="checkpoint every so many steps (0: never)")
    p.add_argument("--tensorboard", action="store_true", help="TensorBoard logs in <out>/tensorboard")
    p.add_argument("--out", type=Path, default=Path("results/agents"))
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)
    add_plant_options(p)


def check_before_training(algo: str, hyper: dict, env_id: str, env_kwargs: dict) -> None:
    """What an SB3 entry must pass before any training starts (its keys and values are checked when it is read):
    the residual's and the paired baseline's laws apply to the plant, and SB3 builds the model."""
    if algo not in ("cmaes", "shac") and "dataset" not in TRAINERS[algo].options:  # SB3's
        import torch

        # this command's own process: one torch thread, as in training (none spins against the environments)
        torch.set_num_threads(1)
        full_kwargs = {**env_kwargs, **(hyper.get("env_kwargs") or {})}
        check_laws(hyper, env_id, full_kwargs)
        check_with_sb3(algo, hyper, env_id, full_kwargs)


def run(args: argparse.Namespace) -> int:
    executor = sweep.options(args)
    if args.algo not in ALGOS:
        raise ValueError(f"--algo must be one of {sorted(ALGOS)}, got {args.algo!r}")
    if args.hyperparams is None and args.algo not in available_algos():
        raise ValueError(f"--algo {args.algo} has no shipped hyperparameters (shipped: {available_algos()}); give "
                         "a YAML file in RL Zoo's format with --hyperparams")
    if any(s < 0 for s in args.seeds):
        raise ValueError(f"--seeds must be >= 0, got {args.seeds}")
    if args.timesteps is not None and args.timesteps < 1:
        raise ValueError(f"--timesteps must be >= 1, got {args.timesteps}")
    for name, v in (("--eval-freq", args.eval_freq), ("--checkpoint-freq", args.checkpoint_freq)):
        if v < 0:
            raise ValueError(f"{name} must be >= 0, got {v}")
    if args.eval_episodes < 1:
        raise ValueError(f"--eval-episodes must be >= 1, got {args.eval_episodes}")
    offline = "dataset" in TRAINERS[args.algo].options
    if offline and args.dataset is None:
        raise ValueError(f"--algo {args.algo} learns from recorded episodes: give --dataset FOLDER (mrd-env dataset)")
    if args.dataset is not None and not offline:
        raise ValueError(f"--dataset applies to the offline algorithms "
                         f"({', '.join(a for a, t in TRAINERS.items() if 'dataset' in t.options)}), not to {args.algo}")
    disturbance = None
    if args.disturbance is not None:
        text = args.disturbance.strip()
        if text.startswith(("{", "[", '"')):  # meant as JSON: a malformed one is named as such, not taken for a kind's name
            try:
                disturbance = json.loads(text)
            except json.JSONDecodeError as exc:
                raise ValueError(f"--disturbance is not valid JSON ({exc.msg} at character {exc.pos}): "
                                 f"{args.disturbance}") from None
        else:
            disturbance = text  # a kind's name
    if args.warm_start is not None:
        from controllers import available_controllers
        if args.algo not in ("cmaes", "shac"):
            raise ValueError("--warm-start applies to --algo cmaes and shac")
        if args.algo == "cmaes" and args.warm_start not in available_controllers():
            raise ValueError(f"--warm-start must be a law of {available_controllers()}, got {args.warm_start!r}")
    plant = with_plant_options([profile(args.plant)], args)[0]
    env_kwargs = env_options(plant, args.control_dt, args.sensors, args.history, disturbance)
    if args.damper is not None:
        from mrd_env.dampers import damper_class, is_preset_file

        damper_class(args.damper)  # ValueError naming the models, or the preset file's problem
        # a preset file by its absolute path, so that the agent's record finds it from anywhere
        env_kwargs["damper"] = str(Path(args.damper).resolve()) if is_preset_file(args.damper) else args.damper
    if args.preview:
        from ..common.scenarios import preview_options
        env_kwargs = preview_options(plant, env_kwargs)
    env_id = plant.env_id
    overrides = _parse_overrides(args.set)
    # --residual-scale and --residual-hold: options of --residual LAW's residual, or of the YAML's
    options = {k: v for k, v in (("scale", args.residual_scale), ("hold", args.residual_hold)) if v is not None}
    if args.residual is not None:
        overrides["residual"] = None if args.residual == "none" else {"law": args.residual, **options}
        if args.residual == "none" and options:
            raise ValueError(f"--residual-{next(iter(options))} applies to a residual; it is switched off by "
                             "--residual none")
    if args.paired_baseline is not None:
        overrides["paired_baseline"] = None if args.paired_baseline == "none" else args.paired_baseline
    if args.algo in ("cmaes", "shac") and (overrides.get("residual") or overrides.get("paired_baseline")):
        raise ValueError(f"--residual and --paired-baseline apply to the SB3 algorithms, not to {args.algo} "
                         "(it warm-starts with --warm-start)")
    hyper = hyperparameters(args.algo, env_id, args.hyperparams, overrides)
    if args.residual is None and options:  # options of the YAML's residual
        spec = residual_spec(hyper.get("residual"))
        if spec is None:
            raise ValueError(f"--residual-{next(iter(options))} needs a residual: --residual LAW, or a "
                             "hyperparameter file with one")
        hyper = hyperparameters(args.algo, env_id, args.hyperparams, {**overrides, "residual": {**spec, **options}})
    check_before_training(args.algo, hyper, env_id, env_kwargs)
    if offline:  # the dataset read and checked against the agent's observations before anything is written
        from experiments.training.offline import check_dataset
        check_dataset(args.dataset, plant, env_kwargs)
    if args.tensorboard:
        import importlib.util
        if importlib.util.find_spec("tensorboard") is None:
            raise ImportError("--tensorboard needs the tensorboard package (pip install tensorboard)")
    # the environment is built (and its options checked) before any training starts
    import gymnasium as gym

    import mrd_env  # noqa: F401
    gym.make(env_id, **env_kwargs).close()
    command = "mrd-env " + " ".join(shlex.quote(a) for a in getattr(args, "_argv", sys.argv[1:]))
    folders = train(plant, args.algo, args.seeds, out=args.out, timesteps=args.timesteps, hyper=hyper,
                    env_kwargs=env_kwargs, eval_freq=args.eval_freq, eval_episodes=args.eval_episodes,
                    checkpoint_freq=args.checkpoint_freq, tensorboard=args.tensorboard,
                    progress=not args.no_progress, command=command, warm_start=args.warm_start,
                    **({"dataset": args.dataset} if offline else {}), **executor)
    for f in folders:
        print(f"saved {f} (score it on the suites it fits: mrd-env benchmark --plant {plant.name} --controller {f})")
    return 0
