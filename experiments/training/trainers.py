"""The trainer interface of ``mrd-env train``: every algorithm is a :class:`Trainer` in :data:`TRAINERS`, and every
trainer does one job the same way — train one agent for one plant and seed on the plant's training distribution,
validate it on unseen seeds, keep the best, and write the agent folder (:func:`controllers.agents.save_agent`) with
the run's learning curves. What the trainers share lives here: the training environment's options
(:func:`env_options`), the validation scenario (:func:`validation_split`), the validation table and console line,
and the learning-curve figure.

A trainer is named by its entry points (``"module:function"``, as Gymnasium registers environments), so this module
imports no trainer and every trainer imports this one — no import circle:

* ``train(plant, algo, seed, *, out, timesteps, hyper, env_kwargs, eval_freq, eval_episodes, progress, command,
  **options) -> Path`` trains one agent on ``plant`` (a :class:`~.plants.PlantProfile`) and returns its folder
  (``options``: those the trainer lists in :attr:`Trainer.options`, e.g. ``checkpoint_freq``, ``tensorboard``,
  ``report`` — a hyperparameter search's pruning — or ``warm_start``);
* ``check(algo, hyper) -> dict`` checks a hyperparameter entry (``ValueError`` naming a bad key or value) before
  any training starts.

The Stable-Baselines3 algorithms (PPO, SAC, TD3, A2C, RecurrentPPO, TQC) share one trainer
(:mod:`.sb3_trainer`); CMA-ES (:mod:`.evolution`) and SHAC (:mod:`.shac`) have their own; BC and TD3+BC learn from a
recorded dataset instead of the environment (:mod:`.offline`, the trainers with the ``dataset`` option). A new trainer is a module with these two functions
and an entry in :data:`TRAINERS`.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrd_env.envs import RL_DEFAULTS

from experiments.common.plants import PlantProfile, by_env_id
from experiments.common.scenarios import Scenario, validation

#: What each optional keyword of ``train`` is, for the message when a trainer lacks it.
OPTION_NAMES = {"report": "pruning", "checkpoint_freq": "checkpoints", "tensorboard": "TensorBoard logs",
                "warm_start": "warm start", "dataset": "offline dataset (--dataset)"}


@dataclass(frozen=True)
class Trainer:
    """One algorithm of ``mrd-env train`` (see the module docstring)."""

    algo: str             #: ``--algo``
    label: str            #: the algorithm's name in ``agent.json`` ("PPO", "CMA-ES")
    entry_point: str      #: ``"module:function"`` of ``train``
    checker: str          #: ``"module:function"`` of ``check``
    options: tuple = ()   #: the optional keywords of ``train`` it takes

    def _load(self, ref: str):
        module, _, name = ref.partition(":")
        return getattr(importlib.import_module(module), name)

    def check(self, hyper: dict) -> dict:
        """``hyper`` checked (and completed) by the trainer; ``ValueError`` naming what is wrong."""
        return self._load(self.checker)(self.algo, hyper)

    def train(self, plant: PlantProfile, seed: int, **kw) -> Path:
        """Train one agent; its folder. An option the trainer lacks, given a value, is a ``ValueError``."""
        unsupported = [k for k in OPTION_NAMES if k not in self.options and kw.get(k)]
        if "warm_start" in unsupported:
            raise ValueError("--warm-start applies to --algo "
                             + ", ".join(t.algo for t in TRAINERS.values() if "warm_start" in t.options))
        if unsupported:
            raise ValueError(f"{self.label} training has no {', '.join(OPTION_NAMES[k] for k in unsupported)}")
        kw = {k: v for k, v in kw.items() if k not in OPTION_NAMES or k in self.options}
        return self._load(self.entry_point)(plant, self.algo, seed, **kw)


_SB3 = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "a2c": "A2C", "recurrentppo": "RecurrentPPO", "tqc": "TQC",
        "ars": "ARS"}
#: Every trainer by ``--algo``.
TRAINERS: dict[str, Trainer] = {
    **{algo: Trainer(algo, label, "experiments.training.sb3_trainer:train_sb3", "experiments.training.sb3_trainer:check",
                     ("report", "checkpoint_freq", "tensorboard")) for algo, label in _SB3.items()},
    "cmaes": Trainer("cmaes", "CMA-ES", "experiments.training.evolution:train_cmaes",
                     "experiments.training.evolution:check_entry", ("warm_start",)),
    "shac": Trainer("shac", "SHAC", "experiments.training.shac:train_shac", "experiments.training.shac:check_entry",
                    ("warm_start",)),
    # offline: from a recorded dataset, no environment step (the trainers that take one)
    "bc": Trainer("bc", "BC", "experiments.training.offline:train_bc", "experiments.training.offline:check_entry",
                  ("dataset",)),
    "td3bc": Trainer("td3bc", "TD3+BC", "experiments.training.offline:train_td3bc",
                     "experiments.training.offline:check_entry", ("dataset",)),
}


def trainer(algo: str) -> Trainer:
    """The trainer of ``algo``; ``ValueError`` naming the algorithms otherwise."""
    if algo not in TRAINERS:
        raise ValueError(f"algo must be one of {sorted(TRAINERS)}, got {algo!r}")
    return TRAINERS[algo]


#: {--algo: the algorithm's name} of every trainer (:data:`TRAINERS`).
ALGOS = {algo: t.label for algo, t in TRAINERS.items()}


def train_one(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
              hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
              eval_episodes: int = 8, checkpoint_freq: int = 0, tensorboard: bool = False, progress: bool = False,
              command: str = "", report=None, warm_start: str | None = None, dataset=None) -> Path:
    """Train one agent on ``plant`` with the trainer of ``algo`` (:data:`TRAINERS`); return its folder. ``report``
    (SB3): told every validation, stops the training when it returns False (a hyperparameter search's pruning);
    ``warm_start`` (CMA-ES): a law's name, which the policy imitates before training (:mod:`.warm_start`);
    ``dataset`` (BC, TD3+BC): the recorded episodes' folder (:mod:`.offline`)."""
    return trainer(algo).train(plant, seed, out=out, timesteps=timesteps, hyper=hyper, env_kwargs=env_kwargs,
                               eval_freq=eval_freq, eval_episodes=eval_episodes, checkpoint_freq=checkpoint_freq,
                               tensorboard=tensorboard, progress=progress, command=command, report=report,
                               warm_start=warm_start, dataset=dataset)


# --- hyperparameter entries -----------------------------------------------------------------------------------------
#: The shipped hyperparameter files: ``<algo>.yml`` (RL Zoo's layout, keyed by environment id).
HYPERPARAMS = Path(__file__).parents[1] / "hyperparams"


def available_algos() -> list[str]:
    """The algorithms ``--algo`` offers: those with a shipped hyperparameter file (others need ``--hyperparams``)."""
    return sorted(a for a in TRAINERS if (HYPERPARAMS / f"{a}.yml").exists())


def hyperparameters(algo: str, env_id: str, path: Path | None = None, overrides: dict | None = None) -> dict:
    """The entry of ``env_id`` in the YAML file of ``algo`` (RL Zoo's format), with ``overrides``."""
    import yaml

    path = Path(path) if path is not None else HYPERPARAMS / f"{algo}.yml"
    if not path.exists():
        raise ValueError(f"no hyperparameter file {path}")
    try:
        table = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path} is not a YAML hyperparameter file ({' '.join(str(exc).split())[:120]})") from None
    if not isinstance(table, dict):
        raise ValueError(f"{path} is not a YAML hyperparameter file (expected {{env id: {{key: value}}}})")
    fallback = getattr(by_env_id(env_id), "hyperparams_fallback", None)
    if env_id not in table and fallback in table:  # e.g. the half car trains with the quarter car's entry
        env_id = fallback
    if env_id not in table:
        raise ValueError(f"{path} has no entry for {env_id}; entries: {sorted(table)}")
    if not isinstance(table[env_id], dict):
        raise ValueError(f"{path}: the entry for {env_id} must be a mapping {{key: value}}, got {table[env_id]!r}")
    out = dict(table[env_id])
    for k, v in (overrides or {}).items():
        out[k] = v
    return check_hyperparameters(algo, out)


def check_hyperparameters(algo: str, hyper: dict) -> dict:
    """``hyper`` if its trainer accepts every key and value (:meth:`Trainer.check`); ``ValueError`` otherwise."""
    if not isinstance(hyper.get("env_kwargs") or {}, dict):
        raise ValueError(f"hyperparameter env_kwargs must be a mapping of environment options, got "
                         f"{hyper['env_kwargs']!r}")
    normalize = hyper.get("normalize", True)
    if not isinstance(normalize, (bool, dict)):
        raise ValueError(f"hyperparameter normalize must be true, false or a mapping of VecNormalize options, got "
                         f"{normalize!r}")
    trainer(algo).check(hyper)
    return hyper


def residual_spec(value) -> dict | None:
    """The ``residual`` entry as {"law": name, "scale": s} (and ``boundary``: "reflect", the default, or "clip";
    ``hold``: environment steps per correction, default 1; :mod:`controllers.residual`) (None: no residual);
    ``ValueError`` if malformed."""
    from controllers.residual import Residual, check_hold

    if value is None or value is False:
        return None
    spec = {"law": value} if isinstance(value, str) else dict(value) if isinstance(value, dict) else None
    if spec is None or not isinstance(spec.get("law"), str) or set(spec) - {"law", "scale", "boundary", "hold"}:
        raise ValueError(f"hyperparameter residual must be a law's name or {{law: name, scale: s, boundary: b, "
                         f"hold: k}}, got {value!r}")
    if "hold" in spec:
        spec["hold"] = check_hold(spec["hold"])
    scale = spec.setdefault("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale <= 1:
        raise ValueError(f"the residual's scale must be a number in (0, 1], got {scale!r}")
    if spec.get("boundary", "reflect") not in Residual.BOUNDARIES:
        raise ValueError(f"the residual's boundary must be one of {list(Residual.BOUNDARIES)}, "
                         f"got {spec['boundary']!r}")
    return spec


def _residual_tags(hyper: dict) -> list[str]:
    """``residual`` (a correction to a law), ``hold<k>`` (held for k steps of the law)."""
    spec = residual_spec(hyper.get("residual"))
    return [] if not spec else ["residual"] + ([f"hold{spec['hold']}"] if spec.get("hold", 1) > 1 else [])


def run_name(plant: PlantProfile, algo: str, hyper: dict, env_kwargs: dict) -> str:
    """``<plant>_<algo>`` with the variant's tags: ``-residual``, ``-hold<k>``, ``-paired``, ``-h<k>`` (history),
    ``-preview``."""
    tags = _residual_tags(hyper) + \
        (["paired"] if hyper.get("paired_baseline") else []) + \
        ([f"h{int(env_kwargs['history'])}"] if int(env_kwargs.get("history", 1)) > 1 else []) + \
        (["preview"] if env_kwargs.get("preview") else [])
    return "_".join((plant.name, "-".join([algo, *tags])))


def agent_name(label: str, seed: int, hyper: dict, env_kwargs: dict) -> str:
    """The agent's name in tables and legends: the algorithm, what it adds — ``residual`` (a correction to a
    law; ``hold<k>``), ``preview`` (it sees the road ahead) — and its seed, e.g. ``"CMA-ES preview s0"``."""
    tags = _residual_tags(hyper) + \
        (["preview"] if env_kwargs.get("preview") else [])
    return " ".join([label, *tags, f"s{seed}"])


# --- what every trainer shares ------------------------------------------------------------------------------------
def env_options(plant: PlantProfile, control_dt: float = RL_DEFAULTS["control_dt"], sensors=None, history: int = 1,
                disturbance=None, **extra) -> dict:
    """The training environment's options: the plant's training distribution (or ``disturbance`` in the plant's
    disturbance option), normalised actions, the control step, and the observation options."""
    kw = {**plant.training, "action_mode": RL_DEFAULTS["action_mode"], "control_dt": float(control_dt),
          "history": int(history)}
    if sensors:
        kw["sensors"] = list(sensors)
    if disturbance is not None:
        kw.pop(plant.disturbance_key, None)
        kw[plant.disturbance_key] = disturbance
    kw.update(extra)
    return kw


def validation_split(plant: PlantProfile, env_kwargs: dict, episodes: int) -> tuple[Scenario, dict]:
    """The validation scenario of a training environment (its disturbance options on seeds training never
    draws) and the options that define what the agent sees and does (kept when the scenario changes)."""
    from controllers.agents import OBSERVATION_OPTIONS

    obs_kwargs = {k: v for k, v in env_kwargs.items() if k in OBSERVATION_OPTIONS}
    disturbance = {k: v for k, v in env_kwargs.items() if k not in OBSERVATION_OPTIONS}
    return Scenario("validation", plant.env_id, disturbance, validation(plant, episodes)[0].seeds), obs_kwargs


#: The constant commands R_p is the best of: 9 from the lowest command to the highest (the yardstick's grid).
PASSIVE_GRID = np.linspace(0.0, 1.0, 9)


class _ConstantCommands:
    """A controller on a vector environment of ``len(fractions)`` blocks of ``n`` environments: block k holds the
    command at ``fractions[k]`` of the action space, every damper alike."""

    def __init__(self, venv, fractions, n: int):
        box = venv.single_action_space
        f = np.repeat(np.asarray(fractions, dtype=float), n)[:, None]
        self.action = (box.low + f * (box.high - box.low)).astype(box.dtype)

    def reset(self, mask=None) -> None:
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.action, state


def passive_reference(episodes: Scenario, obs_kwargs: dict) -> float:
    """R_p on the validation ``episodes``: the best mean return of a constant command (:data:`PASSIVE_GRID` across
    the action space), what an agent must beat to do better than a passive damper tuned to these episodes. All
    commands run in one vector environment (each episode once per command)."""
    from dataclasses import replace

    from experiments.common.evaluation import evaluate_batch

    k, n = len(PASSIVE_GRID), len(episodes.seeds)
    grid = replace(episodes, seeds=tuple(episodes.seeds) * k)
    eps = evaluate_batch(lambda v: _ConstantCommands(v, PASSIVE_GRID, n), grid, "", **obs_kwargs)
    return float(np.array([e.episode_return for e in eps]).reshape(k, n).mean(axis=1).max())


def say_validation(run: str, steps: int, value: float, best: float, progress: bool,
                   passive: float | None = None) -> None:
    """One console line per validation (above the progress bar): the return now, the best so far and, given
    ``passive`` (R_p, :func:`passive_reference`), whether it beats the best constant command."""
    if progress:
        from tqdm.auto import tqdm

        ref = "" if passive is None else \
            (f"; best constant command R_p {passive:.4g}: {value - passive:+.3g}, "
             f"{'above' if value > passive else 'not above'} passive")
        tqdm.write(f"{run}: validation return {value:.4g} at {steps} steps (best so far {best:.4g}{ref})")


def write_csv(path: Path, rows: list[dict]) -> None:
    """``rows`` as a CSV file (the header: the first row's keys), e.g. ``validation.csv``; written atomically (a
    reader during training sees the previous file or the new one, never half of one)."""
    import csv
    import io

    from mrd_env.storage import write_text

    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text(path, buf.getvalue())


class NetworkValidation:
    """The validation of a policy network during training (the CMA-ES and SHAC trainers): each call scores ``live``
    (a policy with ``predict``) on the validation ``episodes``, appends a row to the run's ``validation.csv`` (with
    any extra ``columns``) and, when its mean return is the best so far, saves the parameters ``theta`` in ``best/``
    through ``save(folder, theta, extra)``."""

    def __init__(self, run_dir: Path, episodes: Scenario, obs_kwargs: dict, save, progress: bool):
        self.run_dir, self.episodes, self.obs_kwargs, self.save, self.progress = (run_dir, episodes, obs_kwargs,
                                                                                  save, progress)
        self.rows: list[dict] = []
        self.best = -np.inf
        self.passive = None  # R_p, computed at the first validation that is shown

    def __call__(self, live, theta, steps: int, **columns) -> None:
        from controllers.base import AgentController

        from experiments.common.evaluation import evaluate_batch

        eps = evaluate_batch(lambda v: AgentController(v, live, name="live"), self.episodes, "", **self.obs_kwargs)
        r = np.array([e.episode_return for e in eps])
        self.rows.append({"timesteps": steps, "validation_return": float(r.mean()),
                          "validation_return_std": float(r.std()), **columns})
        write_csv(self.run_dir / "validation.csv", self.rows)
        if r.mean() > self.best:
            self.best = float(r.mean())
            self.save(self.run_dir / "best", theta, {"validation_return": self.best, "timesteps": steps})
        if self.progress and self.passive is None:
            self.passive = passive_reference(self.episodes, self.obs_kwargs)
        say_validation(self.run_dir.name, steps, float(r.mean()), self.best, self.progress, self.passive)


def steps_label(run_dir: Path) -> str:
    """The x-axis label of a run's curves: environment steps, or the agent's steps when its correction is held
    for several of the environment's (a residual with ``hold``)."""
    import json

    path = run_dir / "agent.json"
    meta = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    if meta.get("offline"):
        return "gradient steps (offline: no environment step)"
    hold = int((meta.get("residual") or {}).get("hold", 1))
    if hold == 1:
        return "environment steps"
    dt = float(meta["env_kwargs"].get("control_dt", 1e-3))
    return f"agent steps (each {hold} environment steps of {dt * 1e3:g} ms)"


def plot_learning_curve(run_dir: Path) -> Path | None:
    """Training episode returns (mean over 20 episodes) and validation returns against environment steps."""
    import csv

    from mrd_env.report import figure, save_figure

    fig, ax = figure(figsize=(7, 4))
    drawn = False
    mon = run_dir / "training.monitor.csv"
    if mon.exists():
        rows = list(csv.reader(mon.open()))[2:]
        if rows:
            r = np.array([float(x[0]) for x in rows])
            steps = np.cumsum([int(x[1]) for x in rows])
            k = min(20, r.size)
            y = np.convolve(r, np.ones(k) / k, mode="valid")
            # a short run has a handful of points: markers, so that one point is still seen
            what = "training episodes" if k == 1 else f"training episodes, running mean of {k}"
            ax.plot(steps[k - 1:], y, "s-" if y.size < 20 else "-", ms=3, lw=1,
                    label=f"{what} (the training distribution)")
            drawn = True
    val = run_dir / "validation.csv"
    if val.exists():
        rows = list(csv.DictReader(val.open()))
        ax.plot([int(r["timesteps"]) for r in rows], [float(r["validation_return"]) for r in rows], "o-", ms=3,
                label="validation (unseen seeds, its own episodes)")
        drawn = True
    if not drawn:
        return None
    ax.set_xlabel(steps_label(run_dir))
    ax.set_ylabel("episode return (dimensionless)")
    ax.set_title(run_dir.name)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, run_dir / "learning_curve.png")
