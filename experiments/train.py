"""``mrd-env train``: train agents on an mrd-env environment, following RL Zoo's conventions.

Hyperparameters per environment and algorithm come from YAML files shipped with the project
(``experiments/hyperparams/<algo>.yml``, RL Zoo's layout: ``n_envs``, ``n_timesteps``, ``policy``,
``normalize`` and the algorithm's own keyword arguments, keyed by environment id); ``--hyperparams`` names
another file, ``--set key=value`` overrides one entry. The agent trains on the training distribution of
:mod:`experiments.scenarios` (a new road or ground motion per episode) in the native vector environment through
the SB3 bridge, with observations (and rewards) normalised by ``VecNormalize``. During training it is evaluated
every ``--eval-freq`` steps on the validation scenarios (the training distribution on seeds training never
draws; the test scenarios are never seen), and the best agent is kept; checkpoints every ``--checkpoint-freq``
steps; learning curves as CSV (training episodes, validation) and PNG; TensorBoard logs with ``--tensorboard``;
several seeds in one command (``--seeds 0 1 2``); a progress bar. ``--algo cmaes`` trains a policy network with an
evolution strategy instead, on the same scenarios and with the same outputs (:mod:`.evolution`).

Each run writes a folder ``<out>/<plant>_<algo>_s<seed>/`` holding the final agent (``agent.json``, ``model.zip``,
``normalization.npz``: :func:`controllers.load_agent` reads it), ``best/`` (the best validation agent), the
checkpoints, ``training.monitor.csv``, ``validation.csv`` and ``learning_curve.png``. ``agent.json`` records the plant,
the algorithm, the seed and budget, the environment options (``env_kwargs``), the hyperparameters, the wall
time and the command that reproduces the run.
"""
from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from . import sweep
from .scenarios import ENV_IDS, TRAINING, Scenario, validation

ALGOS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "a2c": "A2C", "recurrentppo": "RecurrentPPO", "tqc": "TQC",
         "cmaes": "CMA-ES"}
HYPERPARAMS = Path(__file__).with_name("hyperparams")


def available_algos() -> list[str]:
    """The algorithms ``--algo`` offers: those with a shipped hyperparameter file (others need ``--hyperparams``)."""
    return sorted(a for a in ALGOS if (HYPERPARAMS / f"{a}.yml").exists())
#: Keys of a hyperparameter entry that are not the algorithm's keyword arguments: RL Zoo's, and ours —
#: ``residual`` (a law's name, or {law, scale}: the agent learns a correction to it, :mod:`controllers.residual`)
#: and ``paired_baseline`` (a law's name: rewards relative to it on the same disturbance,
#: :class:`controllers.training_wrappers.PairedBaselineVecEnv`).
_ZOO_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "noise_type", "noise_std", "residual",
             "paired_baseline")
#: RL Zoo's ``noise_type`` values (action noise of the off-policy algorithms, std ``noise_std`` in action units).
NOISE_TYPES = ("normal", "ornstein-uhlenbeck")


def agent_metadata(path: str | Path) -> dict:
    """The metadata of a saved agent (its folder or a file in it); ``ValueError`` for a missing or bad agent."""
    from controllers.agents import agent_files

    return agent_files(path)[1]


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
    if env_id not in table:
        raise ValueError(f"{path} has no entry for {env_id}; entries: {sorted(table)}")
    out = dict(table[env_id])
    for k, v in (overrides or {}).items():
        out[k] = v
    return check_hyperparameters(algo, out)


def check_hyperparameters(algo: str, hyper: dict) -> dict:
    """``hyper`` if every key is an RL Zoo key or a keyword of the algorithm, and the budget is valid."""
    import inspect

    from controllers.agents import _algorithm

    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {sorted(ALGOS)}, got {algo!r}")
    if algo == "cmaes":
        from .evolution import check
        check(hyper)
        return hyper
    accepted = set(inspect.signature(_algorithm(ALGOS[algo]).__init__).parameters) - {"self", "env", "policy"}
    unknown = sorted(k for k in hyper if k not in _ZOO_KEYS and k not in accepted)
    if unknown:
        raise ValueError(f"hyperparameters {unknown} are not {ALGOS[algo]} options; valid: "
                         f"{sorted(_ZOO_KEYS)} and {sorted(accepted)}")
    for v in hyper.values():
        schedule(v)  # a malformed lin_ schedule is refused before training
    residual_spec(hyper.get("residual"))
    if hyper.get("noise_type") is not None and hyper["noise_type"] not in NOISE_TYPES:
        raise ValueError(f"hyperparameter noise_type must be one of {list(NOISE_TYPES)}, got {hyper['noise_type']!r}")
    std = hyper.get("noise_std", 0.1)
    if isinstance(std, bool) or not isinstance(std, (int, float)) or not std > 0:
        raise ValueError(f"hyperparameter noise_std must be a number > 0, got {std!r}")
    if hyper.get("paired_baseline") is not None and not isinstance(hyper["paired_baseline"], str):
        raise ValueError(f"hyperparameter paired_baseline must be a law's name, got {hyper['paired_baseline']!r}")
    for key in ("n_envs", "n_timesteps"):
        v = hyper.get(key, 1)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 1 or float(v) != int(v):
            raise ValueError(f"hyperparameter {key} must be an integer >= 1, got {v!r}")
    return hyper


def residual_spec(value) -> dict | None:
    """The ``residual`` entry as {"law": name, "scale": s} (None: no residual); ``ValueError`` if malformed."""
    if value is None or value is False:
        return None
    spec = {"law": value} if isinstance(value, str) else dict(value) if isinstance(value, dict) else None
    if spec is None or not isinstance(spec.get("law"), str) or set(spec) - {"law", "scale"}:
        raise ValueError(f"hyperparameter residual must be a law's name or {{law: name, scale: s}}, got {value!r}")
    scale = spec.setdefault("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale <= 1:
        raise ValueError(f"the residual's scale must be a number in (0, 1], got {scale!r}")
    return spec


def check_laws(hyper: dict, env_id: str, env_kwargs: dict) -> None:
    """The residual's and the paired baseline's laws exist and apply to the environment (``ValueError`` naming
    the option and the valid laws otherwise), before any training starts."""
    from controllers import available_controllers
    from controllers.residual import Residual

    import gymnasium as gym

    laws = [("residual", (residual_spec(hyper.get("residual")) or {}).get("law")),
            ("paired_baseline", hyper.get("paired_baseline"))]
    laws = [(k, law) for k, law in laws if law is not None]
    if not laws:
        return
    for key, law in laws:
        if law not in available_controllers():
            raise ValueError(f"{key} must be one of {available_controllers()}, got {law!r}")
    env = gym.make(env_id, **env_kwargs)
    try:
        for key, law in laws:
            try:
                Residual(env, law)
            except ValueError as exc:
                raise ValueError(f"{key} {law!r} does not apply to {env_id}: {exc}") from None
    finally:
        env.close()


def check_with_sb3(algo: str, hyper: dict, env_id: str, env_kwargs: dict) -> None:
    """Build the model once on a one-environment copy of the set-up, so that a value SB3 refuses (e.g.
    ``learning_rate=banana``) is a ``ValueError`` naming the hyperparameter before any training starts."""
    from controllers.agents import _algorithm

    from mrd_env.envs.sb3 import make_sb3_vec_env

    cls = _algorithm(ALGOS[algo])
    venv = make_sb3_vec_env(env_id, n_envs=1, seed=0, **env_kwargs)
    kwargs = algorithm_kwargs(hyper, venv.action_space.shape[0])
    policy = hyper.get("policy", "MlpPolicy")

    def builds(kw: dict) -> Exception | None:
        import warnings

        try:
            with warnings.catch_warnings():  # e.g. a batch size meant for the real number of environments
                warnings.simplefilter("ignore")
                cls(policy, venv, device="cpu", verbose=0, **kw)
        except Exception as exc:  # noqa: BLE001  (whatever SB3 raises for a bad value)
            return exc
        return None

    try:
        error = builds(kwargs)
        if error is None:
            return
        culprits = [k for k in kwargs if builds({k: kwargs[k]}) is not None] or sorted(kwargs)
        detail = " ".join(str(error).split())[:160] or type(error).__name__
        raise ValueError(f"{ALGOS[algo]} rejects hyperparameter(s) "
                         f"{', '.join(f'{k}={hyper.get(k, kwargs[k])!r}' for k in culprits)}: {detail}")
    finally:
        venv.close()


def algorithm_kwargs(hyper: dict, n_actions: int) -> dict:
    """The algorithm's keyword arguments of a hyperparameter entry: its own keys (``lin_`` schedules made
    SB3's), and RL Zoo's ``noise_type``/``noise_std`` as an ``action_noise``."""
    kwargs = {k: schedule(v) for k, v in hyper.items() if k not in _ZOO_KEYS}
    if hyper.get("noise_type"):
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        cls = NormalActionNoise if hyper["noise_type"] == "normal" else OrnsteinUhlenbeckActionNoise
        std = float(hyper.get("noise_std", 0.1))
        kwargs["action_noise"] = cls(mean=np.zeros(n_actions), sigma=std * np.ones(n_actions))
    return kwargs


def schedule(value):
    """RL Zoo's ``lin_<x>`` (a value decaying linearly from x to 0 over training, e.g. ``learning_rate:
    lin_3e-4``) as SB3's schedule; any other value unchanged."""
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError:
            start = math.nan
        if not start > 0:
            raise ValueError(f"a linear schedule is lin_<x> with a number x > 0, got {value!r}")
        return lambda progress_remaining: progress_remaining * start
    return value


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


def env_options(plant: str, control_dt: float = 0.01, sensors=None, history: int = 1,
                disturbance=None, **extra) -> dict:
    """The training environment's options: the plant's training distribution (or ``disturbance``), normalised
    actions, the control step, and the observation options."""
    kw = {**TRAINING[plant], "action_mode": "normalized", "control_dt": float(control_dt), "history": int(history)}
    if sensors:
        kw["sensors"] = list(sensors)
    if disturbance is not None:
        key = "road" if plant == "quarter_car" else "ground_motion"
        kw.pop("road", None)
        kw.pop("ground_motion", None)
        kw[key] = disturbance
    kw.update(extra)
    return kw


def validation_split(plant: str, env_kwargs: dict, episodes: int) -> tuple[Scenario, dict]:
    """The validation scenario of a training environment (its disturbance options on seeds training never
    draws) and the options that define what the agent sees and does (kept when the scenario changes)."""
    from controllers.agents import OBSERVATION_OPTIONS

    obs_kwargs = {k: v for k, v in env_kwargs.items() if k in OBSERVATION_OPTIONS}
    disturbance = {k: v for k, v in env_kwargs.items() if k not in OBSERVATION_OPTIONS}
    return Scenario("validation", ENV_IDS[plant], disturbance, validation(plant, episodes)[0].seeds), obs_kwargs


class _Live:
    """The agent being trained, as a predict on raw observations (the running normalisation of VecNormalize)."""

    def __init__(self, model, vecnorm):
        self.model, self.vecnorm = model, vecnorm

    def reset(self, mask=None):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        o = self.vecnorm.normalize_obs(np.asarray(obs, dtype=np.float32)) if self.vecnorm is not None else obs
        return self.model.predict(o, state=state, episode_start=episode_start, deterministic=deterministic)


def _callbacks(run_dir: Path, model_saver, vecnorm, scenarios: list[Scenario], obs_kwargs: dict, eval_freq: int,
               checkpoint_freq: int, timesteps: int, progress: bool, report=None, residual: dict | None = None):
    """Validation with best-agent saving, checkpoints and a progress bar (SB3 callbacks); ``report(timesteps,
    validation_return) -> bool`` is told every validation and stops the training when it returns False (a
    hyperparameter search's pruning)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from controllers.agents import agent_controller

    from .evaluation import evaluate_batch

    class Validation(BaseCallback):
        def __init__(self):
            super().__init__()
            self.best = -np.inf
            self.rows = []
            self.next_eval = eval_freq
            self.next_ckpt = checkpoint_freq

        def _evaluate(self):
            live = _Live(self.model, vecnorm)
            returns = []
            for sc in scenarios:
                eps = evaluate_batch(lambda v: agent_controller(v, live, residual, name="live"), sc, "", **obs_kwargs)
                returns += [e.episode_return for e in eps]
            mean = float(np.mean(returns))
            self.rows.append({"timesteps": self.num_timesteps, "validation_return": mean,
                              "validation_return_std": float(np.std(returns))})
            _write_csv(run_dir / "validation.csv", self.rows)
            if mean > self.best:
                self.best = mean
                model_saver(run_dir / "best", {"validation_return": mean, "timesteps": self.num_timesteps})
            say_validation(run_dir.name, self.num_timesteps, mean, self.best, progress)
            return report is None or report(self.num_timesteps, mean)

        def _on_training_start(self) -> None:
            if eval_freq:  # the curve starts from the untrained (or warm-started) policy
                self._evaluate()

        def _on_step(self) -> bool:
            if eval_freq and self.num_timesteps >= self.next_eval:
                while self.next_eval <= self.num_timesteps:  # once, however many steps a vector step adds
                    self.next_eval += eval_freq
                if not self._evaluate():
                    return False
            if checkpoint_freq and self.num_timesteps >= self.next_ckpt:
                while self.next_ckpt <= self.num_timesteps:
                    self.next_ckpt += checkpoint_freq
                model_saver(run_dir / "checkpoints" / f"step_{self.num_timesteps}", {"timesteps": self.num_timesteps})
            return True

        def _on_training_end(self) -> None:
            # the model after the last update, unless the last validation already scored it
            if eval_freq and (not self.rows or self.rows[-1]["timesteps"] != self.num_timesteps):
                self._evaluate()

    class Progress(BaseCallback):
        def _on_training_start(self):
            from tqdm.auto import tqdm
            self.bar = tqdm(total=timesteps, desc=f"train {run_dir.name}", unit="step", disable=not progress)

        def _on_step(self) -> bool:
            self.bar.update(self.model.num_timesteps - self.bar.n)
            return True

        def _on_training_end(self):
            self.bar.close()

    return Validation(), Progress()


def say_validation(run: str, steps: int, value: float, best: float, progress: bool) -> None:
    """One console line per validation (above the progress bar): the return now and the best so far."""
    if progress:
        from tqdm.auto import tqdm

        tqdm.write(f"{run}: validation return {value:.4g} at {steps} steps (best so far {best:.4g})")


def _write_csv(path: Path, rows: list[dict]) -> None:
    import csv

    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def run_name(plant: str, algo: str, hyper: dict, env_kwargs: dict) -> str:
    """``<plant>_<algo>`` with the variant's tags: ``-residual``, ``-paired``, ``-h<k>`` (history), ``-preview``."""
    tags = (["residual"] if residual_spec(hyper.get("residual")) else []) + \
        (["paired"] if hyper.get("paired_baseline") else []) + \
        ([f"h{int(env_kwargs['history'])}"] if int(env_kwargs.get("history", 1)) > 1 else []) + \
        (["preview"] if env_kwargs.get("preview") else [])
    return "_".join((plant, "-".join([algo, *tags])))


def train_one(plant: str, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
              hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
              eval_episodes: int = 8, checkpoint_freq: int = 0, tensorboard: bool = False, progress: bool = False,
              command: str = "", report=None, warm_start: str | None = None) -> Path:
    """Train one agent (see the module docstring); return its folder. ``report``: see :func:`_callbacks`;
    ``warm_start`` (CMA-ES): a law's name, which the policy imitates before training (:mod:`.warm_start`)."""
    if algo == "cmaes":
        if report is not None or checkpoint_freq or tensorboard:
            raise ValueError("CMA-ES training has no pruning, checkpoints or TensorBoard logs")
        from .evolution import train_cmaes
        return train_cmaes(plant, seed, out=out, timesteps=timesteps, hyper=hyper, env_kwargs=env_kwargs,
                           eval_freq=eval_freq, eval_episodes=eval_episodes, progress=progress, command=command,
                           warm_start=warm_start)
    if warm_start is not None:
        raise ValueError("--warm-start applies to --algo cmaes")
    import torch
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from controllers.agents import AGENT_FORMAT, _algorithm
    from controllers.residual import zero_policy_output
    from controllers.training_wrappers import PairedBaselineVecEnv, ResidualVecEnv

    from mrd_env.envs.sb3 import make_sb3_vec_env

    if plant not in ENV_IDS:
        raise ValueError(f"plant must be one of {sorted(ENV_IDS)}, got {plant!r}")
    if algo not in ALGOS:
        raise ValueError(f"algo must be one of {sorted(ALGOS)}, got {algo!r}")
    env_id = ENV_IDS[plant]
    hyper = dict(hyper if hyper is not None else hyperparameters(algo, env_id))
    env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
    env_kwargs.update(hyper.get("env_kwargs") or {})
    n_envs = int(hyper.get("n_envs", 1))
    timesteps = int(timesteps if timesteps is not None else float(hyper.get("n_timesteps", 100_000)))
    if timesteps < 1:
        raise ValueError(f"timesteps must be >= 1, got {timesteps}")
    run_dir = Path(out) / f"{run_name(plant, algo, hyper, env_kwargs)}_s{seed}"
    run_dir.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)  # the environments take the other core
    residual = residual_spec(hyper.get("residual"))
    venv = make_sb3_vec_env(env_id, n_envs=n_envs, seed=seed, **env_kwargs)
    if residual:
        venv = ResidualVecEnv(venv, residual["law"], residual["scale"])
    venv = VecMonitor(venv, filename=str(run_dir / "training"))  # the environment's own returns
    if hyper.get("paired_baseline"):
        venv = PairedBaselineVecEnv(venv, hyper["paired_baseline"])
    normalize = hyper.get("normalize", True)
    norm_kw = normalize if isinstance(normalize, dict) else {}
    vecnorm = VecNormalize(venv, gamma=float(hyper.get("gamma", 0.99)), **norm_kw) if normalize else None
    train_env = vecnorm if vecnorm is not None else venv
    kwargs = algorithm_kwargs(hyper, venv.action_space.shape[0])
    model = _algorithm(ALGOS[algo])(hyper.get("policy", "MlpPolicy"), train_env, seed=seed, device="cpu", verbose=0,
                                    tensorboard_log=str(Path(out) / "tensorboard") if tensorboard else None, **kwargs)
    if residual:  # the untrained agent is its law exactly
        zero_policy_output(model)
    t_start = time.perf_counter()

    def save(folder: Path, extra: dict) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        model.save(folder / "model.zip")
        meta = {"format": AGENT_FORMAT, "name": f"{ALGOS[algo]} s{seed}", "plant": plant, "env_id": env_id,
                "algo": ALGOS[algo], "recurrent": algo == "recurrentppo", "seed": seed, "timesteps": timesteps,
                "env_kwargs": env_kwargs, "hyperparameters": hyper, "model": "model.zip", "residual": residual,
                "normalization": None, "command": command, "wall_time_s": time.perf_counter() - t_start, **extra}
        if vecnorm is not None:
            rms = vecnorm.obs_rms
            np.savez(folder / "normalization.npz", mean=rms.mean, var=rms.var, clip=vecnorm.clip_obs,
                     epsilon=vecnorm.epsilon)
            meta["normalization"] = "normalization.npz"
        (folder / "agent.json").write_text(json.dumps(meta, indent=2, default=_jsonable), encoding="utf-8")

    # validation: the training distribution itself on seeds training never draws
    val, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)
    scenarios = [val]
    callbacks = _callbacks(run_dir, save, vecnorm, scenarios, obs_kwargs, eval_freq, checkpoint_freq, timesteps,
                           progress, report, residual)
    try:
        model.learn(total_timesteps=timesteps, callback=list(callbacks), tb_log_name=run_dir.name)
    except KeyboardInterrupt:  # the run so far is an agent: evaluate takes the folder
        save(run_dir, {"timesteps_done": int(model.num_timesteps), "interrupted": True})
        plot_learning_curve(run_dir)
        print(f"interrupted at {model.num_timesteps} steps: saved the agent so far in {run_dir} (the best "
              f"validated one in {run_dir / 'best'})", file=sys.stderr)
        raise
    save(run_dir, {"timesteps_done": int(model.num_timesteps)})
    plot_learning_curve(run_dir)
    train_env.close()
    return run_dir


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, tuple):
        return list(v)
    raise TypeError(f"not JSON serialisable: {type(v).__name__}")


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
            ax.plot(steps[k - 1:], y, "s-" if y.size < 20 else "-", ms=3, lw=1,
                    label=f"training episodes (mean of {k})")
            drawn = True
    val = run_dir / "validation.csv"
    if val.exists():
        rows = list(csv.DictReader(val.open()))
        ax.plot([int(r["timesteps"]) for r in rows], [float(r["validation_return"]) for r in rows], "o-", ms=3,
                label="validation (unseen seeds)")
        drawn = True
    if not drawn:
        return None
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.set_title(run_dir.name)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, run_dir / "learning_curve.png")


def plot_seed_curves(run_dirs, path: Path, references: dict[str, float] | None = None) -> Path | None:
    """The validation returns of several seeds (each, and their mean) against environment steps, with
    horizontal ``references`` (e.g. the classical laws' validation returns)."""
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
    fig, ax = figure(figsize=(7, 4))
    for name, x, y in curves:
        ax.plot(x, y, lw=0.8, alpha=0.6, label=name)
    n = min(len(y) for _, _, y in curves)
    ax.plot(curves[0][1][:n], np.mean([y[:n] for _, _, y in curves], axis=0), "k-", lw=2, label="mean over seeds")
    for i, (name, value) in enumerate((references or {}).items()):
        ax.axhline(value, ls="--", lw=1, color=f"C{(i + len(curves)) % 10}", label=name)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("validation return (unseen seeds)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, path)


def train(plant: str, algo: str, seeds, *, backend: str = "serial", jobs: int | None = None,
          address: str | None = None, **kw) -> list[Path]:
    """One agent per seed, one task each (:mod:`mrd_env.executor`: serially, on a process pool or on Ray; each
    seed's agent is the same on all of them); their folders, and with several seeds a figure of their
    validation curves (``<out>/<plant>_<algo>_learning_curves.png``)."""
    from mrd_env.executor import Task, resolve_backend, run_tasks

    seeds = [int(s) for s in seeds]
    parallel = resolve_backend(backend, len(seeds), jobs) != "serial"
    # in parallel, one progress bar over the seeds instead of one per run
    tasks = [Task(train_one, (plant, algo, s), {**kw, "progress": kw.get("progress", False) and not parallel},
                  label=f"{plant} {algo} seed {s}") for s in seeds]
    folders = run_tasks(tasks, backend=backend, jobs=jobs, address=address,
                        progress=kw.get("progress", False) and parallel, desc=f"train {plant} {algo}")
    if len(folders) > 1:
        hyper = kw.get("hyper") or {}
        env_kwargs = {**(kw.get("env_kwargs") or env_options(plant)), **(hyper.get("env_kwargs") or {})}
        refs = law_references(plant, env_kwargs, kw.get("eval_episodes", 8)) if kw.get("eval_freq") else None
        plot_seed_curves(folders, Path(kw["out"]) / f"{run_name(plant, algo, hyper, env_kwargs)}_learning_curves.png",
                         refs)
    return folders


#: The laws drawn next to the agents' validation curves: the best law at the agents' 10 ms, and a passive one.
REFERENCE_LAWS = {"quarter_car": ("skyhook_continuous", "passive_off"), "building": ("clipped_optimal", "passive_on")}


def law_references(plant: str, env_kwargs: dict | None = None, eval_episodes: int = 8) -> dict[str, float]:
    """The validation return of each of ``REFERENCE_LAWS[plant]`` on the agents' validation episodes, sensors
    and control step."""
    from controllers import make_controller

    from .evaluation import evaluate_batch

    env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
    sc, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)
    out = {}
    for law in REFERENCE_LAWS[plant]:
        eps = evaluate_batch(lambda v, n=law: make_controller(n, v), sc, "", **obs_kwargs)
        out[f"{law} @ {1000 * float(env_kwargs.get('control_dt', 1e-3)):g} ms"] = \
            float(np.mean([e.episode_return for e in eps]))
    return out


# --- CLI ----------------------------------------------------------------------------------------------------------

def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", choices=sorted(ENV_IDS), default="quarter_car")
    p.add_argument("--algo", default="ppo", help=f"one of {', '.join(available_algos())} (shipped hyperparameters); "
                                                 f"{', '.join(sorted(set(ALGOS) - set(available_algos())))} with "
                                                 "--hyperparams")
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="one agent per seed (default 0)")
    p.add_argument("--timesteps", type=int, default=None, help="environment steps (default: the YAML's n_timesteps)")
    p.add_argument("--hyperparams", type=Path, default=None, help="YAML file (default experiments/hyperparams/<algo>.yml)")
    p.add_argument("--set", nargs="+", action="extend", default=[], metavar="KEY=VALUE",
                   help="override hyperparameters (YAML values; repeatable)")
    p.add_argument("--control-dt", type=float, default=0.01, help="agent step in s (a multiple of 1 ms; default 0.01)")
    p.add_argument("--sensors", nargs="+", default=None, help="sensor names (default: the plant's measured set)")
    p.add_argument("--history", type=int, default=1, help="control steps stacked in the observation (default 1)")
    p.add_argument("--preview", action="store_true",
                   help="quarter car: the agent also sees the road 10..100 ms ahead (the road_preview sensor)")
    p.add_argument("--residual", default=None, metavar="LAW",
                   help="the agent learns a correction to this law's command, starting exactly at the law "
                        "(default: the YAML's residual, if any; 'none' to switch it off)")
    p.add_argument("--residual-scale", type=float, default=None,
                   help="largest correction as a share of the command range, in (0, 1] (default 1)")
    p.add_argument("--paired-baseline", default=None, metavar="LAW",
                   help="variance reduction: rewards relative to this law on the same disturbance "
                        "(default: the YAML's paired_baseline; 'none' to switch it off)")
    p.add_argument("--damper", default=None,
                   help="damper model name or preset file (fitted.json from mrd-env identify; default: the plant's)")
    p.add_argument("--disturbance", default=None,
                   help="training disturbance as JSON (default: the plant's training distribution), e.g. "
                        "'{\"kind\": \"iso8608\", \"road_class\": \"C\"}'")
    p.add_argument("--warm-start", default=None, metavar="LAW",
                   help="cmaes: begin as this classical law (behaviour cloning; default: the YAML's warm_start)")
    p.add_argument("--eval-freq", type=int, default=20_000, help="validation every so many steps (0: never)")
    p.add_argument("--eval-episodes", type=int, default=8, help="validation episodes (unseen seeds)")
    p.add_argument("--checkpoint-freq", type=int, default=0, help="checkpoint every so many steps (0: never)")
    p.add_argument("--tensorboard", action="store_true", help="TensorBoard logs in <out>/tensorboard")
    p.add_argument("--out", type=Path, default=Path("results/agents"))
    p.add_argument("--no-progress", action="store_true")
    sweep.add_arguments(p)


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
    disturbance = None
    if args.disturbance is not None:
        try:
            disturbance = json.loads(args.disturbance)
        except json.JSONDecodeError:
            disturbance = args.disturbance  # a kind's name
    if args.warm_start is not None:
        from controllers import available_controllers
        if args.algo != "cmaes":
            raise ValueError("--warm-start applies to --algo cmaes")
        if args.warm_start not in available_controllers():
            raise ValueError(f"--warm-start must be a law of {available_controllers()}, got {args.warm_start!r}")
    env_kwargs = env_options(args.plant, args.control_dt, args.sensors, args.history, disturbance)
    if args.damper is not None:
        from mrd_env.dampers import damper_class, is_preset_file

        damper_class(args.damper)  # ValueError naming the models, or the preset file's problem
        # a preset file by its absolute path, so that the agent's record finds it from anywhere
        env_kwargs["damper"] = str(Path(args.damper).resolve()) if is_preset_file(args.damper) else args.damper
    if args.preview:
        from .scenarios import preview_options
        env_kwargs = preview_options(args.plant, env_kwargs)
    env_id = ENV_IDS[args.plant]
    overrides = _parse_overrides(args.set)
    if args.residual is not None:
        overrides["residual"] = None if args.residual == "none" else \
            {"law": args.residual, **({"scale": args.residual_scale} if args.residual_scale is not None else {})}
    elif args.residual_scale is not None:
        raise ValueError("--residual-scale needs --residual LAW")
    if args.paired_baseline is not None:
        overrides["paired_baseline"] = None if args.paired_baseline == "none" else args.paired_baseline
    if args.algo == "cmaes" and (overrides.get("residual") or overrides.get("paired_baseline")):
        raise ValueError("--residual and --paired-baseline apply to the SB3 algorithms, not to cmaes "
                         "(CMA-ES warm-starts from a law with --warm-start)")
    hyper = hyperparameters(args.algo, env_id, args.hyperparams, overrides)
    if args.algo != "cmaes":
        full_kwargs = {**env_kwargs, **(hyper.get("env_kwargs") or {})}
        check_laws(hyper, env_id, full_kwargs)
        check_with_sb3(args.algo, hyper, env_id, full_kwargs)
    if args.tensorboard:
        import importlib.util
        if importlib.util.find_spec("tensorboard") is None:
            raise ImportError("--tensorboard needs the tensorboard package (pip install tensorboard)")
    # the environment is built (and its options checked) before any training starts
    import gymnasium as gym

    import mrd_env  # noqa: F401
    gym.make(env_id, **env_kwargs).close()
    command = "mrd-env " + " ".join(shlex.quote(a) for a in getattr(args, "_argv", sys.argv[1:]))
    folders = train(args.plant, args.algo, args.seeds, out=args.out, timesteps=args.timesteps, hyper=hyper,
                    env_kwargs=env_kwargs, eval_freq=args.eval_freq, eval_episodes=args.eval_episodes,
                    checkpoint_freq=args.checkpoint_freq, tensorboard=args.tensorboard,
                    progress=not args.no_progress, command=command, warm_start=args.warm_start, **executor)
    for f in folders:
        print(f"saved {f} (evaluate with: mrd-env evaluate --plant {args.plant} --agents {f})")
    return 0
