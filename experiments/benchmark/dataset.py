"""Offline datasets (``mrd-env dataset``): a controller's episodes on a benchmark suite, recorded as Minari datasets.

`Minari <https://minari.farama.org>`_ is Farama's format for offline RL (D4RL's successor): one dataset is a folder
(HDF5 here) of episodes — observations (one more than the actions: the last one included), actions, rewards,
terminations, truncations and infos per step, with each episode's seed — and the Gymnasium ``EnvSpec`` of the
environment they came from, so that ``minari.load_dataset(id).recover_environment()`` rebuilds it.

**One dataset per scenario.** An mrd_env environment takes its road or ground motion as constructor options and no
reset options, and a Minari dataset holds one environment spec: the episodes of one scenario of a suite (its
options, the suite's sensors, its control step) make one dataset, ``mrd-env/<suite id>/<scenario>/<controller>-v0``
(Minari's ``namespace/dataset-vN``; the namespace ``mrd-env/<suite id>`` is the suite, as D4RL's ``D4RL/door`` is the
environment and ``expert-v2`` the policy). A robustness twin (every episode its own draw) would need one dataset per
episode: refused.

**The same episodes as the score.** A controller is built and driven exactly as
:func:`experiments.benchmark.scoring.score` drives it (:func:`~experiments.benchmark.scoring.controller_spec`, the
episode's :func:`~experiments.benchmark.scoring.env_options`, the suite's vector environment reset with the
episode seeds, the actions checked): environment i of that vector environment equals a scalar environment reset with
the same seed, bit for bit (:mod:`mrd_env.envs.vector`), which is what ``recover_environment()`` gives.

**The clairvoyant sequences** (``controller="clairvoyant"``): the suites store the references' returns, not their
commands, so they are solved again here — :func:`mrd_env.optimal.clairvoyant` at the suite's control step on the
episode's reference options (the disk cache is used), then replayed in the suite's environment to record what the
sensors saw. **Non-causal**: the commands were optimised knowing the whole disturbance; the dataset's description and
metadata say so (``mrd_env.causal`` false). A solve takes seconds to minutes an episode: record a few (``episodes``).

Beside Minari's own metadata, the key ``mrd_env`` holds the suite (id, digest), the scenario, the controller's
description (as in a result file), whether it is causal, each episode's seed, return and stored references (R_p,
R_c), and the columns: each sensor's columns of the observation with its unit, and the action's unit. Infos per step: ``t`` (s), ``cost`` and ``cost_terms`` (the constraint costs, s in violation over the
step; the CMDP convention of :mod:`mrd_env.envs.costs`), where the environment reports them.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from mrd_env import storage

#: The dataset metadata's format (the ``mrd_env`` key).
FORMAT = "mrd-env-dataset"
FORMAT_VERSION = 1
#: Where the datasets go unless told otherwise (``results/`` is never committed).
DEFAULT_ROOT = Path("results/datasets")
#: The namespace of every dataset this project records.
NAMESPACE = "mrd-env"
#: The pseudo-controller of the clairvoyant command sequences (non-causal).
CLAIRVOYANT = "clairvoyant"
#: The step infos kept (those the environment reports at its reset and every step).
INFO_KEYS = ("t", "cost", "cost_terms")
#: Minari's storage backend (the ``hdf5`` extra: h5py).
DATA_FORMAT = "hdf5"


@dataclass(frozen=True)
class Planned:
    """One dataset to record: the scenario's index, its seeds, the dataset's id and its environment options."""

    index: int
    seeds: tuple[int, ...]
    dataset_id: str
    options: dict


@dataclass(frozen=True)
class Recorded:
    """A recorded dataset: its id and folder, episodes, steps, size on disk (bytes), build time (s), and the load
    average (1 min) at its start and end."""

    dataset_id: str
    path: Path
    episodes: int
    steps: int
    size: int
    seconds: float
    load: tuple[float, float]

    def line(self) -> str:
        return (f"{self.dataset_id}: {self.episodes} episodes, {self.steps} steps, {self.size / 1e6:.2f} MB, "
                f"{self.seconds:.1f} s (load {self.load[0]:.1f} to {self.load[1]:.1f})")


def slug(text: str) -> str:
    """``text`` as a Minari id part: lower case ASCII letters and digits, runs of anything else as one '-'."""
    out = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
    if not out:
        raise ValueError(f"{text!r} has no letter or digit to name a dataset with")
    return out


def dataset_id(suite, scenario, name: str, version: int = 0) -> str:
    """``mrd-env/<suite id>/<scenario>/<controller>-v<version>`` (see the module docstring)."""
    return f"{NAMESPACE}/{suite.id}/{slug(scenario.name)}/{slug(name)}-v{version}"


@contextlib.contextmanager
def datasets_path(root: str | Path):
    """Minari's datasets folder (``MINARI_DATASETS_PATH``, its only setting for it) set to ``root`` inside the block,
    restored after it."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).resolve())
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = before


def load(dataset_id: str, root: str | Path = DEFAULT_ROOT):
    """``minari.load_dataset(dataset_id)`` from the folder ``root``."""
    import minari

    with datasets_path(root):
        return minari.load_dataset(dataset_id)


def clairvoyant_spec():
    """The clairvoyant command sequences as a :class:`~experiments.benchmark.scoring.ControllerSpec`."""
    from experiments.benchmark.scoring import ControllerSpec

    return ControllerSpec("clairvoyant", CLAIRVOYANT, CLAIRVOYANT,
                          {"name": CLAIRVOYANT, "kind": "clairvoyant", "causal": False,
                           "spec": "mrd_env.optimal.clairvoyant at the suite's control step, re-simulated"})


def resolve_controller(controller, suite, *, name=None, options=None, trust_agent=False, converted=None):
    """The spec of ``controller`` on ``suite`` (a spec: itself), checked (:func:`~experiments.benchmark.scoring.check_controller`):
    ``"clairvoyant"``, one of the suite's shipped rows by its name (``mpc+preview (reward)``:
    :func:`~experiments.benchmark.run.shipped_controllers`), or anything ``mrd-env score`` takes."""
    from controllers import available_controllers

    from experiments.benchmark.run import shipped_controllers
    from experiments.benchmark.scoring import ControllerSpec, check_controller, controller_spec

    if isinstance(controller, ControllerSpec):
        return controller
    if controller == CLAIRVOYANT:
        if options or name not in (None, CLAIRVOYANT):
            raise ValueError("controller clairvoyant takes no options and no other name")
        return clairvoyant_spec()
    rows = {r["name"]: r for r in shipped_controllers(suite)}
    if isinstance(controller, str) and controller in rows and controller not in available_controllers() \
            and not options:
        row = rows[controller]
        controller, options, name = row["controller"], row["options"], name or row["name"]
    spec = controller_spec(controller, name=name, options=options, trust_agent=trust_agent, converted=converted,
                           suite=suite)
    check_controller(spec, suite)
    return spec


def plan(suite, spec, *, root: str | Path = DEFAULT_ROOT, episodes: int | None = None, scenarios=None,
         overwrite: bool = False) -> list[Planned]:
    """The datasets :func:`record` would write, checked before anything runs: ``ValueError`` for an unknown
    scenario, a robustness twin, or a dataset that exists (without ``overwrite``)."""
    from experiments.benchmark.scoring import env_options

    names = [sc.name for sc in suite.scenarios]
    unknown = [s for s in scenarios or () if s not in names]
    if unknown:
        raise ValueError(f"--scenario {unknown[0]!r} is not a scenario of {suite.id} (its scenarios: {names})")
    if episodes is not None and (isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1):
        raise ValueError(f"--episodes must be a whole number >= 1, got {episodes!r}")
    out = []
    for i, sc in enumerate(suite.scenarios):
        if scenarios and sc.name not in scenarios:
            continue
        seeds = tuple(int(s) for s in sc.seeds[:episodes])
        opts = [env_options(suite, sc, s, spec) for s in seeds]
        if any(o != opts[0] for o in opts):
            raise ValueError(f"suite {suite.id}, scenario {sc.name}: every episode has its own environment (a "
                             "robustness twin's draws), and a Minari dataset holds one: record its nominal suite")
        out.append(Planned(i, seeds, dataset_id(suite, sc, spec.name), opts[0]))
    ids = [p.dataset_id for p in out]
    if len(set(ids)) != len(ids):
        raise ValueError(f"two scenarios of {suite.id} give the dataset id {ids[0]}: rename one")
    existing = [p.dataset_id for p in out if (Path(root) / p.dataset_id).exists()]
    if existing and not overwrite:
        raise ValueError(f"dataset {existing[0]} exists in {root} (--overwrite replaces it)")
    return out


def _load1() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def _size(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def run_episodes(suite, spec, planned: Planned) -> tuple[list[dict], object, dict]:
    """The episodes of ``planned`` with ``spec``, in one vector environment of the suite as the score runs them:
    per episode its seed, observations (n + 1), actions (n), rewards, terminations, truncations and infos; the
    scalar environment's spec; and what the columns are (the observation's sensors, the action's unit)."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    from mrd_env.envs.vector import env_info

    from experiments.benchmark.scoring import built_controller, DrivenController, ControllerSignals, action_unit

    options = dict(planned.options)
    seeds = list(planned.seeds)
    commands = _clairvoyant_commands(suite, planned) if spec.kind == "clairvoyant" else None
    venv = gym.make_vec(suite.env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", **options)
    with ControllerSignals() as signals:
        try:
            ctrl = None if commands is not None else \
                DrivenController(built_controller(spec, venv, signals), venv, spec.name, user=spec.kind == "python", signals=signals)
            obs, info = venv.reset(seed=seeds)
            if ctrl is not None:
                ctrl.reset()
            eps = [{"seed": s, "observations": [obs[b]], "actions": [], "rewards": [], "terminations": [],
                    "truncations": [], "infos": [_infos(env_info(info, b))]} for b, s in enumerate(seeds)]
            done = np.zeros(len(seeds), dtype=bool)
            k = 0
            while not done.all():
                if ctrl is not None:
                    action, _ = ctrl.predict(obs, deterministic=True)
                else:  # an episode's commands end with it; an ended one's further actions are not recorded
                    action = np.stack([c[min(k, len(c) - 1)] for c in commands]).astype(venv.single_action_space.dtype)
                obs, r, term, trunc, info = venv.step(action)
                for b in np.flatnonzero(~done):
                    e = eps[b]
                    e["actions"].append(np.array(action[b]))
                    e["rewards"].append(float(r[b]))
                    e["terminations"].append(bool(term[b]))
                    e["truncations"].append(bool(trunc[b]))
                    e["observations"].append(obs[b])
                    e["infos"].append(_infos(env_info(info, b)))
                done |= term | trunc
                k += 1
        finally:
            venv.close()
    env_spec = replace(gym.spec(suite.env_id), kwargs={**gym.spec(suite.env_id).kwargs, **options})
    layout = [{"sensor": n, "columns": [sl.start, sl.stop], "unit": u} for n, sl, u in venv.sensor_layout]
    return eps, env_spec, {"observation": layout, "action": action_unit(venv)}


def _infos(info: dict) -> dict:
    """The kept infos (:data:`INFO_KEYS`) of one step, as plain floats."""
    out = {}
    for k in INFO_KEYS:
        if k in info:
            v = info[k]
            out[k] = {n: float(x) for n, x in v.items()} if isinstance(v, dict) else float(v)
    return out


def _clairvoyant_commands(suite, planned: Planned) -> list[np.ndarray]:
    """Each episode's clairvoyant commands (n_steps, n_dampers), solved at the suite's control step on the
    episode's reference options (:meth:`mrd_env.suites.Suite.reference_options`)."""
    from mrd_env.optimal import clairvoyant

    sc = suite.scenarios[planned.index]
    out = []
    for seed in planned.seeds:
        res = clairvoyant(suite.env_id, seed=seed, control_dt=suite.control_dt, progress=False,
                          **suite.reference_options(sc, seed))
        out.append(np.asarray(res.commands, dtype=np.float64))
    return out


def _stacked(rows):
    """A list of per-step values as arrays: numbers as one array, dicts key by key."""
    if isinstance(rows[0], dict):
        return {k: _stacked([r[k] for r in rows]) for k in rows[0]}
    return np.asarray(rows)


def _buffers(eps: list[dict]):
    from minari.data_collector import EpisodeBuffer

    out = []
    for i, e in enumerate(eps):
        keys = set(e["infos"][0])
        if any(set(x) != keys for x in e["infos"]):
            raise ValueError(f"episode seed {e['seed']}: the environment's infos change keys between steps")
        out.append(EpisodeBuffer(id=i, seed=int(e["seed"]), observations=np.stack(e["observations"]),
                                 actions=np.stack(e["actions"]), rewards=e["rewards"],
                                 terminations=e["terminations"], truncations=e["truncations"],
                                 infos=_stacked(e["infos"])))
    return out


def _metadata(suite, spec, planned: Planned, eps: list[dict], command) -> dict:
    from importlib.metadata import PackageNotFoundError, version

    sc = suite.scenarios[planned.index]
    try:
        ours = version("mrd-env")
    except PackageNotFoundError:
        ours = "unknown"
    episodes = []
    for e in eps:
        ref = suite.references.get(sc.label(e["seed"]))
        episodes.append({"label": sc.label(e["seed"]), "seed": int(e["seed"]), "steps": len(e["actions"]),
                         "return": float(np.sum(e["rewards"])), "terminated": bool(e["terminations"][-1]),
                         "passive": None if ref is None else float(ref.passive),
                         "clairvoyant": None if ref is None else float(ref.clairvoyant)})
    return {"format": FORMAT, "format_version": FORMAT_VERSION, "mrd_env_version": ours,
            "suite": {"id": suite.id, "digest": suite.digest, "env_id": suite.env_id},
            "scenario": sc.name, "control_dt_s": suite.control_dt, "controller": spec.description,
            "causal": spec.kind != "clairvoyant", "episodes": episodes,
            "infos": {"t": "s", "cost": "s in violation over the step (CMDP cost)",
                      "cost_terms": "s in violation over the step, per constraint"},
            "command": list(command or [])}


def _description(suite, spec, planned: Planned) -> str:
    sc = suite.scenarios[planned.index]
    what = ("the clairvoyant command sequences (NON-CAUSAL: optimised knowing the whole disturbance; an oracle, not "
            "a policy)" if spec.kind == "clairvoyant" else f"the controller {spec.name} ({spec.kind})")
    return (f"{what} on the scenario {sc.name} of the mrd-env benchmark suite {suite.id} (digest {suite.digest[:12]}), "
            f"{len(planned.seeds)} episode(s) at the suite's control step {suite.control_dt:g} s. Rewards are the "
            "environment's; info['cost'] is the constraint cost (s in violation over the step).")


def write_namespaces(root: Path, suite, scenario) -> None:
    """Minari's namespace files for ``mrd-env``, the suite and the scenario (written atomically, kept if present)."""
    from minari.namespace import NAMESPACE_METADATA_FILENAME

    described = {NAMESPACE: {"description": "datasets recorded by mrd-env (MR-damper environments)"},
                 f"{NAMESPACE}/{suite.id}": {"description": f"the benchmark suite {suite.id}: {suite.description}",
                                             "digest": suite.digest},
                 f"{NAMESPACE}/{suite.id}/{slug(scenario.name)}": {"description": f"scenario {scenario.name}",
                                                                   "options": scenario.options}}
    for ns, meta in described.items():
        path = root / ns / NAMESPACE_METADATA_FILENAME
        if not path.exists():
            storage.write_json(path, meta)


def record(suite, controller, *, root: str | Path = DEFAULT_ROOT, name: str | None = None, options: dict | None = None,
           episodes: int | None = None, scenarios=None, overwrite: bool = False, trust_agent: bool = False,
           command=None, progress=None) -> list[Recorded]:
    """Record ``controller`` (see :func:`resolve_controller`) on the suite's episodes (the first ``episodes`` of each
    scenario; ``scenarios``: those only) as Minari datasets in ``root``, one per scenario (see the module docstring);
    each written into a staging folder and swapped in whole (:func:`mrd_env.storage.replace_folder`). ``progress``:
    called with each :class:`Recorded`."""
    from minari import create_dataset_from_buffers

    from experiments.benchmark.scoring import one_torch_thread, resolve_suite

    suite = resolve_suite(suite)
    root = Path(root)
    spec = resolve_controller(controller, suite, name=name, options=options, trust_agent=trust_agent,
                              converted=root / "converted-agents")
    planned = plan(suite, spec, root=root, episodes=episodes, scenarios=scenarios, overwrite=overwrite)
    storage.writable_folder(root)
    one_torch_thread(spec)
    done = []
    for p in planned:
        t0, load0 = time.perf_counter(), _load1()
        eps, env_spec, columns = run_episodes(suite, spec, p)
        target = root / p.dataset_id
        staging = storage.staging_folder(target)
        try:
            with datasets_path(staging), warnings.catch_warnings():
                # Minari's advice for datasets published on its hub (a permalink, an e-mail, an evaluation env)
                warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
                ds = create_dataset_from_buffers(p.dataset_id, _buffers(eps), env=env_spec,
                                                 algorithm_name=spec.name, author={"mrd-env"},
                                                 description=_description(suite, spec, p), data_format=DATA_FORMAT,
                                                 requirements=["mrd-env"])
                ds.storage.update_metadata({"mrd_env": {**_metadata(suite, spec, p, eps, command),
                                                        "columns": columns}})
            storage.replace_folder(staging / p.dataset_id, target)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        write_namespaces(root, suite, suite.scenarios[p.index])
        rec = Recorded(p.dataset_id, target, len(eps), sum(len(e["actions"]) for e in eps), _size(target),
                       time.perf_counter() - t0, (load0, _load1()))
        done.append(rec)
        if progress is not None:
            progress(rec)
    return done


def replay(dataset) -> list[dict]:
    """Each episode of ``dataset`` (a loaded Minari dataset) replayed in its recovered environment from its seed:
    per episode the largest differences of the rewards and observations from the recorded ones (0.0: bit for bit)."""
    env = dataset.recover_environment()
    out = []
    try:
        for ep, meta in zip(dataset.iterate_episodes(), dataset.storage.get_episode_metadata(dataset.episode_indices)):
            obs, _ = env.reset(seed=int(meta["seed"]))
            d_obs = float(np.max(np.abs(np.asarray(obs, dtype=np.float64) - ep.observations[0])))
            d_rew = 0.0
            for k, a in enumerate(ep.actions):
                obs, r, term, trunc, _ = env.step(a)
                d_rew = max(d_rew, abs(float(r) - float(ep.rewards[k])))
                d_obs = max(d_obs, float(np.max(np.abs(np.asarray(obs, dtype=np.float64) - ep.observations[k + 1]))))
                if (term, trunc) != (bool(ep.terminations[k]), bool(ep.truncations[k])):
                    d_rew = float("inf")
            out.append({"seed": int(meta["seed"]), "steps": len(ep.actions), "reward": d_rew, "observation": d_obs})
    finally:
        env.close()
    return out


def describe(dataset) -> str:
    """A dataset's metadata (Minari's and ``mrd_env``'s) as JSON text."""
    meta = dict(dataset.storage.metadata)
    return json.dumps(meta, indent=1, sort_keys=True, default=str)
