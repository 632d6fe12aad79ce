"""The Stable-Baselines3 trainer of ``mrd-env train`` (PPO, SAC, TD3, A2C, and sb3-contrib's RecurrentPPO and TQC;
:class:`~experiments.training.trainers.Trainer`): RL Zoo's hyperparameter entries, the native vector environment through
the SB3 bridge with observations (and rewards) normalised by ``VecNormalize``, validation with best-agent saving,
checkpoints, TensorBoard logs, a hyperparameter search's pruning; residual policies (``residual``: the agent learns a
correction to a law's command), the paired baseline (``paired_baseline``: rewards relative to a law on the same
disturbance) and, for SAC, TD3 and TQC, the actor warm-up (``actor_warmup_steps``: the critic learns first) and the
actor's own learning rate (``actor_learning_rate``; :mod:`.actor_warmup`). The agent folder is
:func:`controllers.agents.save_agent`'s (the policy as arrays, code-free; SB3's ``model.zip`` beside it to resume
training); every save is atomic."""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from experiments.training.actor_warmup import actor_options, with_actor_warmup
from experiments.common.plants import PlantProfile
from experiments.common.scenarios import Scenario
from experiments.training.trainers import (TRAINERS, agent_name, passive_reference, plot_learning_curve, residual_spec, run_name,
                       say_validation, validation_split, write_csv)

#: Keys of a hyperparameter entry that are not the algorithm's keyword arguments: RL Zoo's, and ours —
#: ``residual`` (a law's name, or {law, scale, boundary, hold}: the agent learns a correction to it, held for
#: ``hold`` steps of the law; :mod:`controllers.residual`)
#: ``paired_baseline`` (a law's name: rewards relative to it on the same disturbance,
#: :class:`controllers.training_wrappers.PairedBaselineVecEnv`), ``actor_warmup_steps`` and ``actor_learning_rate``
#: (SAC, TD3, TQC: gradient steps with the actor frozen while the critic learns; the actor's own learning rate;
#: :mod:`.actor_warmup`).
_ZOO_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs", "noise_type", "noise_std", "residual",
             "paired_baseline", "actor_warmup_steps", "actor_learning_rate")
#: RL Zoo's ``noise_type`` values (action noise of the off-policy algorithms, std ``noise_std`` in action units).
NOISE_TYPES = ("normal", "ornstein-uhlenbeck")



def check(algo: str, hyper: dict) -> dict:
    """``hyper`` if every key is an RL Zoo key or a keyword of the algorithm, and the budget is valid."""
    import inspect

    from controllers.agents import algorithm_class

    label = TRAINERS[algo].label
    accepted = set(inspect.signature(algorithm_class(label).__init__).parameters) - {"self", "env", "policy"}
    unknown = sorted(k for k in hyper if k not in _ZOO_KEYS and k not in accepted)
    if unknown:
        raise ValueError(f"hyperparameters {unknown} are not {label} options; valid: "
                         f"{sorted(_ZOO_KEYS)} and {sorted(accepted)}")
    for v in hyper.values():
        schedule(v)  # a malformed lin_ schedule is refused before training
    residual_spec(hyper.get("residual"))
    actor_options(algo, hyper)
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




def check_laws(hyper: dict, env_id: str, env_kwargs: dict) -> None:
    """The residual's and the paired baseline's laws exist and apply to the environment (``ValueError`` naming
    the option and the valid laws otherwise), before any training starts."""
    from controllers import available_controllers
    from controllers.residual import Residual

    from experiments.common.evaluation import laws_apply

    laws = [("residual", (residual_spec(hyper.get("residual")) or {}).get("law")),
            ("paired_baseline", hyper.get("paired_baseline"))]
    laws = [(k, law) for k, law in laws if law is not None]
    if not laws:
        return
    for key, law in laws:
        if law not in available_controllers():
            raise ValueError(f"{key} must be one of {available_controllers()}, got {law!r}")
    laws_apply(env_id, env_kwargs, laws, env_id, Residual)


def check_with_sb3(algo: str, hyper: dict, env_id: str, env_kwargs: dict) -> None:
    """Build the model once on a one-environment copy of the set-up, so that a value SB3 refuses (e.g.
    ``learning_rate=banana``) is a ``ValueError`` naming the hyperparameter before any training starts."""
    from controllers.agents import algorithm_class

    from mrd_env.envs.sb3 import make_sb3_vec_env

    import torch

    torch.set_num_threads(1)  # this command's own process, as train_sb3's: no thread spins against the environment
    label = TRAINERS[algo].label
    cls = algorithm_class(label)
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
        raise ValueError(f"{label} rejects hyperparameter(s) "
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




class _Live:
    """The agent being trained, as a predict on raw observations (VecNormalize's statistics at this validation,
    :class:`controllers.agents.ObservationNormalizer`)."""

    def __init__(self, model, vecnorm):
        from controllers.agents import ObservationNormalizer

        self.model = model
        self.normalize = ObservationNormalizer.from_vecnormalize(vecnorm) \
            if vecnorm is not None and vecnorm.norm_obs else None

    def reset(self, mask=None):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        o = self.normalize(np.asarray(obs, dtype=np.float32)) if self.normalize is not None else obs
        return self.model.predict(o, state=state, episode_start=episode_start, deterministic=deterministic)


def _callbacks(run_dir: Path, model_saver, vecnorm, scenarios: list[Scenario], obs_kwargs: dict, eval_freq: int,
               checkpoint_freq: int, timesteps: int, progress: bool, report=None, residual: dict | None = None):
    """Validation with best-agent saving, checkpoints and a progress bar (SB3 callbacks); ``report(timesteps,
    validation_return) -> bool`` is told every validation and stops the training when it returns False (a
    hyperparameter search's pruning)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from controllers.agents import agent_controller

    from experiments.common.evaluation import evaluate_batch

    class Validation(BaseCallback):
        def __init__(self):
            super().__init__()
            self.best = -np.inf
            self.rows = []
            self.next_eval = eval_freq
            self.next_ckpt = checkpoint_freq
            # R_p on the validation episodes, for the console lines: whether the agent beats a passive damper
            self.passive = passive_reference(scenarios[0], obs_kwargs) if eval_freq and progress else None

        def _evaluate(self):
            live = _Live(self.model, vecnorm)
            returns = []
            for sc in scenarios:
                eps = evaluate_batch(lambda v: agent_controller(v, live, residual, name="live"), sc, "", **obs_kwargs)
                returns += [e.episode_return for e in eps]
            mean = float(np.mean(returns))
            self.rows.append({"timesteps": self.num_timesteps, "validation_return": mean,
                              "validation_return_std": float(np.std(returns))})
            write_csv(run_dir / "validation.csv", self.rows)
            if mean > self.best:
                self.best = mean
                model_saver(run_dir / "best", {"validation_return": mean, "timesteps": self.num_timesteps})
            say_validation(run_dir.name, self.num_timesteps, mean, self.best, progress, self.passive)
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




def train_sb3(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
              hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
              eval_episodes: int = 8, checkpoint_freq: int = 0, tensorboard: bool = False, progress: bool = False,
              command: str = "", report=None) -> Path:
    """Train one agent of an SB3 algorithm on ``plant`` (see the module docstring); return its folder. ``report``:
    see :func:`_callbacks`."""
    import torch
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from controllers.agents import ObservationNormalizer, algorithm_class, save_agent
    from controllers.residual import zero_policy_output
    from controllers.training_wrappers import PairedBaselineVecEnv, ResidualVecEnv

    from mrd_env.envs.sb3 import make_sb3_vec_env

    from experiments.training.trainers import env_options, hyperparameters

    env_id = plant.env_id
    label = TRAINERS[algo].label
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
        venv = ResidualVecEnv(venv, residual["law"], residual["scale"], boundary=residual.get("boundary", "reflect"),
                              hold=residual.get("hold", 1))
    venv = VecMonitor(venv, filename=str(run_dir / "training"))  # the environment's own returns
    if hyper.get("paired_baseline"):
        venv = PairedBaselineVecEnv(venv, hyper["paired_baseline"])
    normalize = hyper.get("normalize", True)
    norm_kw = normalize if isinstance(normalize, dict) else {}
    vecnorm = VecNormalize(venv, gamma=float(hyper.get("gamma", 0.99)), **norm_kw) if normalize else None
    train_env = vecnorm if vecnorm is not None else venv
    kwargs = algorithm_kwargs(hyper, venv.action_space.shape[0])
    actor = actor_options(algo, hyper)  # SAC, TD3, TQC: the actor warm-up, the actor's learning rate
    cls = with_actor_warmup(algorithm_class(label)) if actor else algorithm_class(label)
    model = cls(hyper.get("policy", "MlpPolicy"), train_env, seed=seed, device="cpu", verbose=0,
                tensorboard_log=str(Path(out) / "tensorboard") if tensorboard else None, **kwargs)
    if not tensorboard:
        # what SB3 would log at verbose 0 (nothing), without the empty SB3-<time> folder it makes in the system's
        # temporary folder for every run without a log folder
        model.set_logger(Logger(folder=None, output_formats=[]))
    for k, v in actor.items():
        setattr(model, k, v)
    if residual:  # the untrained agent is its law exactly
        zero_policy_output(model)
    t_start = time.perf_counter()

    def save(folder: Path, extra: dict, in_place: bool = False) -> None:
        """The agent now, code-free (controllers.agents.save_agent), with SB3's model.zip to resume training:
        swapped in whole (best/, checkpoints) or, in the run folder, ``in_place`` (atomic either way)."""
        meta = {"name": agent_name(label, seed, hyper, env_kwargs), "plant": plant.name, "env_id": env_id,
                "algo": label, "recurrent": algo == "recurrentppo", "seed": seed, "timesteps": timesteps,
                "env_kwargs": env_kwargs, "hyperparameters": hyper, "residual": residual,
                "command": command, "wall_time_s": time.perf_counter() - t_start, **extra}
        # the statistics VecNormalize holds now, where it normalises observations (with norm_obs false they stay
        # at mean 0, variance 1, and a loaded agent would clip raw observations at ±clip_obs)
        normalizes = vecnorm is not None and vecnorm.norm_obs
        save_agent(folder, meta, policy=model.policy, sb3_model=model, in_place=in_place,
                   normalizer=ObservationNormalizer.from_vecnormalize(vecnorm) if normalizes else None)

    # validation: the training distribution itself on seeds training never draws
    val, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)
    scenarios = [val]
    callbacks = _callbacks(run_dir, save, vecnorm, scenarios, obs_kwargs, eval_freq, checkpoint_freq, timesteps,
                           progress, report, residual)
    try:
        model.learn(total_timesteps=timesteps, callback=list(callbacks), tb_log_name=run_dir.name)
    except KeyboardInterrupt:  # the run so far is an agent: evaluate takes the folder
        save(run_dir, {"timesteps_done": int(model.num_timesteps), "interrupted": True}, in_place=True)
        plot_learning_curve(run_dir)
        print(f"interrupted at {model.num_timesteps} steps: saved the agent so far in {run_dir} (the best "
              f"validated one in {run_dir / 'best'})", file=sys.stderr)
        raise
    save(run_dir, {"timesteps_done": int(model.num_timesteps)}, in_place=True)
    plot_learning_curve(run_dir)
    train_env.close()
    return run_dir


