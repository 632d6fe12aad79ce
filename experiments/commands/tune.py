"""``mrd-env tune``: hyperparameter search for ``mrd-env train`` with Optuna.

Each trial draws hyperparameters (RL Zoo's search spaces, or ``--space residual`` for a residual agent),
trains one agent for ``--timesteps`` on the plant's training distribution and reports its validation returns
(unseen seeds, never the test scenarios) as it goes; Optuna's TPE sampler proposes the next trial and its median pruner stops trials whose
validation falls behind. The study lives in a journal file (``<out>/<study>.log``), so several workers — the
processes of a local pool or the tasks of a Ray cluster (``--backend``, ``--jobs``, ``--address``) — add
trials to the same study; rerunning the command resumes it. Writes ``<out>/<study>_trials.md``/``.csv`` and
``<out>/<study>_best.yml`` (the best trial's hyperparameters in the layout of ``experiments/hyperparams``).

Why Optuna rather than Ray Tune: a search of RL hyperparameters here is a few dozen trials of minutes each,
which Optuna runs on one machine with no service, resumes from a file, and prunes through the validation the
trainer already does (RL Zoo itself tunes with Optuna); for a cluster, the same study's workers run as Ray
tasks through the project's one executor.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mrd_env import storage

from ..common import sweep
from ..common.plants import PlantProfile, default_plant, plant_choices, plant_name, profile
from experiments.training.trainers import ALGOS, env_options, hyperparameters


SEARCHABLE = ("ppo", "recurrentppo", "sac", "tqc", "td3")


#: ``--space``: RL Zoo's search spaces, or the narrow ones of residual agents (docs/rl-agents.md).
SPACES = ("zoo", "residual")

#: The residual space's draws for PPO and RecurrentPPO: (name, kind, choices or (low, high[, log])). γ stays in
#: [0.995, 0.999]: at 10 ms a lower discount drifts the agent to softer commands (docs/rl-agents.md); the
#: exploration noise stays small.
RESIDUAL_SPACE = (
    ("learning_rate", "float", (3e-5, 1e-3, True)),
    ("log_std_init", "float", (-3.5, -1.0)),
    ("residual_scale", "float", (0.2, 1.0)),
    ("gamma", "float", (0.995, 0.999)),
    ("gae_lambda", "categorical", [0.95, 0.98, 0.99]),
    ("n_epochs", "categorical", [5, 10, 20]),
    ("batch_size", "categorical", [1024, 2048, 4096]),
    ("n_steps", "categorical", [256, 512, 1024]),
)

#: The residual space of the off-policy algorithms (SAC, TQC, TD3): their actors left the law within 10⁴ steps
#: and did not come back (docs/rl-agents.md), so it searches what sets that pace — the learning rate, the target
#: networks' τ, how often they learn, the actor's warm-up while the critic learns — with γ high, as for PPO.
OFF_POLICY_RESIDUAL_SPACE = (
    ("learning_rate", "float", (1e-5, 1e-3, True)),
    ("residual_scale", "float", (0.1, 1.0)),
    ("gamma", "float", (0.99, 0.999)),
    ("tau", "categorical", [0.002, 0.005, 0.01, 0.02]),
    ("batch_size", "categorical", [128, 256, 512]),
    ("train_freq", "categorical", [1, 4, 8]),
    ("actor_warmup_steps", "categorical", [0, 10000, 30000]),
)

#: Each algorithm's residual space: the off-policy one with SAC's (and TQC's) entropy coefficient, or TD3's action
#: noise.
_ENTROPY = (("ent_coef", "float", (1e-5, 1e-2, True)),)
RESIDUAL_SPACES = {
    "ppo": RESIDUAL_SPACE, "recurrentppo": RESIDUAL_SPACE,
    "sac": OFF_POLICY_RESIDUAL_SPACE + _ENTROPY, "tqc": OFF_POLICY_RESIDUAL_SPACE + _ENTROPY,
    "td3": OFF_POLICY_RESIDUAL_SPACE + (("noise_std", "float", (0.01, 0.2, True)),),
}

#: Values a residual space's parameter takes when the YAML entry leaves it out (the trainers' own defaults).
_DEFAULTS = {"actor_warmup_steps": 0, "residual_scale": 1.0}


def _set(h: dict, name: str, value) -> None:
    """Put a searched value where the trainer reads it (``log_std_init`` in the policy's keywords,
    ``residual_scale`` in the residual)."""
    if name == "log_std_init":
        h["policy_kwargs"] = {**(h.get("policy_kwargs") or {}), "log_std_init": value}
    elif name == "residual_scale":
        h["residual"] = {**h["residual"], "scale": value}
    else:
        h[name] = value


def _get(h: dict, name: str):
    """The value of a searched parameter in the entry ``h`` (the inverse of :func:`_set`)."""
    if name == "log_std_init":
        return (h.get("policy_kwargs") or {}).get("log_std_init")
    if name == "residual_scale":
        return h["residual"].get("scale", _DEFAULTS[name])
    return h.get(name, _DEFAULTS.get(name))


def base_params(base: dict, algo: str = "ppo") -> dict:
    """The residual space's parameters of the YAML entry ``base`` (its first trial: the recipe as it is);
    ``ValueError`` naming a parameter the entry leaves out or sets to a value the space does not hold."""
    out = {}
    for name, kind, spec in RESIDUAL_SPACES[algo]:
        value = _get(base, name)
        if value is None or (kind == "categorical" and value not in spec):
            raise ValueError(f"--space residual: the hyperparameter entry's {name} must be "
                             f"{'one of ' + str(spec) if kind == 'categorical' else 'a number'}, got {value!r}")
        out[name] = float(value) if kind == "float" else value
    return out


def sample(trial, algo: str, base: dict, space: str = "zoo") -> dict:
    """Hyperparameters of a trial: ``base`` (the YAML entry) with the searched keys drawn (RL Zoo's spaces, or
    with ``space="residual"`` :data:`RESIDUAL_SPACE`)."""
    h = dict(base)
    if space == "residual":
        if algo not in RESIDUAL_SPACES:
            raise ValueError(f"--space residual searches {', '.join(RESIDUAL_SPACES)}, not {algo!r}")
        if not isinstance(h.get("residual"), dict):
            raise ValueError("--space residual needs a hyperparameter entry with a residual: {law: ..., scale: ...}")
        for name, kind, spec in RESIDUAL_SPACES[algo]:
            if kind == "float":
                value = trial.suggest_float(name, spec[0], spec[1], log=len(spec) > 2 and spec[2])
            else:
                value = trial.suggest_categorical(name, spec)
            _set(h, name, value)
        return h
    if algo in ("ppo", "recurrentppo"):
        h["n_steps"] = trial.suggest_categorical("n_steps", [64, 128, 256, 512])
        h["batch_size"] = trial.suggest_categorical("batch_size", [64, 128, 256, 512])
        h["gamma"] = trial.suggest_categorical("gamma", [0.9, 0.95, 0.98, 0.99, 0.995])
        h["gae_lambda"] = trial.suggest_categorical("gae_lambda", [0.8, 0.9, 0.95, 0.98])
        h["learning_rate"] = trial.suggest_float("learning_rate", 1e-5, 1e-3, log=True)
        h["ent_coef"] = trial.suggest_float("ent_coef", 1e-8, 1e-2, log=True)
        h["clip_range"] = trial.suggest_categorical("clip_range", [0.1, 0.2, 0.3])
        h["n_epochs"] = trial.suggest_categorical("n_epochs", [5, 10, 20])
        kw = dict(h.get("policy_kwargs") or {})
        kw["log_std_init"] = trial.suggest_float("log_std_init", -3.0, 0.0)
        h["policy_kwargs"] = kw
    elif algo in ("sac", "tqc", "td3"):
        h["learning_rate"] = trial.suggest_float("learning_rate", 1e-5, 1e-2, log=True)
        h["batch_size"] = trial.suggest_categorical("batch_size", [64, 128, 256, 512])
        h["gamma"] = trial.suggest_categorical("gamma", [0.9, 0.95, 0.98, 0.99, 0.995])
        h["tau"] = trial.suggest_categorical("tau", [0.005, 0.01, 0.02, 0.05])
        h["train_freq"] = trial.suggest_categorical("train_freq", [1, 4, 8, 16])
        if algo == "td3":  # RL Zoo's action noise
            h["noise_type"] = h.get("noise_type") or "normal"
            h["noise_std"] = trial.suggest_float("noise_std", 0.01, 0.3, log=True)
    else:
        raise ValueError(f"no search space for {algo!r}; searchable: {', '.join(SEARCHABLE)}")
    return h


def trial_value(rows: list[dict]) -> float:
    """A trial's value: its best validation return once it has trained (``rows`` of its validation.csv). The
    untrained agent's (step 0) does not count: a residual agent is its law there, and every trial that only fell
    below the law would tie with it."""
    trained = [float(r["validation_return"]) for r in rows if int(r["timesteps"]) > 0]
    return max(trained or [float(r["validation_return"]) for r in rows])


def pruner(eval_freq: int):
    """The median pruner of every study: from the fourth trial on, at the second validation at the earliest (the
    journal does not store a pruner, so each worker sets it when it loads the study; Optuna's default would prune
    from the sixth trial on, at the first validation)."""
    import optuna

    return optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=2 * eval_freq)


def _storage(path: Path):
    import optuna
    from optuna.storages.journal import JournalFileBackend

    return optuna.storages.JournalStorage(JournalFileBackend(str(path)))


def sampler_seed(seed: int, worker_index: int, earlier_trials: int) -> int:
    """The TPE sampler's seed of a worker: ``seed`` + its index in a new study; in a resumed one a seed of its own
    (the same seed would propose the first run's trials again, and train them with the same seed)."""
    if earlier_trials == 0:
        return seed + worker_index
    return int(np.random.SeedSequence([seed, worker_index, earlier_trials]).generate_state(1)[0])


def worker(plant: PlantProfile, algo: str, study: str, out: Path, n_trials: int, timesteps: int, eval_freq: int,
           eval_episodes: int, seed: int, hyperparams: Path | None = None, space: str = "zoo",
           tpe_seed: int | None = None) -> int:
    """Add ``n_trials`` trials to the study (one worker; several run side by side on one journal); the trials train
    with ``seed``, the sampler draws with ``tpe_seed`` (default ``seed``)."""
    import optuna

    from experiments.training.trainers import train_one

    base = hyperparameters(algo, plant.env_id, hyperparams)
    st = optuna.load_study(study_name=study, storage=_storage(out / f"{study}.log"),
                           sampler=optuna.samplers.TPESampler(seed=seed if tpe_seed is None else tpe_seed),
                           pruner=pruner(eval_freq))

    def objective(trial):
        h = sample(trial, algo, base, space)

        def report(step, value):
            if step == 0:  # not the trial's result (see trial_value): the median pruner judges a trial by its best
                return True  # value so far, and a residual agent's law there would shield every trial from it
            trial.report(value, step)
            return not trial.should_prune()

        run = train_one(plant, algo, seed, out=out / "trials" / f"trial_{trial.number}", timesteps=timesteps,
                        hyper=h, env_kwargs=env_options(plant), eval_freq=eval_freq, eval_episodes=eval_episodes,
                        report=report)
        if trial.should_prune():
            raise optuna.TrialPruned()
        import csv
        return trial_value(list(csv.DictReader((run / "validation.csv").open())))

    st.optimize(objective, n_trials=n_trials)
    return n_trials


def tune(plant: PlantProfile, algo: str, *, trials: int, timesteps: int, out: Path, study: str | None = None,
         eval_freq: int = 50_000, eval_episodes: int = 4, seed: int = 0, hyperparams: Path | None = None,
         backend: str = "serial", jobs: int | None = None, address: str | None = None, progress: bool = True,
         space: str = "zoo"):
    """Run the search (``trials`` in all, split over the workers); the study. In the residual space a new
    study's first trial is the YAML entry as it is: the recipe's own score at the same budget."""
    import optuna

    from mrd_env.executor import Task, default_jobs, resolve_backend, run_tasks

    study = study or f"{plant.name}_{algo}"
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    st = optuna.create_study(study_name=study, storage=_storage(out / f"{study}.log"), direction="maximize",
                             pruner=pruner(eval_freq), load_if_exists=True)
    earlier = len(st.trials)
    if space == "residual" and not earlier:
        st.enqueue_trial(base_params(hyperparameters(algo, plant.env_id, hyperparams), algo))
    workers = 1 if resolve_backend(backend, trials, jobs) == "serial" else min(trials, jobs or default_jobs())
    split = [trials // workers + (1 if i < trials % workers else 0) for i in range(workers)]
    tasks = [Task(worker, (plant, algo, study, out, n, timesteps, eval_freq, eval_episodes, seed + i, hyperparams,
                           space, sampler_seed(seed, i, earlier)),
                  label=f"tune worker {i}") for i, n in enumerate(split)]
    run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress, desc=f"tune {study}")
    return st


def report_study(st, algo: str, env_id: str, out: Path, hyperparams: Path | None = None) -> tuple[Path, Path]:
    import yaml

    from mrd_env.report import write_table

    rows = [{"trial": t.number, "state": t.state.name, "value": t.value if t.value is not None else float("nan"),
             **t.params} for t in st.trials]
    md, _ = write_table(rows, out / f"{st.study_name}_trials", floatfmt=".4g",
                        title=f"{st.study_name}: trials (value = best validation return)")
    best = hyperparameters(algo, env_id, hyperparams)
    best_trial = st.best_trial
    for k, v in best_trial.params.items():
        _set(best, k, v)
    path = out / f"{st.study_name}_best.yml"
    storage.write_text(path, f"# best of {len(st.trials)} trials (validation return {best_trial.value:.4g}); mrd-env tune\n"
                    + yaml.safe_dump({env_id: best}, sort_keys=False))
    return md, path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", type=plant_name, choices=plant_choices(), default=default_plant())
    p.add_argument("--algo", choices=sorted(ALGOS), default="ppo")
    p.add_argument("--trials", type=int, default=20,
                   help="trials to run, over all workers, added to the study's earlier ones (default 20)")
    p.add_argument("--timesteps", type=int, default=300_000, help="environment steps per trial")
    p.add_argument("--eval-freq", type=int, default=50_000, help="validation (and pruning) every so many steps")
    p.add_argument("--eval-episodes", type=int, default=4)
    p.add_argument("--study", default=None, help="study name (default <plant>_<algo>); rerun to resume")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--hyperparams", type=Path, default=None,
                   help="YAML of the fixed hyperparameters (default experiments/hyperparams/<algo>.yml)")
    p.add_argument("--space", choices=SPACES, default="zoo",
                   help="zoo: RL Zoo's search spaces; residual (a residual in the YAML; the YAML entry as the "
                        "first trial): for PPO and RecurrentPPO learning rate, log_std_init, residual scale, gamma "
                        "in [0.995, 0.999], GAE lambda, epochs, batch, n_steps; for SAC, TQC and TD3 learning rate, "
                        "residual scale, gamma in [0.99, 0.999], tau, batch, train_freq, the actor's warm-up, and "
                        "SAC's entropy coefficient or TD3's action noise")
    p.add_argument("--out", type=Path, default=Path("results/tune"))
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)


def run(args: argparse.Namespace) -> int:
    executor = sweep.options(args)
    if args.algo not in SEARCHABLE:
        raise ValueError(f"--algo {args.algo}: no search space; searchable: {', '.join(SEARCHABLE)}")
    for name, v, lo in (("--trials", args.trials, 1), ("--timesteps", args.timesteps, 1),
                        ("--eval-freq", args.eval_freq, 1), ("--eval-episodes", args.eval_episodes, 1),
                        ("--seed", args.seed, 0)):
        if v < lo:
            raise ValueError(f"{name} must be >= {lo}, got {v}")
    try:
        import optuna  # noqa: F401
    except ImportError:
        raise ImportError("mrd-env tune needs Optuna (pip install 'mrd-env[tune]')") from None
    plant = profile(args.plant)
    env_id = plant.env_id
    base = hyperparameters(args.algo, env_id, args.hyperparams)  # the base entry exists and is valid
    if args.space == "residual":
        if args.algo not in RESIDUAL_SPACES:
            raise ValueError(f"--space residual searches {', '.join(RESIDUAL_SPACES)}, not {args.algo}")
        if not isinstance(base.get("residual"), dict):
            raise ValueError("--space residual needs a hyperparameter file whose entry has a residual "
                             "(e.g. experiments/hyperparams/ppo-residual.yml)")
        base_params(base, args.algo)  # the entry holds every searched parameter, as the first trial
    st = tune(plant, args.algo, trials=args.trials, timesteps=args.timesteps, out=args.out, study=args.study,
              eval_freq=args.eval_freq, eval_episodes=args.eval_episodes, seed=args.seed,
              hyperparams=args.hyperparams, progress=not args.no_progress, space=args.space, **executor)
    md, best = report_study(st, args.algo, env_id, args.out, args.hyperparams)
    print(md.read_text())
    print(f"best trial {st.best_trial.number}: validation return {st.best_value:.4g}; hyperparameters in {best} "
          f"(train with: mrd-env train --plant {plant.name} --algo {args.algo} --hyperparams {best})")
    return 0
