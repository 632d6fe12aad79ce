"""``mrd-env train --algo cmaes``: an evolution strategy trains a small neural policy on the return itself.

Why: on these plants the return of an episode is dominated by the disturbance (the road, the ground motion),
not by the policy. A policy gradient sees the effect of one action through a critic that cannot predict the
disturbance ahead (R² ≈ 0.35 for the car's value), so PPO's updates are mostly noise once it is close to a good
law: started from skyhook it drifts away from it. An evolution strategy compares whole policies instead, and with
*common random numbers* the comparison is paired: every candidate of a generation drives the same ``episodes``
roads or ground motions, so the disturbance cancels out of the ranking (as in a paired t-test).

The strategy is separable CMA-ES (``cma``, Hansen's reference implementation; Ros & Hansen 2008) over the weights of
an :class:`~controllers.mlp_policy.MLPPolicy` (tanh layers, actions in [−1, 1]); evolution strategies as an
alternative to policy gradients: Salimans et al. 2017, Mania et al. 2018. The population runs in one native vector
environment (``popsize × episodes`` environments, one compiled call per step), so a generation costs about as
much as its environment steps. The policy may start as a classical law (``warm_start``: behaviour cloning on
the law's noisy rollouts, see :mod:`.warm_start`); it is the same kind of agent as any other — the same
sensors, the same control step, a policy network that ``predict`` runs on one observation.

Validation (unseen seeds of the training distribution; the first one scores the cloned law), best-agent saving,
learning curves and the agent folder are those of every ``mrd-env train`` run (:mod:`.trainers`, whose interface
this trainer implements: :func:`train_cmaes` and :func:`check_entry`); ``training.monitor.csv`` has one
row per generation (the population's mean return, its environment steps).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from experiments.common.plants import PlantProfile

#: The hyperparameters of the strategy (``experiments/hyperparams/cmaes.yml``) and their defaults.
DEFAULTS = {"n_timesteps": 5e7, "popsize": 16, "episodes": 8, "sigma0": 0.05, "hidden": [16, 16],
            "warm_start": None, "obs_clip": 10.0}


def check(hyper: dict) -> dict:
    """``hyper`` completed with the defaults, every value checked."""
    unknown = sorted(set(hyper) - set(DEFAULTS) - {"n_envs", "policy", "normalize", "env_kwargs"})
    if unknown:
        raise ValueError(f"hyperparameters {unknown} are not CMA-ES options; valid: {sorted(DEFAULTS)}")
    h = {**DEFAULTS, **hyper}
    for key in ("popsize", "episodes", "n_timesteps"):
        v = h[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v < 1 or float(v) != int(v):
            raise ValueError(f"hyperparameter {key} must be an integer >= 1, got {v!r}")
    if int(h["popsize"]) < 4:
        raise ValueError(f"hyperparameter popsize must be >= 4, got {h['popsize']}")
    if not (isinstance(h["sigma0"], (int, float)) and h["sigma0"] > 0):
        raise ValueError(f"hyperparameter sigma0 must be > 0, got {h['sigma0']!r}")
    if h["warm_start"] is not None:
        from controllers import available_controllers
        if h["warm_start"] not in available_controllers():
            raise ValueError(f"hyperparameter warm_start must be None or a law of {available_controllers()}, "
                             f"got {h['warm_start']!r}")
    hidden = h["hidden"]
    if not isinstance(hidden, (list, tuple)) or not all(isinstance(n, int) and n >= 1 for n in hidden):
        raise ValueError(f"hyperparameter hidden must be a list of layer widths >= 1, got {hidden!r}")
    return h


def check_entry(algo: str, hyper: dict) -> dict:
    """The trainer interface's check (:class:`~experiments.training.trainers.Trainer`): ``hyper`` completed with the
    defaults, every value checked."""
    return check(hyper)


class NormalizedPolicy:
    """A policy on raw observations: (o − mean)/√(var + ε), clipped
    (:class:`controllers.agents.ObservationNormalizer`), then the MLP."""

    def __init__(self, policy, mean, var, clip: float, eps: float = 1e-8):
        from controllers.agents import ObservationNormalizer

        self.policy = policy
        self.normalize = ObservationNormalizer(mean, var, clip, eps)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.policy.predict(self.normalize(obs), state)


def _returns(venv, policy, norm: NormalizedPolicy, thetas: np.ndarray, seeds: list[int]) -> tuple[np.ndarray, int]:
    """Mean return of each candidate over the same episodes (seeds), and the environment steps taken."""
    P, E = len(thetas), len(seeds)
    layers = policy.layers(thetas)
    obs, _ = venv.reset(seed=[s for _ in range(P) for s in seeds])
    done = np.zeros(P * E, dtype=bool)
    R = np.zeros(P * E)
    steps = 0
    while not done.all():
        a = policy.forward(layers, norm.normalize(obs).reshape(P, E, -1)).reshape(P * E, -1)
        obs, r, term, trunc, _ = venv.step(a)
        R[~done] += r[~done]
        steps += int((~done).sum())
        done |= term | trunc
    return R.reshape(P, E).mean(axis=1), steps


def _clone(policy, law: str, env_id: str, env_kwargs: dict, n_envs: int, seed: int, clip: float):
    """Observation statistics and the MLP's weights imitating ``law`` (or zero weights: mid-range command)."""
    import gymnasium as gym
    from gymnasium.vector import AutoresetMode

    from controllers import make_controller
    from mrd_env.envs.sb3 import SB3VecEnv

    from experiments.training.warm_start import collect, fit_policy

    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
    sb3 = SB3VecEnv(venv)
    sb3.seed(seed)
    rng = np.random.default_rng(seed)
    if law is None:
        O = collect(None, sb3, steps=1000, noise=0.5, rng=rng)[0]
    else:
        O, A, _, _ = collect(make_controller(law, venv), sb3, steps=2000, noise=0.3, rng=rng)
    obs = O.reshape(-1, O.shape[-1])
    mean, var = obs.mean(axis=0), obs.var(axis=0)
    norm = NormalizedPolicy(policy, mean, var, clip)
    if law is not None:
        policy.theta = fit_policy(policy.sizes, norm.normalize(obs), A.reshape(len(obs), -1), seed=seed)
    venv.close()
    return mean, var


def train_cmaes(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
                hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
                eval_episodes: int = 8, progress: bool = False, command: str = "",
                warm_start: str | None = None) -> Path:
    """Train one CMA-ES agent on ``plant`` (see the module docstring; ``algo`` is "cmaes"); return its folder."""
    import cma
    import gymnasium as gym

    from controllers.agents import ObservationNormalizer, save_agent
    from controllers.mlp_policy import MLPPolicy

    from experiments.common.scenarios import HELD_OUT_SEED
    from experiments.training.trainers import NetworkValidation, agent_name, env_options, plot_learning_curve, run_name, validation_split

    import mrd_env  # noqa: F401
    h = check(dict(hyper or {}))
    env_id = plant.env_id
    env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
    env_kwargs.update(h.get("env_kwargs") or {})
    law = warm_start if warm_start is not None else h["warm_start"]
    timesteps = int(timesteps if timesteps is not None else float(h["n_timesteps"]))
    P, E = int(h["popsize"]), int(h["episodes"])
    run_dir = Path(out) / f"{run_name(plant, 'cmaes', h, env_kwargs)}_s{seed}"
    run_dir.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    venv = gym.make_vec(env_id, num_envs=P * E, vectorization_mode="vector_entry_point", **env_kwargs)
    n_obs, n_act = venv.single_observation_space.shape[0], venv.single_action_space.shape[0]
    policy = MLPPolicy((n_obs, *h["hidden"], n_act))
    mean, var = _clone(policy, law, env_id, env_kwargs, E, seed, float(h["obs_clip"]))
    norm = NormalizedPolicy(policy, mean, var, float(h["obs_clip"]))
    es = cma.CMAEvolutionStrategy(policy.theta.copy(), float(h["sigma0"]),
                                  {"popsize": P, "seed": seed + 1, "CMA_diagonal": True, "verbose": -9})
    rng = np.random.default_rng(seed)

    val, obs_kwargs = validation_split(plant, env_kwargs, eval_episodes)

    def save(folder: Path, theta: np.ndarray, extra: dict, in_place: bool = False) -> None:
        meta = {"name": agent_name("CMA-ES", seed, h, env_kwargs), "plant": plant.name, "env_id": env_id,
                "algo": "CMA-ES", "recurrent": False, "seed": seed, "timesteps": timesteps, "env_kwargs": env_kwargs,
                "hyperparameters": {**h, "warm_start": law}, "command": command,
                "wall_time_s": time.perf_counter() - t_start, **extra}
        # atomic: best/ swapped in whole, the run folder's own agent in place (controllers.agents.save_agent)
        save_agent(folder, meta, policy=MLPPolicy(policy.sizes, theta), in_place=in_place,
                   normalizer=ObservationNormalizer(mean, var, float(h["obs_clip"]), 1e-8))

    validation = NetworkValidation(run_dir, val, obs_kwargs, save, progress)

    def validate(theta: np.ndarray, steps: int) -> None:
        validation(NormalizedPolicy(MLPPolicy(policy.sizes, theta), mean, var, float(h["obs_clip"])), theta, steps)

    from tqdm.auto import tqdm
    bar = tqdm(total=timesteps, desc=f"train {run_dir.name}", unit="step", disable=not progress)
    monitor = run_dir / "training.monitor.csv"
    monitor.write_text(f'#{{"t_start": {time.time()}, "env_id": "{env_id}"}}\nr,l,t\n', encoding="utf-8")
    steps, next_eval = 0, 0
    try:
        while steps < timesteps:
            if eval_freq and steps >= next_eval:
                validate(es.mean, steps)
                next_eval = steps + eval_freq
            thetas = np.asarray(es.ask())
            # common random numbers: every candidate meets the same disturbances (seeds never used by validation)
            seeds = [int(s) for s in rng.integers(0, HELD_OUT_SEED, size=E)]
            returns, n = _returns(venv, policy, norm, thetas, seeds)
            es.tell(list(thetas), list(-returns))
            steps += n
            bar.update(n)
            with monitor.open("a", encoding="utf-8") as fh:
                fh.write(f"{returns.mean():.6g},{n},{time.perf_counter() - t_start:.3f}\n")
    except KeyboardInterrupt:  # the search so far is an agent: the benchmark takes the folder
        bar.close()
        save(run_dir, es.mean, {"timesteps_done": steps, "interrupted": True}, in_place=True)
        plot_learning_curve(run_dir)
        print(f"interrupted at {steps} steps: saved the agent so far in {run_dir}", file=sys.stderr)
        raise
    bar.close()
    if eval_freq:
        validate(es.mean, steps)
    save(run_dir, es.mean, {"timesteps_done": steps}, in_place=True)
    plot_learning_curve(run_dir)
    venv.close()
    return run_dir
