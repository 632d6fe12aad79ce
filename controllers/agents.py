"""Trained agents behind the controllers' interface: ``load_agent(path)`` reads an agent saved by
``mrd-env train`` — a folder holding ``agent.json`` (the metadata), ``model.zip`` (the Stable-Baselines3 or
sb3-contrib policy; ``policy.npz`` for a CMA-ES policy network, :mod:`controllers.mlp_policy`) and
``normalization.npz`` (the observation statistics it was trained with) — and returns a
:class:`TrainedAgent`: ``predict(obs)`` on raw observations of one environment or a batch, the options of the
environment it was trained in (``env_kwargs``: ``gym.make(agent.env_id, **agent.env_kwargs)`` rebuilds it) and
the options that define its observation and action (``observation_kwargs``: sensors, history, control step,
action mode), which an evaluation must keep while it changes the disturbance.

An agent is recognised by its metadata file, never by its file name. The agents shipped with the project live
in ``controllers/agents/`` (:func:`shipped_agents`).

This module owns the agent folder's format: :func:`write_agent` writes it (every trainer of ``mrd-env train``
calls it) and :func:`load_agent` reads it; and the observation normaliser (:class:`ObservationNormalizer`: the
statistics of ``normalization.npz``, applied the same way during training, validation and evaluation).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

AGENT_FORMAT = "mrd-env-agent"
#: Options of the environment that define what an agent sees and does (kept whatever the scenario).
OBSERVATION_OPTIONS = ("sensors", "sensor_noise", "sensor_delay", "history", "preview", "control_dt", "dt", "action_mode",
                       "damper", "damper_preset", "damper_params", "plant_preset", "plant_params", "damper_floors", "inverse",
                       "force_range")
SHIPPED = Path(__file__).with_name("agents")
#: The agent folder's metadata and observation statistics files.
METADATA_FILE = "agent.json"
NORMALIZATION_FILE = "normalization.npz"


class ObservationNormalizer:
    """Observations as a policy was trained on them: (o − mean)/√(var + ε), clipped to ±clip (float64) —
    SB3's ``VecNormalize`` rule, the statistics of an agent's ``normalization.npz``."""

    def __init__(self, mean, var, clip: float = 10.0, epsilon: float = 1e-8):
        self.mean, self.var = np.asarray(mean), np.asarray(var)
        self.clip, self.epsilon = float(clip), float(epsilon)
        self.scale = np.sqrt(self.var + self.epsilon)

    def __call__(self, obs) -> np.ndarray:
        return np.clip((np.asarray(obs, dtype=np.float64) - self.mean) / self.scale, -self.clip, self.clip)

    @property
    def shape(self) -> tuple:
        return tuple(np.shape(self.mean))

    @classmethod
    def from_vecnormalize(cls, vecnorm) -> "ObservationNormalizer":
        """The current statistics of an SB3 ``VecNormalize`` (a snapshot: its running statistics move on)."""
        rms = vecnorm.obs_rms
        return cls(rms.mean, rms.var, vecnorm.clip_obs, vecnorm.epsilon)

    def save(self, path: str | Path) -> Path:
        np.savez(path, mean=self.mean, var=self.var, clip=self.clip, epsilon=self.epsilon)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> "ObservationNormalizer":
        with np.load(path) as z:
            return cls(z["mean"], z["var"], float(z["clip"]), float(z["epsilon"]))


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, tuple):
        return list(v)
    raise TypeError(f"not JSON serialisable: {type(v).__name__}")


def write_agent(folder: str | Path, meta: dict, normalizer: ObservationNormalizer | None = None) -> Path:
    """Write an agent folder's metadata (``agent.json``: ``meta`` with the format tag; it must name the plant, the
    environment id, the algorithm, the environment options and the model file the trainer saved in ``folder``)
    and its observation statistics (``normalization.npz``, when the policy was trained on normalised
    observations). The folder is what :func:`load_agent` reads; returns it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    missing = [k for k in ("plant", "env_id", "algo", "env_kwargs", "model") if k not in meta]
    if missing:
        raise ValueError(f"an agent's metadata needs {missing}")
    meta = {"format": AGENT_FORMAT, **meta}
    meta["normalization"] = None
    if normalizer is not None:
        normalizer.save(folder / NORMALIZATION_FILE)
        meta["normalization"] = NORMALIZATION_FILE
    (folder / METADATA_FILE).write_text(json.dumps(tag_tuples(meta), indent=2, default=_jsonable), encoding="utf-8")
    return folder


#: JSON has no tuple, and the environments read a tuple (lo, hi) as a range to draw from but a list as choices:
#: agent.json writes a tuple as {"__tuple__": [...]}, so that ``env_kwargs`` rebuilds the training distribution.
TUPLE_TAG = "__tuple__"


def tag_tuples(value):
    """``value`` with every tuple, at any depth, as {TUPLE_TAG: [...]} (JSON-ready)."""
    if isinstance(value, tuple):
        return {TUPLE_TAG: [tag_tuples(v) for v in value]}
    if isinstance(value, list):
        return [tag_tuples(v) for v in value]
    if isinstance(value, dict):
        return {k: tag_tuples(v) for k, v in value.items()}
    return value


def _untag(obj: dict):
    return tuple(obj[TUPLE_TAG]) if set(obj) == {TUPLE_TAG} else obj


def agent_files(path: str | Path) -> tuple[Path, dict]:
    """(folder, metadata) of the agent at ``path`` (its folder, or any file in it); ``ValueError`` for a missing
    or unreadable agent."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"agent {path}: no such file or folder")
    folder = path if path.is_dir() else path.parent
    meta_path = folder / METADATA_FILE
    if not meta_path.exists():
        raise ValueError(f"agent {path}: no agent.json in {folder} (mrd-env train writes it next to the model)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"), object_hook=_untag)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"agent {path}: agent.json is not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != AGENT_FORMAT:
        raise ValueError(f"agent {path}: agent.json is not an mrd-env agent (missing \"format\": \"{AGENT_FORMAT}\")")
    missing = [k for k in ("plant", "env_id", "algo", "env_kwargs", "model") if k not in meta]
    if missing:
        raise ValueError(f"agent {path}: agent.json lacks {missing}")
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    if meta["env_id"] not in gym.registry:
        raise ValueError(f"agent {path}: unknown environment {meta['env_id']!r} in agent.json")
    if not (folder / meta["model"]).exists():
        raise ValueError(f"agent {path}: the model file {meta['model']} is missing")
    return folder, meta


def algorithm_class(name: str):
    """The Stable-Baselines3 (or sb3-contrib) class of an algorithm's name ("PPO", "RecurrentPPO", ...)."""
    import stable_baselines3 as sb3

    if hasattr(sb3, name):
        return getattr(sb3, name)
    try:
        import sb3_contrib
    except ImportError:
        raise ImportError(f"the agent's algorithm {name} needs sb3-contrib (pip install sb3-contrib)") from None
    if not hasattr(sb3_contrib, name):
        raise ValueError(f"unknown algorithm {name!r} in agent.json")
    return getattr(sb3_contrib, name)


_algorithm = algorithm_class  # the former name (tests and other sessions' modules use it)


class TrainedAgent:
    """A saved agent: SB3's ``predict`` on raw observations (normalised as in training)."""

    def __init__(self, folder: Path, meta: dict):
        self.folder = folder
        self.meta = meta
        self.plant = meta["plant"]
        self.env_id = meta["env_id"]
        self.env_kwargs = dict(meta["env_kwargs"])
        self.observation_kwargs = {k: v for k, v in self.env_kwargs.items() if k in OBSERVATION_OPTIONS}
        self.name = meta.get("name") or f"{meta['algo']} s{meta.get('seed', 0)}"
        if meta["algo"] == "CMA-ES":  # a NumPy policy network (experiments/evolution.py)
            from .mlp_policy import MLPPolicy
            self.model = MLPPolicy.load(folder / meta["model"])
        else:
            self.model = algorithm_class(meta["algo"]).load(folder / meta["model"], device="cpu")
        norm = meta.get("normalization")
        self.normalizer = ObservationNormalizer.load(folder / norm) if norm else None
        self._state = None

    def normalize(self, obs) -> np.ndarray:
        """The observation as the policy takes it (normalised as in training; float32)."""
        o = np.asarray(obs, dtype=np.float64) if self.normalizer is None else self.normalizer(obs)
        return o.astype(np.float32)

    def reset(self, mask=None) -> None:
        self._state = None

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        if episode_start is None and self.meta.get("recurrent") and obs.ndim == 2:
            episode_start = np.zeros(obs.shape[0], dtype=bool)
        action, self._state = self.model.predict(self.normalize(obs), state=self._state if state is None else state,
                                                 episode_start=episode_start, deterministic=deterministic)
        return action, self._state

    def bind(self, env):
        """This agent as a :class:`~controllers.base.AgentController` of ``env`` (one or a vector of them), after
        checking that ``env`` shows it the observation it was trained on."""
        base = getattr(env, "unwrapped", env)
        shape = tuple(getattr(base, "single_observation_space", base.observation_space).shape)
        if self.meta.get("residual"):  # a residual agent also sees its law's commands
            shape = (shape[0] + int(base.n_dampers),)
        if self.normalizer is not None and shape != self.normalizer.shape:
            raise ValueError(f"agent {self.name}: the environment's observation has shape {shape}, the agent was "
                             f"trained on {self.normalizer.shape}; build it with agent.observation_kwargs")
        if abs(float(base.control_dt) - float(self.env_kwargs.get("control_dt", 1e-3))) > 1e-12:
            raise ValueError(f"agent {self.name}: the environment steps every {base.control_dt:g} s, the agent was "
                             f"trained at {self.env_kwargs.get('control_dt', 1e-3):g} s")
        return agent_controller(env, self, self.meta.get("residual"), name=self.name, env_kwargs=self.env_kwargs)


def agent_controller(env, model, residual: dict | None = None, **options):
    """``model`` (SB3's ``predict`` on raw observations) as a controller of ``env``: its actions are the
    environment's (:class:`~controllers.base.AgentController`) or, with ``residual`` = {"law": name, "scale": s},
    corrections to that law's command (:class:`~controllers.residual.ResidualController`; ``hold``, too)."""
    if residual:
        from .residual import ResidualController
        return ResidualController(env, model, residual["law"], residual.get("scale", 1.0),
                                  boundary=residual.get("boundary", "reflect"), hold=residual.get("hold", 1),
                                  **options)
    from .base import AgentController
    return AgentController(env, model, **options)


def agent_digest(path: str | Path) -> str:
    """A short hash of the agent at ``path`` (its agent.json, model and normalisation files): what a cached result
    computed with the agent is keyed by, so that another agent in a folder of the same name (every run's
    ``best/``, a retrained shipped agent) is never served its result."""
    import hashlib

    folder, meta = agent_files(path)
    h = hashlib.sha256()
    for name in (METADATA_FILE, meta["model"], meta.get("normalization")):
        if name and (folder / name).exists():
            h.update((folder / name).read_bytes())
    return h.hexdigest()[:16]


def load_agent(path: str | Path) -> TrainedAgent:
    """The agent saved at ``path`` (its folder, or a file in it)."""
    folder, meta = agent_files(path)
    return TrainedAgent(folder, meta)


def shipped_agents(plant: str | None = None) -> list[Path]:
    """Folders of the agents shipped with the project (for ``plant``, or all)."""
    out = []
    for meta_path in sorted(SHIPPED.glob("*/agent.json")):
        meta = json.loads(meta_path.read_text(encoding="utf-8"), object_hook=_untag)
        if plant is None or meta.get("plant") == plant:
            out.append(meta_path.parent)
    return out
