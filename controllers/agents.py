"""Trained agents behind the controllers' interface: ``load_agent(path)`` reads an agent saved by
``mrd-env train`` and returns a :class:`TrainedAgent`: ``predict(obs)`` on raw observations of one environment or a
batch, the options of the environment it was trained in (``env_kwargs``: ``gym.make(agent.env_id,
**agent.env_kwargs)`` rebuilds it) and the options that define its observation and action (``observation_kwargs``:
sensors, history, control step, action mode), which an evaluation must keep while it changes the disturbance.

An agent is a folder holding ``agent.json`` (the metadata, and the description of the policy network), the policy's
weights as plain arrays — ``policy.safetensors`` for a Stable-Baselines3 or sb3-contrib policy
(:mod:`controllers.policy_format`), ``policy.npz`` for a CMA-ES network (:mod:`controllers.mlp_policy`) — and
``normalization.npz`` (the observation statistics it was trained with). Loading runs no code from the folder: the
network is built by the project from its description and the arrays are read as arrays (no pickle). SB3's own
``model.zip`` (pickled Python objects: loading one can run any code) is written beside them by the trainers to resume
training, and is loaded only with ``trust=True`` (``--trust-agent``) where an agent has nothing else
(:func:`export_agent` converts such a folder once).

Every file ``agent.json`` names is resolved inside the folder (no absolute path, no ``..``, no link leaving it:
:func:`mrd_env.storage.inside`), and its SHA-256 is recorded in ``agent.json`` (``files``) and checked when it is
loaded. Saves (:func:`save_agent`) are atomic: a save killed at any moment leaves the previous agent or the new one,
never a mix (a folder written beside its target and swapped in; in a run folder, which holds other files too, files
named by their content's digest and ``agent.json`` written last).

An agent is recognised by its metadata file, never by its file name. The agents shipped with the project live
in ``controllers/agents/`` (:func:`shipped_agents`).

This module owns the agent folder's format (:func:`save_agent` writes it: every trainer of ``mrd-env train`` calls
it; :func:`load_agent` reads it) and the observation normaliser (:class:`ObservationNormalizer`: the statistics of
``normalization.npz``, applied the same way during training, validation and evaluation).
"""
from __future__ import annotations

import glob
import hashlib
import io
import json
import os
import re
import shutil
import warnings
from pathlib import Path

import numpy as np

from mrd_env import storage

AGENT_FORMAT = "mrd-env-agent"
#: Options of the environment that define what an agent sees and does (kept whatever the scenario).
OBSERVATION_OPTIONS = ("sensors", "sensor_noise", "sensor_delay", "history", "preview", "control_dt", "dt", "action_mode",
                       "damper", "damper_preset", "damper_params", "plant_preset", "plant_params", "damper_floors", "inverse",
                       "force_range")
SHIPPED = Path(__file__).with_name("agents")
#: The agent folder's metadata and observation statistics files.
METADATA_FILE = "agent.json"
NORMALIZATION_FILE = "normalization.npz"
#: The largest agent.json read (the shipped ones: a few KiB), and the largest policy or statistics file: a network of
#: the most parameters a description may ask for (controllers.policy_format.MAX_PARAMETERS) in float64, and room.
METADATA_LIMIT, FILE_LIMIT = 16 * 1024 ** 2, 512 * 1024 ** 2
#: The policy files: an SB3/sb3-contrib policy's weights, a CMA-ES network; SB3's zip (to resume training).
POLICY_FILE, MLP_FILE, RESUME_FILE = "policy.safetensors", "policy.npz", "model.zip"
#: An agent's files in a folder that holds other files too (a run folder): named by their content's digest.
_DIGEST_NAMED = re.compile(r"(policy|normalization)-[0-9a-f]{12}\.(safetensors|npz)")
#: Temporary files of a save killed in a run folder (mrd_env.storage's names).
_LEFTOVER = re.compile(r"\.((policy|normalization)-[0-9a-f]{12}\.(safetensors|npz)|agent\.json)\..+\.tmp"
                       r"|\.model\..+\.zip")
_REQUIRED = ("plant", "env_id", "algo", "env_kwargs", "model")


class UntrustedAgentError(ValueError):
    """An agent that can only be loaded by running code from its folder (SB3's ``model.zip``), without trust."""


class AgentDigestError(ValueError):
    """A file of an agent whose content is not the one its ``agent.json`` records."""


class TrustedCodeWarning(UserWarning):
    """An agent loaded from pickled Python objects (SB3's ``model.zip``) because the caller trusted it."""


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

    def to_bytes(self) -> bytes:
        """The ``normalization.npz`` file's bytes (arrays only)."""
        buf = io.BytesIO()
        np.savez(buf, mean=self.mean, var=self.var, clip=self.clip, epsilon=self.epsilon)
        return buf.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> "ObservationNormalizer":
        """The statistics of a ``normalization.npz`` file's bytes, read as arrays only (no pickle)."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                mean, var, clip, eps = z["mean"], z["var"], z["clip"], z["epsilon"]
        except (OSError, ValueError, KeyError, EOFError) as exc:
            raise ValueError(f"not an observation statistics file (arrays mean, var, clip, epsilon): {exc}") from None
        if mean.ndim != 1 or mean.shape != var.shape or any(a.dtype.kind != "f" for a in (mean, var)) or \
                clip.size != 1 or eps.size != 1:
            raise ValueError("not an observation statistics file: mean and var must be vectors of the same size")
        return cls(mean, var, float(clip), float(eps))

    def save(self, path: str | Path) -> Path:
        return storage.write_bytes(path, self.to_bytes())

    @classmethod
    def load(cls, path: str | Path) -> "ObservationNormalizer":
        return cls.from_bytes(_read(Path(path), "observation statistics file"))


def _read(path: Path, what: str, limit: int | None = None) -> bytes:
    """An agent's file, read only if it is a regular file within its size (never a FIFO or a device such as
    ``/dev/zero``, which a shared folder could hold): ``ValueError`` naming it otherwise."""
    return storage.read_limited(path, FILE_LIMIT if limit is None else limit, what=what)


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, tuple):
        return list(v)
    raise TypeError(f"not JSON serialisable: {type(v).__name__}")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _policy_data(policy) -> tuple[bytes, dict, str]:
    """(file bytes, network description, file suffix) of a policy: a CMA-ES network (.npz) or an SB3/sb3-contrib
    policy or model (.safetensors)."""
    from .mlp_policy import MLPPolicy

    if isinstance(policy, MLPPolicy):
        return policy.to_bytes(), {"class": "MLPPolicy", "sizes": list(policy.sizes), "activation": "tanh"}, ".npz"
    from .policy_format import describe_policy, policy_bytes

    policy = getattr(policy, "policy", policy)  # an SB3 model: its policy
    return policy_bytes(policy), describe_policy(policy), ".safetensors"


def save_agent(folder: str | Path, meta: dict, *, policy, normalizer: ObservationNormalizer | None = None,
               sb3_model=None, in_place: bool = False, extra_files: dict[str, bytes] | None = None) -> Path:
    """Save an agent into ``folder``: ``agent.json`` (``meta``, which names the plant, the environment id, the
    algorithm and the environment options; with the network's description and each file's SHA-256), the policy's
    weights (``policy``: an SB3/sb3-contrib policy or model → ``policy.safetensors``; a
    :class:`~controllers.mlp_policy.MLPPolicy` → ``policy.npz``), the observation statistics (``normalization.npz``)
    and, with ``sb3_model``, SB3's ``model.zip`` to resume training (never loaded without trust).

    Atomic: killed at any moment, the folder holds the previous agent or the new one. By default the folder is
    written in full beside ``folder`` and swapped in (its whole content is replaced: ``best/``, checkpoints, an
    exported agent; ``extra_files`` {name: bytes} go with it). ``in_place=True`` (a run folder, which holds the
    training's curves too) writes the agent's files under names carrying their content's digest, then
    ``agent.json`` last, then removes the files of earlier saves. Returns ``folder``."""
    folder = Path(folder)
    meta = {k: v for k, v in meta.items() if k not in ("format", "model", "normalization", "network", "files",
                                                       "resume")}
    missing = [k for k in _REQUIRED[:-1] if k not in meta]
    if missing:
        raise ValueError(f"an agent's metadata needs {missing}")
    meta, bundled = _bundle_files(meta, folder)
    data, network, suffix = _policy_data(policy)

    def name(stem: str, ext: str, content: bytes) -> str:
        return f"{stem}-{_sha256(content)[:12]}{ext}" if in_place else f"{stem}{ext}"

    files = {name("policy", suffix, data): data}
    norm = None
    if normalizer is not None:
        nb = normalizer.to_bytes()
        norm = name("normalization", ".npz", nb)
        files[norm] = nb
    meta = {"format": AGENT_FORMAT, **meta, "model": next(iter(files)), "normalization": norm, "network": network,
            "files": {n: _sha256(d) for n, d in files.items()}}
    if sb3_model is not None:
        meta["resume"] = RESUME_FILE
    text = json.dumps(tag_tuples(meta), indent=2, default=_jsonable)
    if in_place:
        for n, content in bundled.items():  # named by their content: written before the agent.json naming them
            storage.write_bytes(folder / n, content)
        _save_in_place(folder, files, text, sb3_model)
    else:
        _save_swapped(folder, {**(extra_files or {}), **bundled, **files}, text, sb3_model)
    return folder


def _bundle_files(meta: dict, folder: Path) -> tuple[dict, dict[str, bytes]]:
    """``meta`` with every file its ``env_kwargs`` name (a damper preset, a measured road or record) replaced by a
    copy's name inside the agent's folder, and those copies {name: bytes}: an agent is loaded with its files confined
    to its folder (a shared agent reads nothing outside it), so a file it was trained on travels with it, named by
    its content (``data-<digest>-<name>``). A name already inside the folder is kept."""
    from mrd_env.envs.build import map_files
    from mrd_env.resources import file_limit

    bundled: dict[str, bytes] = {}

    def copy(value: str, label: str) -> str:
        path = Path(value)
        if not path.is_absolute() and ".." not in path.parts and (folder / path).is_file():
            return value  # already a file of the folder (an exported agent's copy)
        content = storage.read_limited(path, file_limit(), what=f"agent env_kwargs {label}")
        name = f"data-{_sha256(content)[:12]}-{re.sub(r'[^A-Za-z0-9_.-]+', '_', path.name)[-80:]}"
        bundled[name] = content
        return name

    env_kwargs = meta.get("env_kwargs")
    if not isinstance(env_kwargs, dict):
        return meta, bundled
    return {**meta, "env_kwargs": map_files(env_kwargs, copy, "agent env_kwargs")}, bundled


def _save_in_place(folder: Path, files: dict[str, bytes], text: str, sb3_model) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for f in folder.iterdir():  # temporaries of a save killed before
        if _LEFTOVER.fullmatch(f.name) and f.is_file():
            f.unlink(missing_ok=True)
    if sb3_model is not None:
        with storage.atomic_path(folder / RESUME_FILE) as tmp:
            sb3_model.save(tmp)
    for n, data in files.items():
        storage.write_bytes(folder / n, data)
    storage.write_text(folder / METADATA_FILE, text)  # the new agent exists from here on
    for f in folder.iterdir():  # the files of earlier saves
        if _DIGEST_NAMED.fullmatch(f.name) and f.name not in files and f.is_file():
            f.unlink(missing_ok=True)


def _save_swapped(folder: Path, files: dict[str, bytes], text: str, sb3_model) -> None:
    storage.recover_folder(folder)
    for old in folder.parent.glob(f".{glob.escape(folder.name)}.*.staging"):  # of a save killed before
        shutil.rmtree(old, ignore_errors=True)
    staged = storage.staging_folder(folder)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(staged, 0o777 & ~umask)  # a folder like any other (mkdtemp makes it private)
        for n, data in files.items():
            (staged / n).write_bytes(data)
        if sb3_model is not None:
            sb3_model.save(staged / RESUME_FILE)
        (staged / METADATA_FILE).write_text(text, encoding="utf-8")
        storage.replace_folder(staged, folder)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise


def write_agent(folder: str | Path, meta: dict, normalizer: ObservationNormalizer | None = None) -> Path:
    """Write the metadata (``agent.json``) and the observation statistics (``normalization.npz``) of an agent whose
    model file, named by ``meta["model"]``, is already in ``folder``, with the files' digests (each file atomically;
    :func:`save_agent` saves a whole agent atomically and is what the trainers call)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise ValueError(f"an agent's metadata needs {missing}")
    meta = {"format": AGENT_FORMAT, **meta}
    meta["normalization"] = None
    if normalizer is not None:
        normalizer.save(folder / NORMALIZATION_FILE)
        meta["normalization"] = NORMALIZATION_FILE
    names = [n for n in (meta["model"], meta["normalization"]) if n and n != METADATA_FILE]
    meta["files"] = {n: _sha256(storage.inside(folder, n).read_bytes()) for n in names}
    storage.write_text(folder / METADATA_FILE, json.dumps(tag_tuples(meta), indent=2, default=_jsonable))
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


def _model_kind(meta: dict, where) -> str:
    """How an agent's model file is read: "arrays" (an SB3 policy's safetensors), "mlp" (a CMA-ES network's npz)
    or "sb3-zip" (SB3's pickled zip: trusted only)."""
    suffix = Path(meta["model"]).suffix.lower()
    kinds = {".safetensors": "arrays", ".npz": "mlp", ".zip": "sb3-zip"}
    if suffix not in kinds:
        raise ValueError(f"agent {where}: the model file {meta['model']!r} is none of .safetensors (an SB3 policy's "
                         "weights), .npz (a CMA-ES network) or .zip (SB3's model, trusted only)")
    return kinds[suffix]


def agent_files(path: str | Path) -> tuple[Path, dict]:
    """(folder, metadata) of the agent at ``path`` (its folder, or any file in it); ``ValueError`` for a missing
    or unreadable agent, and for a file name in ``agent.json`` that leaves the folder."""
    path = Path(path)
    if not path.exists():
        storage.recover_folder(path)  # a non-atomic folder swap killed between its two renames
    if not path.exists():
        raise ValueError(f"agent {path}: no such file or folder")
    folder = path if path.is_dir() else path.parent
    meta_path = folder / METADATA_FILE
    if not meta_path.exists():
        raise ValueError(f"agent {path}: no agent.json in {folder} (mrd-env train writes it next to the model)")
    try:
        meta = json.loads(_read(meta_path, f"agent {path}: agent.json", METADATA_LIMIT).decode("utf-8"),
                          object_hook=_untag)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ValueError(f"agent {path}: agent.json is not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != AGENT_FORMAT:
        raise ValueError(f"agent {path}: agent.json is not an mrd-env agent (missing \"format\": \"{AGENT_FORMAT}\")")
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise ValueError(f"agent {path}: agent.json lacks {missing}")
    if not isinstance(meta["env_kwargs"], dict) or not all(isinstance(k, str) for k in meta["env_kwargs"]):
        raise ValueError(f"agent {path}: agent.json's env_kwargs must be an object of options")
    for key in ("algo", "plant", "env_id"):
        if not isinstance(meta[key], str):
            raise ValueError(f"agent {path}: agent.json's {key} must be a string, got {meta[key]!r}")
    files = meta.get("files")
    if files is not None and (not isinstance(files, dict) or not all(
            isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) for v in files.values())):
        raise ValueError(f"agent {path}: agent.json's files must map file names to SHA-256 digests")
    names = [("model", meta["model"])] + [(k, meta[k]) for k in ("normalization", "resume") if meta.get(k)]
    for key, name in names + [("files", n) for n in (files or {})]:
        storage.inside(folder, name, what=f"agent {path}: agent.json's {key} file")
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    if meta["env_id"] not in gym.registry:
        raise ValueError(f"agent {path}: unknown environment {meta['env_id']!r} in agent.json")
    if not (folder / meta["model"]).exists():
        raise ValueError(f"agent {path}: the model file {meta['model']} is missing")
    return folder, meta


def check_env_kwargs(env_id: str, env_kwargs: dict, where) -> None:
    """An agent's environment options, checked by the environment itself before anything runs: ``gym.make``
    (whose constructors validate every option, and refuse a set-up that would not fit in memory) on them, then
    closed; ``ValueError`` naming the agent otherwise."""
    import gymnasium as gym

    import mrd_env  # noqa: F401
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # a former id (a plant's former_ids) of an old agent
            gym.make(env_id, **env_kwargs).close()
    except (TypeError, ValueError, MemoryError) as exc:
        raise ValueError(f"agent {where}: agent.json's env_kwargs are refused by {env_id}: {exc}") from None


#: The algorithms whose SB3 zip a trusted load may read.
SB3_ALGORITHMS = ("PPO", "A2C", "SAC", "TD3", "DDPG", "DQN", "TQC", "RecurrentPPO", "ARS", "TRPO", "QRDQN", "CrossQ",
                  "MaskablePPO")


def algorithm_class(name: str):
    """The Stable-Baselines3 (or sb3-contrib) class of an algorithm's name ("PPO", "RecurrentPPO", ...)."""
    import stable_baselines3 as sb3

    if name not in SB3_ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}; one of {list(SB3_ALGORITHMS)}")
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


def _read_checked(folder: Path, meta: dict, name: str, where) -> bytes:
    """The bytes of the file ``name`` of an agent, after checking them against the digest agent.json records."""
    data = _read(storage.inside(folder, name, what=f"agent {where}: agent.json's file"), f"agent {where}: file")
    files = meta.get("files")
    if files is None:
        if meta.get("network") is not None:
            raise AgentDigestError(f"agent {where}: agent.json records no digests of its files (\"files\"); save the "
                                   "agent again (controllers.agents.export_agent)")
        return data  # an agent saved before digests were recorded
    if name not in files:
        raise AgentDigestError(f"agent {where}: agent.json records no digest for {name}")
    if _sha256(data) != files[name]:
        raise AgentDigestError(f"agent {where}: {name} is not the file agent.json records (its SHA-256 differs: "
                               "a file of another save, or edited); refused")
    return data


def _untrusted(folder, meta: dict) -> UntrustedAgentError:
    return UntrustedAgentError(
        f"agent {folder}: {meta['model']} is a Stable-Baselines3 zip, whose loading runs the Python objects pickled "
        "in it (any code): refused. Load it only if you trust where it comes from (--trust-agent, or "
        "load_agent(path, trust=True)), or ask for the agent in the code-free format (controllers.agents."
        "export_agent converts it once)")


class TrainedAgent:
    """A saved agent: SB3's ``predict`` on raw observations (normalised as in training). ``trust``: see
    :func:`load_agent`."""

    def __init__(self, folder: Path, meta: dict, trust: bool = False, check_env: bool = True):
        self.folder = folder
        self.meta = meta
        self.plant = recorded_plant(meta)
        self.env_id = meta["env_id"]
        from mrd_env.envs.build import confine_files

        # a file an option names (a road's path, a preset-file damper) is one of the agent's own, never elsewhere
        self.env_kwargs = confine_files(meta["env_kwargs"], folder, "agent.json's env_kwargs")
        self.observation_kwargs = {k: v for k, v in self.env_kwargs.items() if k in OBSERVATION_OPTIONS}
        self.name = meta.get("name") or f"{meta['algo']} s{meta.get('seed', 0)}"
        if check_env:
            check_env_kwargs(self.env_id, self.env_kwargs, folder)
        kind = _model_kind(meta, folder)
        if kind == "sb3-zip":
            if not trust:
                raise _untrusted(folder, meta)
            warnings.warn(f"agent {folder}: loading {meta['model']}, a Stable-Baselines3 zip of pickled Python "
                          "objects, because it is trusted: it can run any code", TrustedCodeWarning, stacklevel=3)
            if meta.get("files") is not None and meta["model"] in meta["files"]:
                _read_checked(folder, meta, meta["model"], folder)
            self.model = algorithm_class(meta["algo"]).load(folder / meta["model"], device="cpu")
        else:
            data = _read_checked(folder, meta, meta["model"], folder)
            if kind == "mlp":  # a NumPy policy network (experiments/training/evolution.py)
                from .mlp_policy import MLPPolicy
                try:
                    self.model = MLPPolicy.from_bytes(data)
                except ValueError as exc:
                    raise ValueError(f"agent {folder}: {meta['model']}: {exc}") from None
                sizes = (meta.get("network") or {}).get("sizes")
                if sizes is not None and list(sizes) != list(self.model.sizes):
                    raise ValueError(f"agent {folder}: {meta['model']} holds a network of sizes "
                                     f"{list(self.model.sizes)}, agent.json describes {sizes}")
            else:
                from .policy_format import PolicyModel, load_policy
                try:
                    self.model = PolicyModel(meta["algo"], load_policy(meta.get("network"), data, meta["model"]))
                except ValueError as exc:
                    raise ValueError(f"agent {folder}: {exc}") from None
        norm = meta.get("normalization")
        self.normalizer = None
        if norm:
            try:
                self.normalizer = ObservationNormalizer.from_bytes(_read_checked(folder, meta, norm, folder))
            except AgentDigestError:
                raise
            except ValueError as exc:
                raise ValueError(f"agent {folder}: {norm}: {exc}") from None
        self._state = None

    @property
    def residual(self) -> dict | None:
        """The law this agent corrects ({"law", "scale", ...}), or None."""
        return self.meta.get("residual") or None

    @property
    def observation_shape(self) -> tuple:
        """The shape of one observation the policy takes (a residual agent's: the environment's, then its law's
        command)."""
        if self.normalizer is not None:
            return self.normalizer.shape
        space = getattr(self.model, "observation_space", None)
        if space is not None:
            return tuple(space.shape)
        return (int(self.model.sizes[0]),)

    def normalize(self, obs) -> np.ndarray:
        """The observation as the policy takes it (normalised as in training; float32)."""
        o = np.asarray(obs, dtype=np.float64) if self.normalizer is None else self.normalizer(obs)
        return o.astype(np.float32)

    def reset(self, mask=None) -> None:
        self._state = None

    def _check_observation(self, obs: np.ndarray) -> None:
        want = self.observation_shape
        if obs.shape[obs.ndim - len(want):] == want and obs.ndim in (len(want), len(want) + 1):
            return
        got = obs.shape[-1] if obs.ndim else 0
        if self.residual and obs.ndim in (1, 2) and got < want[-1]:
            raise ValueError(
                f"agent {self.name} is a residual agent over the law {self.residual.get('law')!r}: its policy takes "
                f"the environment's observation followed by the law's command ({want[-1]} values, got {got}) and "
                "returns a correction to that command, not a command. Use it through agent.bind(env), the "
                "controller that computes the law's command and adds the correction: agent.bind(env).predict(obs)")
        raise ValueError(f"agent {self.name}: an observation of shape {obs.shape}; the agent takes {want} (one "
                         f"observation) or (n, {', '.join(map(str, want))}) (a batch): build its environment with "
                         "agent.observation_kwargs")

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        self._check_observation(obs)
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
        if self.residual:  # a residual agent also sees its law's commands
            shape = (shape[0] + int(base.n_dampers),)
        if shape != self.observation_shape:
            raise ValueError(f"agent {self.name}: the environment's observation has shape {shape}, the agent was "
                             f"trained on {self.observation_shape}; build it with agent.observation_kwargs")
        if abs(float(base.control_dt) - float(self.env_kwargs.get("control_dt", 1e-3))) > 1e-12:
            raise ValueError(f"agent {self.name}: the environment steps every {base.control_dt:g} s, the agent was "
                             f"trained at {self.env_kwargs.get('control_dt', 1e-3):g} s")
        return agent_controller(env, self, self.residual, name=self.name, env_kwargs=self.env_kwargs)


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


def loaded_files(meta: dict) -> list[str]:
    """The files of an agent that :func:`load_agent` reads, besides ``agent.json``: its model and its observation
    statistics."""
    return [n for n in (meta["model"], meta.get("normalization")) if n]


def agent_digest(path: str | Path) -> str:
    """A short hash of the agent at ``path``: of exactly the files that loading it reads (its agent.json, model and
    normalisation files). What a cached result computed with the agent is keyed by, so that another agent in a
    folder of the same name (every run's ``best/``, a retrained shipped agent) is never served its result."""
    folder, meta = agent_files(path)
    h = hashlib.sha256()
    h.update(_read(folder / METADATA_FILE, f"agent {path}: agent.json", METADATA_LIMIT))
    for name in loaded_files(meta):
        h.update(_read(storage.inside(folder, name), f"agent {path}: file"))
    return h.hexdigest()[:16]


def load_agent(path: str | Path, trust: bool = False) -> TrainedAgent:
    """The agent saved at ``path`` (its folder, or a file in it). Nothing in the folder runs: the policy is built
    from its description and read from arrays, each file checked against its recorded digest, and the agent's
    environment options are checked by the environment (``gym.make``). An agent that only has SB3's ``model.zip``
    (pickled objects, which can run any code) is refused (:class:`UntrustedAgentError`, a ``ValueError``) unless
    ``trust=True``, which loads it with a :class:`TrustedCodeWarning`."""
    folder, meta = agent_files(path)
    try:
        return TrainedAgent(folder, meta, trust=trust)
    except AgentDigestError:  # read while a save swapped the folder: once more, from the new agent.json
        folder, meta = agent_files(path)
        return TrainedAgent(folder, meta, trust=trust)


def reference_observations(agent: TrainedAgent, n: int, seed: int = 0) -> np.ndarray:
    """``n`` raw observations the agent may meet (around its normalisation's mean, some beyond its clip)."""
    rng = np.random.default_rng(seed)
    shape = agent.observation_shape
    if agent.normalizer is not None:
        return agent.normalizer.mean + np.sqrt(agent.normalizer.var) * rng.normal(0, 3, (n, *shape))
    return rng.normal(0, 1, (n, *shape))


def same_actions(a, b, n: int = 256, steps: int = 3, seed: int = 0) -> bool:
    """Whether two agents (:class:`TrainedAgent`) give the same actions bit for bit on ``n`` observations, over
    ``steps`` successive calls (a recurrent agent's state carried)."""
    obs = reference_observations(a, n, seed)
    a.reset()
    b.reset()
    sa = sb = None
    for k in range(steps):
        start = np.full(n, k == 0)
        xa, sa = a.predict(obs + k, state=sa, episode_start=start if a.meta.get("recurrent") else None)
        xb, sb = b.predict(obs + k, state=sb, episode_start=start if b.meta.get("recurrent") else None)
        if not np.array_equal(np.asarray(xa), np.asarray(xb)):
            return False
    return True


def export_agent(src: str | Path, dst: str | Path, trust: bool = False) -> Path:
    """Convert the agent at ``src`` into the code-free format in ``dst`` (which may be ``src``): the policy as
    arrays with its network's description, the observation statistics, every other file of the folder (learning
    curves: not SB3 zips, not sub-folders), each file's digest in ``agent.json``. An agent that only has SB3's
    ``model.zip`` is read from it, which needs ``trust=True`` (it runs the pickles in it: do it once, where you
    trust the source); the exported agent's actions are checked against the source's, bit for bit, before anything
    is written. Returns ``dst``."""
    folder, meta = agent_files(src)
    agent = TrainedAgent(folder, meta, trust=trust)
    policy = agent.model if not hasattr(agent.model, "policy") else agent.model.policy
    data, network, _ = _policy_data(policy)
    if network["class"] != "MLPPolicy":
        from .policy_format import PolicyModel, load_policy
        rebuilt = TrainedAgent.__new__(TrainedAgent)
        rebuilt.__dict__.update(agent.__dict__, model=PolicyModel(meta["algo"], load_policy(network, data)))
        if not same_actions(agent, rebuilt):
            raise ValueError(f"agent {folder}: the policy rebuilt from its description does not act as the "
                             "original: not exported")
    skip = {METADATA_FILE, meta["model"], meta.get("normalization"), meta.get("resume")}
    extra = {f.name: f.read_bytes() for f in sorted(folder.iterdir())
             if f.is_file() and not f.is_symlink() and f.name not in skip and not f.name.startswith(".")
             and f.suffix.lower() != ".zip" and not _DIGEST_NAMED.fullmatch(f.name)}
    new_meta = dict(meta)
    if _model_kind(meta, folder) == "sb3-zip":
        new_meta["converted_from"] = {"file": meta["model"],
                                      "sha256": _sha256(storage.inside(folder, meta["model"]).read_bytes())}
    return save_agent(dst, new_meta, policy=policy, normalizer=agent.normalizer, extra_files=extra)


def code_free_agent(path: str | Path, folder: str | Path, trust: bool = False) -> Path:
    """An agent folder that loads without running code: ``path`` itself, or for an agent that has only SB3's
    ``model.zip`` and is trusted (``trust=True``, ``--trust-agent``), its code-free copy, exported once into
    ``folder/<name>-<digest>/`` (reused while the source is unchanged), so that the pickles run once, here, and
    never in a sweep's workers. Without trust such an agent is refused (:class:`UntrustedAgentError`)."""
    src, meta = agent_files(path)
    if _model_kind(meta, src) != "sb3-zip":
        return Path(path)
    if not trust:
        raise _untrusted(src, meta)
    dst = Path(folder) / f"{src.resolve().name}-{agent_digest(src)[:12]}"
    if not (dst / METADATA_FILE).exists():
        export_agent(src, dst, trust=True)
    return dst


def recorded_plant(meta: dict) -> str:
    """The name of the plant an agent was trained on, from its metadata, in today's spelling: an agent saved before
    its plant was renamed records the former name, which :func:`mrd_env.plants.plant` maps (after a
    DeprecationWarning); a name no plant has is returned as it is."""
    from mrd_env.plants import plant

    try:
        return plant(meta["plant"]).name
    except ValueError:
        return meta["plant"]


def shipped_agents(plant=None) -> list[Path]:
    """Folders of the agents shipped with the project: all, or those of ``plant`` (its spec or profile, or its
    name), whatever spelling of the plant's name their ``agent.json`` records."""
    name = getattr(plant, "name", plant)
    out = []
    for meta_path in sorted(SHIPPED.glob("*/agent.json")):
        meta = json.loads(meta_path.read_text(encoding="utf-8"), object_hook=_untag)
        if name is None or recorded_plant(meta) == name:
            out.append(meta_path.parent)
    return out
