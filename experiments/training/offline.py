"""Offline training (``mrd-env train --algo bc|td3bc --dataset PATH``): a policy learned from recorded episodes — Minari
datasets written by ``mrd-env dataset`` (:mod:`experiments.benchmark.dataset`) — without running the environment.

* **bc** — behaviour cloning: the policy network regresses the recorded commands on the recorded observations (least
  squares, Adam; :func:`experiments.training.warm_start.fit_policy`, the cloning that warm-starts CMA-ES).
* **td3bc** — TD3+BC (Fujimoto & Gu 2021, "A Minimalist Approach to Offline Reinforcement Learning"): TD3's twin
  critics learn Q from the recorded transitions and rewards, the actor maximises Q normalised by its mean magnitude
  plus the behaviour-cloning term, λ Q(s, π(s)) − (π(s) − a)², λ = α / mean |Q|. The losses, the target policy's
  smoothing and the Polyak updates are TorchRL's (``torchrl.objectives.TD3BCLoss``, ``SoftUpdate``); this module
  feeds it the dataset's transitions and writes the agent. d3rlpy (2.8.1) pins ``gymnasium==1.0.0`` (this project
  runs Gymnasium 1.x beyond it), so the maintained library used is TorchRL, which pins neither Gymnasium nor torch.

Both train a tanh network (:class:`controllers.mlp_policy.MLPPolicy`) on observations normalised by the dataset's
mean and variance, and save it in the project's agent format (``agent.json``, ``policy.npz``,
``normalization.npz``: arrays and JSON, :func:`controllers.agents.save_agent`), so ``mrd-env score`` and
``mrd-env benchmark`` score it like any agent, in the normalised action mode ([−1, 1]) of every trained agent: the
recorded commands (V or A, the dataset's action space) are mapped onto [−1, 1] linearly.

**The dataset fixes what the agent sees.** Each dataset carries its environment's spec; its observations (sensors,
road preview, history, control step, plant options) must be those of the agent's environment (``--preview``,
``--sensors``, ``--control-dt``), else a ``ValueError`` says what differs. ``PATH`` is a dataset's folder (the one
holding ``data/``) or a folder above several, whose episodes are concatenated. Episodes recorded on a shipped
benchmark suite's seeds are refused: an agent is scored on those episodes (``mrd-env dataset`` records the training
distribution through :func:`training_suite`).

``--timesteps`` counts gradient steps (no environment step is taken to train); validation (``--eval-freq``, in
gradient steps) runs the policy on the training distribution's validation seeds, as every trainer does, and keeps
the best in ``best/``; the run folder's own agent is the last one (purely offline). Runs are reproducible bit for bit
(one torch thread, ``torch.manual_seed`` and ``numpy.random.default_rng`` from the seed).
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from experiments.common.plants import PlantProfile

#: The hyperparameters of each offline algorithm (``experiments/hyperparams/<algo>.yml``) and their defaults;
#: ``n_timesteps``: gradient steps.
DEFAULTS = {
    "bc": {"n_timesteps": 2e4, "batch_size": 512, "learning_rate": 3e-3, "hidden": [64, 64], "obs_clip": 10.0},
    # TD3+BC's published settings (Fujimoto & Gu 2021, table 3), but a tanh actor (the agent format's network) and
    # fewer gradient steps (a 1-D action; CPU)
    "td3bc": {"n_timesteps": 5e4, "batch_size": 256, "actor_lr": 3e-4, "critic_lr": 3e-4, "gamma": 0.99,
              "tau": 0.005, "policy_noise": 0.2, "noise_clip": 0.5, "policy_delay": 2, "alpha": 2.5,
              "hidden": [64, 64], "critic_hidden": [256, 256], "obs_clip": 10.0},
}
#: The algorithms' names in ``agent.json``.
LABELS = {"bc": "BC", "td3bc": "TD3+BC"}
#: The environment options that define what the agent observes, beside the sensor layout, the road preview and the
#: control step (compared between the dataset and the agent's environment).
_PLANT_OPTIONS = ("sensor_noise", "sensor_delay", "damper", "damper_preset", "damper_params", "plant_preset",
                  "plant_params", "damper_floors", "inverse", "force_range", "dt")
#: A ``training.log.csv`` row every so many gradient steps.
LOG_EVERY = 1000


def _need(*packages: str) -> None:
    import importlib.util

    missing = [p for p in packages if importlib.util.find_spec(p) is None]
    if missing:
        raise ImportError(f"offline training needs {', '.join(missing)}: pip install 'mrd-env[offline]'")


# --- hyperparameters -------------------------------------------------------------------------------------------
def check(algo: str, hyper: dict) -> dict:
    """``hyper`` completed with ``algo``'s defaults, every value checked (``ValueError`` naming the key)."""
    if algo not in DEFAULTS:
        raise ValueError(f"offline algo must be one of {sorted(DEFAULTS)}, got {algo!r}")
    defaults = DEFAULTS[algo]
    unknown = sorted(set(hyper) - set(defaults))
    if unknown:
        raise ValueError(f"hyperparameters {unknown} are not {LABELS[algo]} options; valid: {sorted(defaults)} (the "
                         "dataset fixes the environment)")
    h = {**defaults, **hyper}

    def number(key, ok, what):
        v = h[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not ok(v):
            raise ValueError(f"hyperparameter {key} must be {what}, got {v!r}")
        return v

    for key in ("n_timesteps", "batch_size", "policy_delay"):
        if key in h:
            number(key, lambda v: v >= 1 and float(v) == int(v), "an integer >= 1")
    for key in ("learning_rate", "actor_lr", "critic_lr", "obs_clip"):
        if key in h:
            number(key, lambda v: 0 < v < math.inf, "a number > 0")
    for key, ok, what in (("gamma", lambda v: 0 <= v < 1, "in [0, 1)"), ("tau", lambda v: 0 < v <= 1, "in (0, 1]"),
                          ("policy_noise", lambda v: 0 <= v < math.inf, "a number >= 0"),
                          ("noise_clip", lambda v: 0 <= v < math.inf, "a number >= 0"),
                          ("alpha", lambda v: 0 <= v < math.inf, "a number >= 0")):
        if key in h:
            number(key, ok, what)
    for key in ("hidden", "critic_hidden"):
        if key in h:
            v = h[key]
            if not isinstance(v, (list, tuple)) or not v or \
                    any(isinstance(x, bool) or not isinstance(x, int) or x < 1 for x in v):
                raise ValueError(f"hyperparameter {key} must be a list of layer widths >= 1, got {v!r}")
            h[key] = [int(x) for x in v]
    return h


def check_entry(algo: str, hyper: dict) -> dict:
    """The trainer interface's check (:class:`~experiments.training.trainers.Trainer`)."""
    return check(algo, hyper)


# --- datasets --------------------------------------------------------------------------------------------------
def dataset_folders(path: str | Path) -> list[Path]:
    """The Minari datasets at ``path``: itself (a folder holding ``data/metadata.json``) or every one below it, in
    name order (staging folders, whose names start with '.', left out); ``ValueError`` where there is none."""
    path = Path(path)
    if not path.is_dir():
        raise ValueError(f"--dataset {path}: not a folder (a Minari dataset's folder, as mrd-env dataset writes)")
    if (path / "data" / "metadata.json").is_file():
        return [path]
    found = sorted(p.parent.parent for p in path.rglob("data/metadata.json")
                   if not any(part.startswith(".") for part in p.relative_to(path).parts))
    if not found:
        raise ValueError(f"--dataset {path}: no Minari dataset in it (a dataset's folder holds data/metadata.json; "
                         "record one with mrd-env dataset)")
    return found


@dataclass
class Transitions:
    """The transitions of one or more datasets: observations (n, d) and the next ones, the commands mapped onto
    [−1, 1] (n, k), rewards (n,) and terminations (n,) — a truncated episode's last transition is not terminal —
    with what they came from (``source``: one entry per dataset) for ``agent.json``."""

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    next_observations: np.ndarray
    terminations: np.ndarray
    episodes: int
    source: list = field(default_factory=list)


def _signature(env_id: str, kwargs: dict) -> dict:
    """What an agent on ``env_id`` with ``kwargs`` observes: the sensor layout (names, columns, units), the road
    preview times, the control and physics steps, the observation's size, and the plant options."""
    import gymnasium as gym

    import mrd_env  # noqa: F401

    from mrd_env.envs.entry import TorchThreadsWarning

    with warnings.catch_warnings():  # built to be read, never stepped next to a training
        warnings.simplefilter("ignore", TorchThreadsWarning)
        env = gym.make(env_id, **kwargs)
    try:
        base = env.unwrapped
        return {"sensors": [(n, sl.start, sl.stop, u) for n, sl, u in base.sensor_layout],
                "road preview (s)": list(getattr(base, "preview_times", ())),
                "control step (s)": float(base.control_dt), "observation size": int(env.observation_space.shape[0]),
                **{k: _json(kwargs.get(k)) for k in _PLANT_OPTIONS}}
    finally:
        env.close()


def _json(value):
    """``value`` as JSON gives it back (tuples as lists): options compared or stored as the files hold them."""
    import json

    return json.loads(json.dumps(value))


def _differences(ours: dict, theirs: dict) -> str:
    return "; ".join(f"{k}: the dataset's {theirs[k]!r}, the agent's {ours[k]!r}" for k in ours if ours[k] != theirs[k])


def load_transitions(path: str | Path, plant: PlantProfile, env_kwargs: dict) -> Transitions:
    """The transitions of the datasets at ``path`` (:func:`dataset_folders`) for an agent on ``plant`` with the
    environment options ``env_kwargs``: ``ValueError`` for a dataset of another environment, of other observations,
    recorded on a shipped benchmark suite's episodes, or empty."""
    _need("minari", "h5py")
    from minari.dataset.minari_dataset import MinariDataset

    from mrd_env.suites import suites

    if env_kwargs.get("action_mode") != "normalized":
        raise ValueError("an offline agent acts in the normalised action mode (action_mode 'normalized'), got "
                         f"{env_kwargs.get('action_mode')!r}")
    ours = _signature(plant.env_id, env_kwargs)
    shipped = {s.digest: sid for sid, s in suites().items()}
    O, A, R, O2, T, source, episodes = [], [], [], [], [], [], 0
    for folder in dataset_folders(path):
        try:
            ds = MinariDataset(folder / "data")
        except Exception as exc:  # h5py's and Minari's own errors on a damaged or foreign folder
            raise ValueError(f"--dataset {folder}: not a readable Minari dataset ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:160]})") from None
        env_spec = ds.spec.env_spec
        if env_spec is None:
            raise ValueError(f"--dataset {folder}: records no environment spec (the agent's observations cannot be "
                             "checked)")
        if env_spec.id != plant.env_id:
            raise ValueError(f"--dataset {folder}: recorded on {env_spec.id}, the {plant.name} agent runs "
                             f"{plant.env_id}")
        diff = _differences(ours, _signature(env_spec.id, dict(env_spec.kwargs)))
        if diff:
            raise ValueError(f"--dataset {folder}: other observations than the agent's ({diff}; --preview, --sensors "
                             "and --control-dt choose the agent's)")
        meta = dict(ds.storage.metadata.get("mrd_env") or {})
        suite = meta.get("suite") or {}
        if suite.get("digest") in shipped:
            raise ValueError(f"--dataset {folder}: recorded on the episodes of the benchmark suite "
                             f"{shipped[suite['digest']]}, on which agents are scored: record the training distribution "
                             "instead (experiments.training.offline.training_suite)")
        space = ds.action_space
        low, high = np.asarray(space.low, dtype=np.float64), np.asarray(space.high, dtype=np.float64)
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(high > low)):
            raise ValueError(f"--dataset {folder}: its action space {space} is not bounded (the commands cannot be "
                             "mapped onto [-1, 1])")
        n0 = sum(len(a) for a in A)
        for ep in ds.iterate_episodes():
            obs = np.asarray(ep.observations, dtype=np.float64)
            O.append(obs[:-1])
            O2.append(obs[1:])
            a = np.asarray(ep.actions, dtype=np.float64).reshape(len(obs) - 1, -1)
            A.append(np.clip(2.0 * (a - low) / (high - low) - 1.0, -1.0, 1.0))
            R.append(np.asarray(ep.rewards, dtype=np.float64))
            T.append(np.asarray(ep.terminations, dtype=bool))
            episodes += 1
        source.append({"dataset": ds.spec.dataset_id, "folder": str(folder), "episodes": int(ds.total_episodes),
                       "steps": int(sum(len(a) for a in A) - n0), "controller": ds.storage.metadata.get("algorithm_name"),
                       "causal": meta.get("causal"), "suite": suite.get("id"), "suite_digest": suite.get("digest"),
                       "seeds": [int(e["seed"]) for e in meta.get("episodes", [])]})
    if not A or sum(len(a) for a in A) == 0:
        raise ValueError(f"--dataset {path}: holds no transition")
    return Transitions(np.concatenate(O), np.concatenate(A), np.concatenate(R), np.concatenate(O2),
                       np.concatenate(T), episodes, source)


def check_dataset(path, plant: PlantProfile, env_kwargs: dict) -> Transitions:
    """The CLI's check before training (``ValueError`` naming the problem); the transitions."""
    return load_transitions(path, plant, env_kwargs)


def training_suite(plant: PlantProfile, like: str = "car-preview-v1", episodes: int = 200, first_seed: int = 0):
    """A suite without references (:class:`mrd_env.suites.Suite`) of the plant's **training distribution** on seeds
    ``first_seed`` … (those training draws from, below the validation and test seeds), with the sensors, road preview
    and control step of the suite ``like``: what ``mrd-env dataset --suite`` records episodes for an offline agent
    on, never the benchmark's episodes."""
    from experiments.benchmark.scoring import resolve_suite
    from experiments.common.scenarios import HELD_OUT_SEED
    from mrd_env.suites import Suite, SuiteScenario

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a whole number >= 1, got {episodes!r}")
    if isinstance(first_seed, bool) or not isinstance(first_seed, int) or \
            not 0 <= first_seed <= HELD_OUT_SEED - episodes:
        raise ValueError(f"first_seed must be in [0, {HELD_OUT_SEED - episodes}] (the training seeds, below "
                         f"{HELD_OUT_SEED}), got {first_seed!r}")
    base = resolve_suite(like)
    if base.plant != plant.name:
        raise ValueError(f"suite {base.id} is of the {base.plant}, not of the {plant.name}")
    seeds = tuple(range(first_seed, first_seed + episodes))
    return Suite(name=f"{base.name}-training", version=base.version, plant=base.plant, env_id=base.env_id,
                 description=f"the {plant.title}'s training distribution (seeds {seeds[0]}-{seeds[-1]}) with the "
                             f"sensors and control step of {base.id}; no references: a source of offline datasets, "
                             "not a benchmark",
                 options={**plant.options, **base.options}, control_dt=base.control_dt,
                 scenarios=(SuiteScenario("training", dict(plant.training), seeds),), criteria=base.criteria)


def write_training_suite(path: str | Path, plant: PlantProfile, **kw) -> Path:
    """:func:`training_suite` written as a suite file (with its content digest; atomically) for ``mrd-env dataset
    --suite PATH``."""
    from mrd_env import storage
    from mrd_env.suites import content_digest

    data = _json(training_suite(plant, **kw).to_json())
    data["digest"] = content_digest(data)
    return storage.write_json(Path(path), data, indent=1)


# --- training --------------------------------------------------------------------------------------------------
class _Run:
    """What both trainers share: the checked hyperparameters, the transitions, the normalisation, the run folder,
    the validation and the agent's save."""

    def __init__(self, plant: PlantProfile, algo: str, seed: int, *, out, timesteps, hyper, env_kwargs, eval_episodes,
                 progress, command, dataset):
        import torch

        from controllers.agents import ObservationNormalizer

        from experiments.training.trainers import NetworkValidation, env_options, run_name, validation_split

        if dataset is None:
            raise ValueError(f"--algo {algo} learns from recorded episodes: give --dataset FOLDER")
        torch.set_num_threads(1)  # one thread: the same weights on every machine, bit for bit (as fit_policy)
        self.t_start = time.perf_counter()
        self.plant, self.algo, self.seed, self.command = plant, algo, int(seed), command
        self.h = check(algo, dict(hyper or {}))
        self.env_kwargs = dict(env_kwargs if env_kwargs is not None else env_options(plant))
        self.steps = int(timesteps if timesteps is not None else float(self.h["n_timesteps"]))
        self.data = load_transitions(dataset, plant, self.env_kwargs)
        obs = self.data.observations
        self.norm = ObservationNormalizer(obs.mean(axis=0), obs.var(axis=0), float(self.h["obs_clip"]), 1e-8)
        self.sizes = (obs.shape[1], *self.h["hidden"], self.data.actions.shape[1])
        self.run_dir = Path(out) / f"{run_name(plant, algo, self.h, self.env_kwargs)}_s{self.seed}"
        self.run_dir.mkdir(parents=True, exist_ok=True)
        val, obs_kwargs = validation_split(plant, self.env_kwargs, eval_episodes)
        self.validation = NetworkValidation(self.run_dir, val, obs_kwargs, self.save, progress)
        self.log: list[dict] = []

    def live(self, theta):
        from controllers.mlp_policy import MLPPolicy

        from experiments.training.evolution import NormalizedPolicy

        return NormalizedPolicy(MLPPolicy(self.sizes, theta), self.norm.mean, self.norm.var, self.norm.clip)

    def validate(self, theta, steps: int) -> None:
        self.validation(self.live(theta), theta, steps)

    def save(self, folder: Path, theta, extra: dict, in_place: bool = False) -> None:
        from controllers.agents import save_agent
        from controllers.mlp_policy import MLPPolicy

        from experiments.training.trainers import agent_name

        d = self.data
        meta = {"name": agent_name(LABELS[self.algo], self.seed, self.h, self.env_kwargs), "plant": self.plant.name,
                "env_id": self.plant.env_id, "algo": LABELS[self.algo], "recurrent": False, "seed": self.seed,
                "timesteps": 0, "offline": True, "gradient_steps": self.steps, "env_kwargs": self.env_kwargs,
                "hyperparameters": self.h, "command": self.command,
                "dataset": {"episodes": d.episodes, "transitions": int(len(d.actions)), "datasets": d.source},
                "wall_time_s": time.perf_counter() - self.t_start, **extra}
        save_agent(folder, meta, policy=MLPPolicy(self.sizes, theta), normalizer=self.norm, in_place=in_place)

    def write_log(self) -> None:
        from experiments.training.trainers import write_csv

        if self.log:
            write_csv(self.run_dir / "training.log.csv", self.log)

    def finish(self, theta, done: int, eval_freq: int, interrupted: bool = False) -> Path:
        from experiments.training.trainers import plot_learning_curve

        self.write_log()
        if eval_freq and not interrupted:
            self.validate(theta, done)
        extra = {"gradient_steps_done": done, **({"interrupted": True} if interrupted else {})}
        self.save(self.run_dir, theta, extra, in_place=True)
        plot_learning_curve(self.run_dir)
        if interrupted:
            print(f"interrupted at {done} gradient steps: saved the agent so far in {self.run_dir}", file=sys.stderr)
        return self.run_dir


def train_bc(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
             hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
             eval_episodes: int = 8, progress: bool = False, command: str = "", dataset=None) -> Path:
    """Behaviour cloning (``algo`` "bc"; the module docstring): the policy fitted to the dataset's commands in
    ``timesteps`` gradient steps (whole epochs: rounded up); its folder. One validation, at the end."""
    from experiments.training.warm_start import fit_policy

    run = _Run(plant, algo, seed, out=out, timesteps=timesteps, hyper=hyper, env_kwargs=env_kwargs,
               eval_episodes=eval_episodes, progress=progress, command=command, dataset=dataset)
    h, d = run.h, run.data
    batches = max(1, len(d.actions) // int(h["batch_size"]))  # fit_policy's batches per epoch
    epochs = max(1, math.ceil(run.steps / batches))
    run.steps = epochs * batches
    X = run.norm(d.observations)
    theta = fit_policy(run.sizes, X, d.actions, seed=run.seed, epochs=epochs, batch_size=int(h["batch_size"]),
                       learning_rate=float(h["learning_rate"]))
    mse = float(np.mean((run.live(theta).policy.predict(X)[0] - d.actions) ** 2))
    run.log.append({"gradient_steps": run.steps, "epochs": epochs, "bc_mse": mse,
                    "wall_s": round(time.perf_counter() - run.t_start, 3)})
    return run.finish(theta, run.steps, eval_freq)


def _tanh_mlp(sizes):
    import torch

    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.Tanh()]
    return torch.nn.Sequential(*layers)


def _theta(net) -> np.ndarray:
    """A tanh ``Sequential``'s weights as an :class:`~controllers.mlp_policy.MLPPolicy`'s flat θ (each layer's
    (n_in, n_out) matrix, then its bias)."""
    out = []
    for m in net:
        if hasattr(m, "weight"):
            out += [m.weight.detach().double().numpy().T.ravel(), m.bias.detach().double().numpy()]
    return np.concatenate(out)


def train_td3bc(plant: PlantProfile, algo: str, seed: int, *, out: Path, timesteps: int | None = None,
                hyper: dict | None = None, env_kwargs: dict | None = None, eval_freq: int = 20_000,
                eval_episodes: int = 8, progress: bool = False, command: str = "", dataset=None) -> Path:
    """TD3+BC (``algo`` "td3bc"; the module docstring) for ``timesteps`` gradient steps of the critics (the actor
    and the targets every ``policy_delay``-th); its folder."""
    _need("torchrl", "tensordict")
    import torch
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule
    from torchrl.modules import ValueOperator
    from torchrl.objectives import SoftUpdate, TD3BCLoss

    run = _Run(plant, algo, seed, out=out, timesteps=timesteps, hyper=hyper, env_kwargs=env_kwargs,
               eval_episodes=eval_episodes, progress=progress, command=command, dataset=dataset)
    h, d = run.h, run.data
    torch.manual_seed(run.seed)
    rng = np.random.default_rng(run.seed)
    n_obs, n_act = run.sizes[0], run.sizes[-1]

    class Critic(torch.nn.Module):
        def __init__(self):
            super().__init__()
            widths = (n_obs + n_act, *h["critic_hidden"])
            layers = []
            for a, b in zip(widths[:-1], widths[1:]):
                layers += [torch.nn.Linear(a, b), torch.nn.ReLU()]
            self.net = torch.nn.Sequential(*layers, torch.nn.Linear(widths[-1], 1))

        def forward(self, observation, action):
            return self.net(torch.cat([observation, action], -1))

    actor = TensorDictModule(_tanh_mlp(run.sizes), in_keys=["observation"], out_keys=["action"])
    qvalue = ValueOperator(module=Critic(), in_keys=["observation", "action"])
    loss = TD3BCLoss(actor, qvalue, bounds=(-1.0, 1.0), num_qvalue_nets=2, policy_noise=float(h["policy_noise"]),
                     noise_clip=float(h["noise_clip"]), alpha=float(h["alpha"]), loss_function="l2")
    loss.make_value_estimator(gamma=float(h["gamma"]))
    target = SoftUpdate(loss, tau=float(h["tau"]))
    actor_opt = torch.optim.Adam(list(loss.actor_network_params.values(True, True)), lr=float(h["actor_lr"]))
    critic_opt = torch.optim.Adam(list(loss.qvalue_network_params.values(True, True)), lr=float(h["critic_lr"]))

    f32 = lambda x: torch.as_tensor(np.asarray(x, dtype=np.float32))  # noqa: E731
    O, O2, A = f32(run.norm(d.observations)), f32(run.norm(d.next_observations)), f32(d.actions)
    R = f32(d.rewards)[:, None]
    T = torch.as_tensor(d.terminations)[:, None]
    n, B, delay = len(A), int(h["batch_size"]), int(h["policy_delay"])

    def theta():
        with loss.actor_network_params.to_module(loss.actor_network):
            return _theta(loss.actor_network.module)

    from tqdm.auto import tqdm
    bar = tqdm(total=run.steps, desc=f"train {run.run_dir.name}", unit="step", disable=not progress)
    step, sums = 0, {}
    try:
        while step < run.steps:
            if eval_freq and step % eval_freq == 0:
                run.validate(theta(), step)
            i = torch.as_tensor(rng.integers(0, n, size=B))
            batch = TensorDict({"observation": O[i], "action": A[i], ("next", "observation"): O2[i],
                                ("next", "reward"): R[i], ("next", "done"): T[i], ("next", "terminated"): T[i]},
                               batch_size=[B])
            q_loss, _ = loss.qvalue_loss(batch)
            critic_opt.zero_grad()
            q_loss.backward()
            critic_opt.step()
            sums["loss_qvalue"] = sums.get("loss_qvalue", 0.0) + float(q_loss.detach())
            if step % delay == 0:
                a_loss, info = loss.actor_loss(batch)
                actor_opt.zero_grad()
                a_loss.backward()
                actor_opt.step()
                target.step()
                for k, v in (("loss_actor", a_loss), ("bc_loss", info["bc_loss"]), ("lambda", info["lmbd"])):
                    sums[k] = sums.get(k, 0.0) + float(v.detach()) * delay  # a mean over the block's steps
            step += 1
            bar.update(1)
            if step % LOG_EVERY == 0 or step == run.steps:
                k = step - (len(run.log) * LOG_EVERY)
                run.log.append({"gradient_steps": step, **{key: v / k for key, v in sums.items()},
                                "wall_s": round(time.perf_counter() - run.t_start, 3)})
                sums = {}
                if len(run.log) % 10 == 0:
                    run.write_log()
    except KeyboardInterrupt:  # the policy so far is an agent
        bar.close()
        run.finish(theta(), step, eval_freq, interrupted=True)
        raise
    bar.close()
    return run.finish(theta(), step, eval_freq)
