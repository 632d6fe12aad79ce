"""Scoring a controller on a benchmark suite (``mrd-env score``).

:func:`score` runs every episode of a suite (:mod:`mrd_env.suites`: its scenarios and seeds, its environment options,
its control step) with one controller — a registered law, a saved agent, or any Python object that follows
:class:`controllers.protocol.ControllerProtocol` — and scores each episode against the suite's **stored** references:
the share of the achievable gain (R − R_p) / (R_c − R_p), and the suite's criteria (its episode metrics, and the
constraint cost where the environment reports one). Nothing is solved here: a suite without a reference for one of
its episodes is refused. Per scenario and over all of them: first the **pooled share** Σ (R − R_p) / Σ (R_c − R_p),
each episode weighed by what is at stake on it, with its bootstrap 95 % interval
(:mod:`experiments.benchmark.aggregate`); then the mean share, the return and every criterion, each as its mean and 95 %
interval over the episodes (:func:`~experiments.common.evaluation.mean_ci`; one episode has no interval).

A :class:`SuiteResult` is written as one plain JSON file per controller (:meth:`SuiteResult.write`, atomically): the
format, the suite's name, version and digest, the controller's description (its name, its kind — law, agent or
python — and, for an agent, the digest of its files), every episode's figures (its return, share and references
R_p and R_c among them) and the summary.
:mod:`experiments.benchmark.ranking` reads such files back, as data only, and merges them.

From Python::

    from experiments.benchmark.ranking import leaderboard
    from experiments.benchmark.scoring import score

    score("car-comfort-v1", "skyhook_continuous").write("results/score/skyhook.json")
    score("car-comfort-v1", MyController).write("results/score/mine.json")   # a class taking the env
    score("car-preview-v1", "mpc", options={"weights": "reward", "f_max": 1e5, "force_ref": 200.0, "horizon": 10},
          name="mpc+preview (reward)")                                       # a law with its options
    print(leaderboard(["results/score/skyhook.json", "results/score/mine.json"], out="results/board").markdown())
"""
from __future__ import annotations

import json
import math
import re
import reprlib
import sys
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from mrd_env import storage
from mrd_env.report import csv_text

from experiments.benchmark.aggregate import ALL, paired_comparison, pooled_shares
from experiments.common.evaluation import evaluate_batch, mean_ci
from experiments.common.scenarios import Scenario

#: The result files' format (bumped when their fields change). Version 2 stores each episode's references
#: (``passive`` R_p, ``clairvoyant`` R_c) beside its return and share; version 1 files, without them, are still read.
FORMAT = "mrd-env-score"
FORMAT_VERSION = 2
READ_VERSIONS = (1, 2)
#: What a controller can be: a registered law, a saved agent, Python code (``module:attribute`` or an object).
KINDS = ("law", "agent", "python")
#: Options of an agent's environment that belong to the agent itself (how its action becomes the command): the
#: suite's environment takes the agent's; every other option is the suite's.
AGENT_ACTION_OPTIONS = ("action_mode", "inverse", "force_range")
#: The unit of the constraint costs (:mod:`mrd_env.envs.costs`: time in violation).
COST_UNIT = "s"

_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = _REPR.maxlong = 120


def bounded(value) -> str:
    """``repr(value)`` cut to about 120 characters (and a few items of a container): what an error message quotes
    of a value the user gave, however large it is."""
    return _REPR.repr(value)


# ---------------------------------------------------------------------------------------------- the suite


def resolve_suite(suite) -> Any:
    """A :class:`mrd_env.suites.Suite`: ``suite`` itself, a shipped suite's name (``car-comfort-v1``; a name without
    version: its latest) or a suite file's path, whose environment is one of its plant's; ``ValueError``
    otherwise."""
    from mrd_env import suites

    if isinstance(suite, suites.Suite):
        found = suite
    elif isinstance(suite, Path):
        found = suites.read_suite(suite)
    elif not isinstance(suite, str):
        raise ValueError(f"a suite is a Suite, its name or its file's path, got a {type(suite).__name__}")
    elif not suite.endswith(".json") and Path(suite).is_file():
        found = suites.read_suite(suite)
    else:
        found = suites.suite(suite)  # looked up here, at call time: a shipped suite's name, or a .json file
    check_plant(found)
    return found


def check_plant(suite) -> None:
    """``ValueError`` unless the suite's ``env_id`` is one of its ``plant``'s ids (the plant names the units of its
    criteria and the folder of its shipped files; :mod:`mrd_env.suites` checks each alone, importing no plant)."""
    from mrd_env.plants import plants

    spec = plants().get(suite.plant)
    ids = [*spec.ids, *spec.former_ids] if spec is not None else []
    if suite.env_id not in ids:
        raise ValueError(f"suite {suite.id}: env_id {suite.env_id!r} is not an environment of the plant "
                         f"{suite.plant!r} (its ids: {ids})")


def check_references(suite) -> None:
    """``ValueError`` naming the episodes of ``suite`` that have no stored reference (scoring solves nothing)."""
    missing = [sc.label(seed) for sc, seed in suite.episodes() if sc.label(seed) not in suite.references]
    if missing:
        raise ValueError(f"suite {suite.id} has no reference for the episode(s) {missing}: a score needs every "
                         "episode's stored reference values (nothing is solved when scoring)")


# ---------------------------------------------------------------------------------------------- the controller


@dataclass(frozen=True)
class ControllerSpec:
    """A controller to score: ``kind`` (``law``, ``agent``, ``python``), ``ref`` (the law's name, the agent's folder,
    ``module:attribute``, or the Python object itself), the row's ``name`` and the result file's ``description``."""

    kind: str
    ref: Any
    name: str
    description: dict

    @property
    def picklable(self) -> bool:
        """Whether a worker can rebuild it (a name, a folder, an import spec; not an object of the caller's)."""
        return isinstance(self.ref, (str, Path))


def _source_digest(obj) -> str | None:
    """SHA-256 of the file that defines ``obj`` (its module's), where there is one: which code was scored."""
    import hashlib
    import inspect

    try:
        path = inspect.getsourcefile(obj if inspect.isclass(obj) or inspect.isfunction(obj) else type(obj))
    except TypeError:
        return None
    if not path or not Path(path).is_file():
        return None
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def controller_spec(controller, *, name: str | None = None, options: dict | None = None, trust_agent: bool = False,
                    converted: str | Path | None = None, suite=None) -> ControllerSpec:
    """What ``controller`` is: a registered law's name (``controllers.available_controllers()``; ``options``: its
    options, plain JSON, e.g. an MPC's ``{"weights": "reward", "horizon": 10}``, recorded in the result), an agent
    folder (a path; an agent that only has SB3's pickled ``model.zip`` needs ``trust_agent`` and is converted once
    into ``converted``), a plain Stable-Baselines3 ``model.zip`` (``trust_agent`` too; its environment is ``suite``'s:
    :func:`sb3_zip_agent`), ``package.module:attribute`` (**imported: its code runs**) or a Python object — a class
    or factory taking the environment, or an object with ``predict`` (:mod:`controllers.protocol`). ``ValueError``
    (one line) otherwise."""
    from controllers import available_controllers
    from controllers.protocol import import_object, is_import_spec

    if isinstance(controller, str) and controller in available_controllers():
        desc = {"name": name or controller, "kind": "law", "spec": controller}
        if options:
            desc["options"] = law_options(options, controller)
            desc["name"] = name or f"{controller} {json.dumps(desc['options'], sort_keys=True)}"
        return ControllerSpec("law", controller, desc["name"], desc)
    if options:
        raise ValueError(f"options are a registered law's ({', '.join(available_controllers())}); {bounded(controller)} is "
                         "not one (an agent or Python controller carries its own settings)")
    if isinstance(controller, str) and is_import_spec(controller) and not Path(controller).exists():
        obj = import_object(controller)  # ValueError, one line; runs the user's module (their explicit choice)
        desc = {"name": name or controller, "kind": "python", "spec": controller}
        digest = _source_digest(obj)
        if digest:
            desc["source_sha256"] = digest
        return ControllerSpec("python", controller, name or controller, desc)
    if isinstance(controller, str) and not Path(controller).exists() and shipped_agent(controller) is not None:
        # a shipped agent by its folder's name (``quarter_car_cmaes``), wherever the package is installed
        return _agent_spec(shipped_agent(controller), name or controller, trust_agent, converted)
    if isinstance(controller, (str, Path)):
        path = Path(controller)
        if not path.exists():
            raise ValueError(_not_found(controller, available_controllers()))
        if _plain_sb3_zip(path) is not None:
            return _sb3_zip_spec(_plain_sb3_zip(path), name, trust_agent, converted, suite)
        return _agent_spec(path, name or str(controller), trust_agent, converted)
    from controllers.protocol import ControllerProtocol

    if not callable(controller) and not isinstance(controller, ControllerProtocol):
        raise ValueError(f"a {type(controller).__name__} is not a controller: give a registered law's name, an agent "
                         "folder, package.module:attribute, a class or factory taking the environment, or an object "
                         "with predict")
    label = name or getattr(controller, "name", None)
    if not isinstance(label, str) or not label:
        label = getattr(controller, "__qualname__", None) or type(controller).__qualname__
    desc = {"name": label, "kind": "python", "spec": f"{getattr(controller, '__module__', '?')}:{label}"}
    digest = _source_digest(controller)
    if digest:
        desc["source_sha256"] = digest
    return ControllerSpec("python", controller, label, desc)


#: A dotted name: ``mylaws.MySkyhook`` written for ``mylaws:MySkyhook``.
_DOTTED = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+")


def _not_found(controller, laws: list[str]) -> str:
    """Why ``controller`` (a string or path naming nothing that exists) is no controller, on one line: a path-like
    text is a missing agent folder; ``mylaws.MySkyhook`` whose top-level module exists means ``mylaws:MySkyhook``
    (looked up with ``importlib.util.find_spec`` on the top-level name only, which imports nothing)."""
    import importlib.util
    import os

    text = str(controller)
    quoted = bounded(text)
    if isinstance(controller, Path) or os.sep in text or "/" in text or text.startswith(("~", ".")) or \
            text.endswith((".zip", ".json")):
        return (f"controller {quoted}: no such folder (an agent folder holds the agent.json that mrd-env train "
                "writes; a plain SB3 model.zip is scored with --trust-agent)")
    hint = ""
    if _DOTTED.fullmatch(text):
        module, _, attr = text.rpartition(".")
        top = module.split(".")[0]
        try:
            found = importlib.util.find_spec(top) is not None or Path(f"{top}.py").is_file() or \
                Path(top, "__init__.py").is_file()
        except (ImportError, ValueError):
            found = False
        if found:
            return (f"controller {quoted}: did you mean {module}:{attr}? (package.module:attribute takes a colon "
                    f"before the attribute; {top} is a module here)")
        hint = "; package.module:attribute takes a colon before the attribute"
    else:
        import difflib

        close = difflib.get_close_matches(text, [*laws, *shipped_agent_names()], n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
    return (f"controller {quoted} is none of: a registered law ({', '.join(laws)}), a shipped agent "
            f"({', '.join(shipped_agent_names())}), an agent folder, package.module:attribute{hint}")


def law_options(options, law: str = "the law") -> dict:
    """``options`` as plain JSON (a dict with string keys of numbers, strings, booleans, null, lists and dicts), as the
    result file records them; ``ValueError`` naming ``law`` otherwise."""
    if not isinstance(options, dict) or not all(isinstance(k, str) for k in options):
        raise ValueError(f"options of {law} must be a dict with string keys, got {bounded(options)}")
    try:
        return json.loads(json.dumps(options, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"options of {law} must be plain JSON (numbers, strings, lists, dicts): {exc}") from None


def shipped_agent_names() -> list[str]:
    """The shipped agents' names (their folders under ``controllers/agents/``), as ``--controller`` takes them."""
    from controllers.agents import shipped_agents

    return [f.name for f in shipped_agents()]


def shipped_agent(name: str) -> Path | None:
    """The folder of the shipped agent ``name`` (a folder name of ``controllers/agents/``), or None."""
    from controllers.agents import METADATA_FILE, SHIPPED

    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", name):
        return None
    folder = SHIPPED / name
    return folder if (folder / METADATA_FILE).is_file() else None


def _agent_spec(path: Path, name: str, trust: bool, converted) -> ControllerSpec:
    """An agent folder's spec; ``name``: the row's name, the one the user gave (the shipped agent's folder name, the
    folder as given, or ``name=``), beside the agent's kind and digest."""
    import tempfile

    from controllers.agents import agent_digest, agent_files, code_free_agent, load_agent

    agent_files(path)  # ValueError for a folder that holds no agent
    if converted is None and trust:
        converted = tempfile.mkdtemp(prefix="mrd-env-converted-agents-")
    folder = code_free_agent(path, converted or ".", trust=trust)  # an SB3 zip: refused, or converted once here
    agent = load_agent(folder)
    label = name
    desc = {"name": label, "kind": "agent", "spec": str(path), "agent_digest": agent_digest(folder),
            "algo": agent.meta.get("algo"), "env_id": agent.env_id,
            "action_options": {k: agent.env_kwargs[k] for k in AGENT_ACTION_OPTIONS if k in agent.env_kwargs}}
    return ControllerSpec("agent", str(folder), label, _plain(desc))


def _plain_sb3_zip(path: Path) -> Path | None:
    """The SB3 zip ``path`` names where it is not part of an mrd-env agent: a ``.zip`` file, or a folder holding
    ``model.zip`` but no ``agent.json``; else None."""
    from controllers.agents import METADATA_FILE, RESUME_FILE

    folder = path if path.is_dir() else path.parent
    if (folder / METADATA_FILE).exists():
        return None
    if path.is_dir():
        return path / RESUME_FILE if (path / RESUME_FILE).is_file() else None
    return path if path.suffix.lower() == ".zip" else None


#: The algorithm of an SB3 zip, from its policy's class (and, for the actor-critic policy, the algorithm's own data).
_SB3_POLICY_ALGORITHMS = {"SACPolicy": "SAC", "TD3Policy": "TD3", "TQCPolicy": "TQC",
                          "RecurrentActorCriticPolicy": "RecurrentPPO", "ARSPolicy": "ARS", "ARSLinearPolicy": "ARS"}


def sb3_zip_agent(zip_path: str | Path, suite, folder: str | Path) -> Path:
    """An agent folder (``folder/<zip>-<digest>/``: a copy of the zip and an ``agent.json``) for a plain
    Stable-Baselines3 ``model.zip`` trained on an mrd_env environment, to be scored on ``suite``. SB3's zip holds the
    policy, its algorithm's data and the observation and action spaces, not the environment's id or options: the
    agent's environment is the suite's (its id, sensors and control step), and the zip's spaces are checked against
    it — the observation's shape, and the action space, which says the action mode (``[-1, 1]``: normalised; the
    suite's command range: physical). **Reading the zip unpickles it (runs any code): trusted zips only.**
    ``ValueError`` (one line) for a zip that is not an SB3 model of a known algorithm or does not fit the suite."""
    import hashlib

    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)
    from controllers.agents import METADATA_FILE, OBSERVATION_OPTIONS, RESUME_FILE, SB3_ALGORITHMS, write_agent
    from mrd_env.storage import read_limited

    zip_path = Path(zip_path)
    where = f"controller {bounded(str(zip_path))}"
    raw = read_limited(zip_path, 512 * 1024 ** 2, what=f"{where}: the zip")
    try:
        from stable_baselines3.common.save_util import load_from_zip_file

        data, _, _ = load_from_zip_file(zip_path, device="cpu", print_system_info=False)
    except ImportError:
        raise ImportError(f"{where}: reading an SB3 zip needs stable-baselines3 (pip install 'mrd-env[rl]')") from None
    except Exception as exc:  # noqa: BLE001 — not a zip, not SB3's, a pickle that fails: one line
        raise ValueError(f"{where}: not a Stable-Baselines3 model zip ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict) or "observation_space" not in data or "action_space" not in data:
        raise ValueError(f"{where}: not a Stable-Baselines3 model zip (no observation and action spaces in it)")
    policy = getattr(data.get("policy_class"), "__name__", "")
    algo = _SB3_POLICY_ALGORITHMS.get(policy) or \
        ("PPO" if "clip_range" in data else "TRPO" if "cg_max_steps" in data else "A2C"
         if policy == "ActorCriticPolicy" else None)
    if algo not in SB3_ALGORITHMS:
        raise ValueError(f"{where}: a model of the policy {policy or '?'}, which is none of the algorithms a zip is "
                         f"scored with ({', '.join(SB3_ALGORITHMS)})")
    venv = gym.make_vec(suite.env_id, num_envs=1, vectorization_mode="vector_entry_point",
                        **{**suite.options, "control_dt": suite.control_dt})
    try:
        obs_shape = tuple(venv.single_observation_space.shape)
        space, n_dampers, spec = venv.single_action_space, int(venv.n_dampers), venv.command_spec
        sensors = [n for n, *_ in venv.sensor_layout]
    finally:
        venv.close()
    zobs, zact = data["observation_space"], data["action_space"]
    if tuple(getattr(zobs, "shape", ()) or ()) != obs_shape:
        raise ValueError(f"{where}: trained on observations of shape {tuple(getattr(zobs, 'shape', ()) or ())}; the "
                         f"suite {suite.id} gives {obs_shape} (its sensors {sensors}, in {suite.env_id})")
    if not isinstance(zact, gym.spaces.Box) or tuple(zact.shape) != (n_dampers,):
        raise ValueError(f"{where}: its action space is {zact}; the suite {suite.id} takes one command per damper, "
                         f"shape ({n_dampers},)")
    lo, hi = np.asarray(zact.low, dtype=np.float64), np.asarray(zact.high, dtype=np.float64)
    if np.allclose(lo, -1.0) and np.allclose(hi, 1.0):
        mode = "normalized"
    elif np.allclose(lo, space.low) and np.allclose(hi, space.high):
        mode = "physical"
    else:
        raise ValueError(f"{where}: it acts in [{_span(lo)}, {_span(hi)}]; the suite {suite.id} takes [-1, 1] "
                         f"(action_mode normalized) or its command's range [{spec.v_min:g}, {spec.v_max:g}] {spec.unit} "
                         "(physical)")
    digest = hashlib.sha256(raw).hexdigest()
    stem = zip_path.stem if zip_path.stem != "model" else zip_path.resolve().parent.name or "model"
    dst = Path(folder) / f"{re.sub(r'[^A-Za-z0-9_.-]+', '_', stem)}-{digest[:12]}-{suite.id}"
    if not (dst / METADATA_FILE).exists():
        dst.mkdir(parents=True, exist_ok=True)
        storage.write_bytes(dst / RESUME_FILE, raw)
        env_kwargs = {k: v for k, v in suite.options.items() if k in OBSERVATION_OPTIONS}
        env_kwargs.update(control_dt=suite.control_dt, action_mode=mode)
        write_agent(dst, {"plant": suite.plant, "env_id": suite.env_id, "algo": algo, "name": stem,
                          "env_kwargs": env_kwargs, "model": RESUME_FILE,
                          "converted_from": {"file": str(zip_path), "sha256": digest,
                                             "environment": f"inferred from the suite {suite.id}"}})
    return dst


def _sb3_zip_spec(zip_path: Path, name, trust: bool, converted, suite) -> ControllerSpec:
    """:func:`sb3_zip_agent` of the zip, then the agent's spec (:func:`_agent_spec`: converted once into the code-free
    format, the pickles read here only); the description names the zip."""
    import tempfile
    from dataclasses import replace

    from controllers.agents import agent_files

    where = f"controller {bounded(str(zip_path))}"
    if not trust:
        raise ValueError(f"{where} is a Stable-Baselines3 zip, whose loading runs the Python objects pickled in it "
                         "(any code): refused. Score it only if you trust where it comes from: --trust-agent "
                         "(score(..., trust_agent=True))")
    if suite is None:
        raise ValueError(f"{where}: a plain SB3 zip is scored in a suite's environment, which it is checked against: "
                         "give the suite (controller_spec(..., suite=...))")
    if converted is None:
        converted = tempfile.mkdtemp(prefix="mrd-env-converted-agents-")
    folder = sb3_zip_agent(zip_path, suite, converted)
    spec = _agent_spec(folder, name or str(zip_path), True, converted)
    desc = {**spec.description, "spec": str(zip_path), "sb3_zip_sha256": agent_files(folder)[1]["converted_from"]["sha256"]}
    return replace(spec, description=desc)


def _plain(v):
    """``v`` with tuples as lists (JSON), recursively."""
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def env_options(suite, scenario, seed: int, spec: ControllerSpec) -> dict:
    """The environment options of the episode (``scenario``, ``seed``) for ``spec``: the suite's, the scenario's and,
    for a robustness twin, the episode's stored draw (``Suite.episode_options``), at the suite's control step; an
    agent keeps its own action options (:data:`AGENT_ACTION_OPTIONS`: how its action becomes the command), every
    other option is the suite's."""
    episode = getattr(suite, "episode_options", None)
    options = dict(episode(scenario, seed)) if episode is not None else {**suite.options, **scenario.options}
    options["control_dt"] = suite.control_dt
    if spec.kind == "agent":
        options.update(spec.description.get("action_options", {}))
    return options


def _build(spec: ControllerSpec, venv):
    """The controller of ``spec`` on ``venv`` (a vector environment of the suite), built — whatever its kind — on
    the environment's declarations only (:func:`controllers.protocol.declarations`: it cannot step, reset or read
    the state or the disturbance of the environment it drives)."""
    from controllers import load_agent, make_controller
    from controllers.protocol import build_controller, declarations, import_object

    view = declarations(venv)
    if spec.kind == "law":
        return make_controller(spec.ref, view, **spec.description.get("options", {}))
    if spec.kind == "agent":
        return load_agent(spec.ref).bind(view)
    obj = import_object(spec.ref) if isinstance(spec.ref, str) else spec.ref
    return build_controller(obj, view, what=f"controller {spec.name}")


def _check_agent(spec: ControllerSpec, suite, venv) -> None:
    """An agent scored on a suite sees the suite's sensors at the suite's control step, in the suite's environment:
    ``ValueError`` where it was trained on another environment, other sensors or another preview."""
    from controllers import load_agent

    agent = load_agent(spec.ref)
    if agent.env_id != suite.env_id:
        raise ValueError(f"agent {spec.name}: trained on {agent.env_id}, the suite {suite.id} runs {suite.env_id}")
    kw = agent.observation_kwargs
    base = getattr(venv, "unwrapped", venv)
    if "sensors" in kw:
        have = [n for n, *_ in base.sensor_layout]
        if list(kw["sensors"]) != have:
            raise ValueError(f"agent {spec.name}: trained on the sensors {bounded(list(kw['sensors']))}, the suite {suite.id} "
                             f"measures {have}")
    if "preview" in kw and tuple(float(x) for x in kw["preview"]) != tuple(getattr(base, "preview_times", ())):
        raise ValueError(f"agent {spec.name}: trained with road preview {bounded(list(kw['preview']))} s, the suite "
                         f"{suite.id} gives {list(getattr(base, 'preview_times', ()))}")


def check_controller(spec: ControllerSpec, suite) -> None:
    """Build ``spec`` on a one-episode vector environment of each of the suite's scenarios, before any episode runs:
    a law that misses a sensor, an agent trained on other observations, a user's factory that raises — each is a
    one-line ``ValueError`` naming the controller."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    for sc in suite.scenarios:
        venv = gym.make_vec(suite.env_id, num_envs=1, vectorization_mode="vector_entry_point",
                            **env_options(suite, sc, sc.seeds[0], spec))
        try:
            if spec.kind == "agent":
                _check_agent(spec, suite, venv)
            try:
                with ControllerSignals() as signals:
                    built_controller(spec, venv, signals)
            except TypeError as exc:
                if spec.kind != "law":
                    raise
                raise ValueError(f"controller {spec.name}: options {bounded(spec.description.get('options', {}))} of "
                                 f"{spec.ref}: {exc}") from None
            except ValueError as exc:
                text = str(exc)
                raise ValueError(text if text.startswith(("controller ", "agent ")) else
                                 f"controller {spec.name}: {text}") from None
        finally:
            venv.close()


class ControllerSignals:
    """Whether SIGINT or SIGTERM arrived while the controllers ran (a context; main thread only): a
    ``KeyboardInterrupt`` or ``SystemExit`` is a stop only when one did; else the controller's code raised it.
    Python-level handlers (Python's Ctrl-C handler, ``mrd-env``'s SIGTERM) are wrapped to note the signal before
    they run; an ignored or default disposition is left alone — then the signal raises nothing in Python (it is
    ignored, or ends the process), so neither exception can come from it; nor can one outside the main thread,
    where no handler runs."""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self):
        self.seen = False
        self._previous: dict = {}

    def __enter__(self):
        import signal
        import threading

        if threading.current_thread() is not threading.main_thread():
            return self
        for name in self.SIGNALS:
            sig = getattr(signal, name, None)
            previous = None if sig is None else signal.getsignal(sig)
            if callable(previous):
                signal.signal(sig, self._noting(previous))
                self._previous[sig] = previous
        return self

    def _noting(self, previous):
        def handler(signum, frame):
            self.seen = True
            return previous(signum, frame)
        return handler

    def __exit__(self, *exc) -> None:
        import signal

        for sig, previous in self._previous.items():
            signal.signal(sig, previous)
        self._previous.clear()


def _exited(name: str, what: str, exc: BaseException, signals: ControllerSignals | None) -> None:
    """Re-raise ``exc`` (a ``SystemExit`` or ``KeyboardInterrupt``) where a signal raised it (a stop); else it is the
    controller's own exit: ``ValueError`` naming it."""
    if signals is None or signals.seen:
        raise exc
    raised = f"SystemExit({bounded(exc.code)})" if isinstance(exc, SystemExit) else type(exc).__name__
    raise ValueError(f"controller {name}: {what} raised {raised} (a controller returns, it does not exit the "
                     "scorer)") from None


def built_controller(spec: ControllerSpec, venv, signals: ControllerSignals | None):
    """:func:`_build`, with a ``sys.exit()`` or ``KeyboardInterrupt`` of the controller's construction its error."""
    try:
        ctrl = _build(spec, venv)
    except (SystemExit, KeyboardInterrupt) as exc:
        _exited(spec.name, "building it", exc, signals)
    if _torch_pending and "torch" in sys.modules:  # the user's code imported torch: one thread (one_torch_thread)
        _one_thread()
    return ctrl


class DrivenController:
    """A controller as :func:`~experiments.common.evaluation.evaluate_batch` drives it, holding the protocol: the
    state handed back, ``episode_start`` at the first step, ``reset`` only where the controller has one, and every
    action checked (shape, finite) with a one-line error naming the controller. ``user``: the controller is the
    user's code, whose exceptions are reported as theirs (a one-line ``ValueError``), not as the project's bugs.
    A ``SystemExit`` or ``KeyboardInterrupt`` its code raises (``sys.exit()`` in ``predict``) is its error too,
    whatever its kind — not the scorer's exit; one raised by a signal (``signals``: :class:`ControllerSignals`) stops the
    scoring."""

    def __init__(self, ctrl, venv, name: str, user: bool = False, signals: ControllerSignals | None = None):
        self.ctrl, self.name, self.user = ctrl, name, user
        self.signals = signals
        self.space = venv.single_action_space
        self.n = int(venv.num_envs)
        self._state, self._start = None, True
        self.low = np.asarray(self.space.low, dtype=np.float64)
        self.high = np.asarray(self.space.high, dtype=np.float64)
        # float32 bounds and a law's own arithmetic (v_max · 1.0, a mapped −1) may land a hair outside: not an error
        self.tol = ACTION_TOLERANCE * np.maximum(self.high - self.low, np.finfo(np.float32).tiny)
        self.unit = action_unit(venv)

    def _call(self, what: str, fn, *args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (SystemExit, KeyboardInterrupt) as exc:  # Ctrl-C or SIGTERM stop the scoring; else its error
            _exited(self.name, what, exc, self.signals)
        except ValueError as exc:
            if not self.user:
                raise
            raise ValueError(f"controller {self.name}: {what}: {exc}") from exc
        except Exception as exc:  # the user's code: its error, on one line
            if not self.user:
                raise
            raise ValueError(f"controller {self.name}: {what} raised {type(exc).__name__}: {exc}") from exc

    def reset(self, mask=None) -> None:
        self._state, self._start = None, True
        reset = getattr(self.ctrl, "reset", None)
        if callable(reset):
            self._call("reset()", reset)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        start = np.full(self.n, self._start)
        self._start = False
        out = self._call("predict", self.ctrl.predict, observation, state=self._state, episode_start=start,
                         deterministic=True)
        if not isinstance(out, tuple) or len(out) != 2:
            raise ValueError(f"controller {self.name}: predict must return (action, state), got a "
                             f"{type(out).__name__}")
        action, self._state = out
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"controller {self.name}: predict returned a {type(action).__name__}, not an array "
                             "of numbers") from None
        want = (self.n, *self.space.shape)
        if a.shape != want and not (a.shape == (self.n,) and self.space.shape == (1,)):
            raise ValueError(f"controller {self.name}: predict returned an action of shape {a.shape}; the suite's "
                             f"environment takes {want} (one row per episode, one command per damper)")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"controller {self.name}: predict returned a non-finite action")
        a = a.reshape(want)
        if np.any(a < self.low - self.tol) or np.any(a > self.high + self.tol):
            # clipped silently, forces in N or [−1, 1] on a 0–2 V suite scored as a (bad) command: refused instead
            raise ValueError(f"controller {self.name}: predict returned actions from {a.min():.6g} to {a.max():.6g}; "
                             f"the suite's environment takes {_span(self.low)} to {_span(self.high)} {self.unit} "
                             "(env.single_action_space): scale the actions into it (nothing is clipped for you)")
        return a.astype(self.space.dtype), self._state


#: How far beyond the action space (a fraction of its range) an action may be and still count as inside it (the
#: environment clips it): float32 bounds and rounding, never a unit mistake.
ACTION_TOLERANCE = 1e-6


def _span(bound: np.ndarray) -> str:
    """An action bound as a number when it is the same for every damper, else the list."""
    flat = np.unique(bound)
    return f"{flat[0]:.6g}" if flat.size == 1 else "[" + ", ".join(f"{b:.6g}" for b in bound.ravel()) + "]"


def action_unit(env) -> str:
    """What the actions of ``env`` are: the command's unit (V or A) in the physical mode, ``N`` (desired force) in the
    force mode, ``(normalised: −1 is v_min, +1 v_max)`` in the normalised one."""
    mode = getattr(env, "action_mode", "physical")
    if mode == "normalized":
        return "(normalised: -1 is the command's v_min, +1 its v_max)"
    if mode == "force":
        return "N (desired damper force)"
    spec = getattr(env, "command_spec", None)
    return f"{getattr(spec, 'unit', '')} (the damper's command)".strip()


def one_torch_thread(spec: ControllerSpec) -> None:
    """torch on one thread, where ``spec`` may run a torch network (an agent's SB3 policy, a user's code) and torch is
    installed. torch's default takes every core, and an SB3 policy evaluated every step then contends with the
    environments and the other workers: the PPO residual agent scored 10× slower on all of car-comfort-v1 on 2 loaded
    cores (27 s and 15 s against 2.8 s and 1.8 s, measured). Called only in processes the project owns — the
    executor's workers and the ``mrd-env`` commands —, never in a caller's Python process (a process-wide setting).
    A user's code that has not imported torch yet is not made to (importing torch costs 2–3 s per process, and a
    pool's every worker paid it for plain NumPy controllers): its build (:func:`built_controller`) sets torch to one
    thread if the code imported it by then."""
    import importlib.util

    global _torch_pending
    if spec.kind == "agent" and importlib.util.find_spec("torch") is not None:
        _one_thread()
    elif spec.kind == "python":
        if "torch" in sys.modules:
            _one_thread()
        else:
            _torch_pending = True


#: A user's controller is to get torch on one thread once its code imports torch (:func:`one_torch_thread`).
_torch_pending = False


def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


def scenario_episodes(suite, index: int, seeds: tuple[int, ...], spec: ControllerSpec,
                      caller: int | None = None) -> list[dict]:
    """The figures of the episodes ``seeds`` of the suite's scenario ``index`` with ``spec`` (a plain function of
    picklable inputs, for :mod:`mrd_env.executor`): per episode its label, scenario, seed, return, share of the
    achievable gain, criteria and termination. Episodes with the same options run in one vector environment (a
    nominal scenario: all its seeds; a robustness twin's episodes each have their own draw). ``caller``: the process
    id of :func:`score`'s caller; in another process (a worker of the executor) torch runs on one thread
    (:func:`one_torch_thread`)."""
    import os

    import mrd_env  # noqa: F401  (registers the environments, also in a fresh worker)

    if caller is not None and os.getpid() != caller:
        one_torch_thread(spec)

    sc = suite.scenarios[index]
    groups: dict[str, tuple[dict, list[int]]] = {}
    for seed in seeds:
        options = env_options(suite, sc, seed, spec)
        key = json.dumps(options, sort_keys=True, default=repr)
        groups.setdefault(key, (options, []))[1].append(int(seed))
    ran = {}
    with ControllerSignals() as signals:
        for options, group in groups.values():
            options = dict(options)
            control_dt = options.pop("control_dt")
            eps = evaluate_batch(lambda venv: DrivenController(built_controller(spec, venv, signals), venv, spec.name,
                                                      user=spec.kind == "python", signals=signals),
                                 Scenario(sc.name, suite.env_id, options, tuple(group)), "", name=spec.name,
                                 control_dt=control_dt)
            ran.update(zip(group, eps))
    eps = [ran[int(seed)] for seed in seeds]
    out = []
    for e, seed in zip(eps, seeds):
        label = sc.label(seed)
        ret = float(e.episode_return)
        crit = {}
        for k in suite.criteria:
            if k not in e.metrics and "terminated" not in e.metrics:
                raise ValueError(f"suite {suite.id}: its criterion {k!r} is not an episode metric of {suite.env_id} "
                                 f"({sorted(e.metrics)})")
            crit[k] = _number(e.metrics.get(k))
        for k in sorted(e.metrics):  # the constraint costs, where the environment reports them
            if (k == "cost" or k.startswith("cost_")) and k not in crit:
                crit[k] = _number(e.metrics[k])
        ref = suite.reference(label)
        out.append({"label": label, "scenario": sc.name, "seed": int(seed), "return": ret, "share": ref.share(ret),
                    "passive": ref.passive, "clairvoyant": ref.clairvoyant, "criteria": crit,
                    "terminated": e.metrics.get("terminated")})
    return out


def _number(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


# ---------------------------------------------------------------------------------------------- the result


def summary_rows(episodes: list[dict], criteria: list[str]) -> list[dict]:
    """Per scenario (in the order of ``episodes``) and over all of them (``all scenarios``): the episodes; the pooled
    share and its bootstrap 95 % interval (:func:`~experiments.benchmark.aggregate.pooled_shares`; NaN for episodes
    that hold no references, a version-1 result read alone); the share of the achievable gain (``share``: the mean of
    the episodes' shares), the return and every criterion, each as its mean and 95 % interval over the episodes (no
    interval for one episode); and how many episodes ended early (``terminated``)."""
    scen = list(dict.fromkeys(e["scenario"] for e in episodes))
    pooled = pooled_shares(episodes)
    rows = []
    for s in scen + [ALL]:
        mine = [e for e in episodes if s == ALL or e["scenario"] == s]
        row = {"scenario": s, "episodes": len(mine)}
        p = pooled[s]
        row.update({"pooled share": p.value, "pooled share lo95": p.lo, "pooled share hi95": p.hi})
        for key, values, upper in [("share", [e["share"] for e in mine], math.inf),
                                   ("return", [e["return"] for e in mine], 0.0),
                                   *((k, [e["criteria"].get(k) for e in mine], math.inf) for k in criteria)]:
            m, lo, hi = mean_ci([_number(v) for v in values], upper=upper)
            row.update({key: m, f"{key} lo95": lo, f"{key} hi95": hi})
        row["terminated"] = sum(1 for e in mine if e.get("terminated"))
        rows.append(row)
    return rows


def _units(suite_plant: str) -> dict:
    from experiments.common.plants import profile

    try:
        return dict(profile(suite_plant).metric_units)
    except ValueError:
        return {}


@dataclass
class SuiteResult:
    """One controller's score on one suite (see the module docstring); :meth:`write` saves it, :func:`read_result`
    reads it back."""

    suite: dict                 #: id, name, version, digest, plant, env_id, control_dt, episodes (the suite's count)
    controller: dict            #: name, kind (law, agent, python), spec, and an agent's digest
    episodes: list[dict]        #: per episode: label, scenario, seed, return, share, criteria, terminated
    criteria: list[str]         #: the criteria's names (the suite's, then the costs the environment reported)
    units: dict = field(default_factory=dict)   #: criterion → unit
    created: str = ""
    mrd_env_version: str = ""
    command: list | None = None

    @property
    def name(self) -> str:
        return self.controller["name"]

    @property
    def complete(self) -> bool:
        """Whether every episode of the suite was scored."""
        return len(self.episodes) == int(self.suite["episodes"])

    def summary(self) -> list[dict]:
        """:func:`summary_rows` of this result's episodes."""
        return summary_rows(self.episodes, self.criteria)

    def shares(self) -> dict[str, tuple[float, float, float]]:
        """{scenario (and ``all scenarios``): (mean share, lower, upper 95 % bound)}."""
        return {r["scenario"]: (r["share"], r["share lo95"], r["share hi95"]) for r in self.summary()}

    def pooled_shares(self) -> dict[str, tuple[float, float, float]]:
        """{scenario (and ``all scenarios``): (pooled share, lower, upper 95 % bound)}: the primary figure."""
        return {s: (p.value, p.lo, p.hi) for s, p in pooled_shares(self.episodes).items()}

    def paired_markdown(self, reference: "SuiteResult", suite=None) -> str:
        """This result against ``reference`` (another controller's result on the same suite) on the same episodes, per
        scenario and over all: the difference of their pooled shares with its paired bootstrap 95 % interval, the
        episodes this one wins, and the verdict (:func:`~experiments.benchmark.aggregate.paired_comparison`; the
        references are ``suite``'s where given). A Markdown table."""
        from mrd_env.report import markdown_table

        rows = [{"scenario": r["scenario"], "episodes": r["episodes"],
                 "pooled share difference": interval_cell(r["difference"], r["lo95"], r["hi95"]),
                 "episodes won": f"{r['won']}/{r['episodes']}", "verdict": r["verdict"]}
                for r in paired_comparison(self, reference, suite)]
        return markdown_table(rows, title=f"{self.name} against {reference.name} on {self.suite['id']}: "
                                          f"{PAIRED_HEADING}")

    def table_rows(self, text: bool = False) -> list[dict]:
        """The summary with the criteria's units in the headers; ``text``: each quantity in one cell, its mean and
        [95 % interval] (the Markdown table), else three numeric columns (the CSV)."""
        def header(k: str) -> str:
            base = k.rsplit(" ", 1)[0] if k.endswith(("lo95", "hi95")) else k
            return f"{k} ({self.units[base]})" if base in self.units else k

        rows = self.summary()
        if not text:
            return [{header(k): v for k, v in r.items()} for r in rows]
        out = []
        for r in rows:
            row = {"scenario": r["scenario"], "episodes": r["episodes"]}
            for k in ("pooled share", "share", "return", *self.criteria):
                row[MEAN_SHARE if k == "share" else header(k)] = interval_cell(
                    r[k], r[f"{k} lo95"], r[f"{k} hi95"], ".3f" if k.endswith("share") else ".4g")
            row["terminated"] = r["terminated"]
            out.append(row)
        return out

    def title(self) -> str:
        partial = "" if self.complete else f"; partial: {len(self.episodes)} of {self.suite['episodes']} episodes"
        return (f"{self.name} on {self.suite['id']}: pooled share of the achievable gain Σ(R − R_p) / Σ(R_c − R_p) "
                "[bootstrap 95 % interval]; mean share (R − R_p) / (R_c − R_p), return and criteria (mean [95 % "
                f"interval over episodes]{partial})")

    def markdown(self) -> str:
        from mrd_env.report import markdown_table

        return markdown_table(self.table_rows(text=True), title=self.title())

    def to_json(self) -> dict:
        return _nulls({"format": FORMAT, "format_version": FORMAT_VERSION, "suite": self.suite,
                       "controller": self.controller, "criteria": list(self.criteria), "units": self.units,
                       "complete": self.complete, "episodes": self.episodes, "summary": self.summary(),
                       "created": self.created, "mrd_env_version": self.mrd_env_version, "command": self.command})

    def write(self, path: str | Path) -> Path:
        """Write the result to ``path`` (plain JSON, atomically: the file is the previous one or this one)."""
        return storage.write_json(path, self.to_json(), indent=1, allow_nan=False)

    def write_tables(self, stem: str | Path) -> tuple[Path, Path]:
        """The summary as ``<stem>.md`` (mean [interval] per cell) and ``<stem>.csv`` (numbers), together."""
        stem = Path(stem)
        md, csv_path = stem.with_suffix(".md"), stem.with_suffix(".csv")
        storage.write_texts({md: self.markdown(), csv_path: csv_text(self.table_rows())})
        return md, csv_path


def _nulls(v):
    """NaN → None, tuples → lists, NumPy scalars → Python numbers (strict JSON)."""
    if isinstance(v, dict):
        return {k: _nulls(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_nulls(x) for x in v]
    if isinstance(v, (np.floating, np.integer)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def score(suite, controller, *, name: str | None = None, options: dict | None = None, episodes: int | None = None,
          backend: str = "auto", jobs: int | None = None, address: str | None = None, trust_agent: bool = False,
          converted: str | Path | None = None, progress: bool = False, command: list | None = None) -> SuiteResult:
    """Score ``controller`` on ``suite`` (see the module docstring).

    ``suite``: a :class:`~mrd_env.suites.Suite`, a shipped suite's name or a suite file. ``controller``: a registered
    law's name, an agent folder, ``package.module:attribute`` (imported: its code runs), or a class, factory or object
    (:mod:`controllers.protocol`). ``name``: the row's name (default: the law's, ``agent <name>``, the import spec or
    the object's ``name``/class name). ``options``: a registered law's options (plain JSON: an MPC's settings, say;
    recorded in the result). ``episodes``: only the first ``episodes`` seeds of each scenario (a smoke run; the result
    says it is partial). ``backend``/``jobs``/``address``: one task per scenario on
    :mod:`mrd_env.executor` (a Python object of the caller's runs in this process); ``"auto"`` (the default) runs
    in this process unless the first scenario's time says the rest is worth a process pool (:func:`_auto`,
    :data:`POOL_MIN_SECONDS`); ``"pool"`` from a script needs its calls under ``if __name__ == "__main__":``
    (:class:`mrd_env.executor.UnguardedMain` otherwise). ``trust_agent``: also load an
    agent that only has SB3's pickled ``model.zip`` (converted once into ``converted``)."""
    import os

    import mrd_env
    from mrd_env.executor import Task, TaskFailed, WorkerDied, resolve_backend, run_tasks

    suite = resolve_suite(suite)
    check_references(suite)
    if episodes is not None and (isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1):
        raise ValueError(f"episodes must be a whole number >= 1 (per scenario), got {bounded(episodes)}")
    spec = controller if isinstance(controller, ControllerSpec) else \
        controller_spec(controller, name=name, options=options, trust_agent=trust_agent, converted=converted,
                        suite=suite)
    check_controller(spec, suite)
    tasks = [Task(scenario_episodes, (suite, i, sc.seeds[:episodes]), {"spec": spec, "caller": os.getpid()},
                  label=f"{spec.name} / {sc.name}") for i, sc in enumerate(suite.scenarios)]
    if not spec.picklable:
        backend = "serial"  # the caller's own object stays in the caller's process
    resolve_backend(backend, len(tasks), jobs)  # a wrong backend or jobs: refused before any episode runs
    desc = f"score {spec.name}"
    try:
        if backend == "auto":
            per_scenario = _auto(tasks, [len(sc.seeds[:episodes]) for sc in suite.scenarios], jobs, progress, desc)
        else:
            per_scenario = run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress,
                                     desc=desc, retry=False)
    except TaskFailed as exc:
        if isinstance(exc.error, ValueError):
            raise ValueError(str(exc.error)) from exc.error
        if isinstance(exc.error, WorkerDied) and spec.kind == "python":  # os._exit() in the user's code
            raise ValueError(f"controller {spec.name}: {exc.task.label}: {exc.error}") from None
        raise
    eps = [e for group in per_scenario for e in group]
    criteria = list(dict.fromkeys(k for e in eps for k in e["criteria"]))
    units = {k: u for k, u in _units(suite.plant).items() if k in criteria}
    units.update({k: COST_UNIT for k in criteria if k == "cost" or k.startswith("cost_")})
    return SuiteResult(
        suite={"id": suite.id, "name": suite.name, "version": suite.version, "digest": suite.digest,
               "plant": suite.plant, "env_id": suite.env_id, "control_dt": suite.control_dt,
               "episodes": len(suite.episodes())},
        controller=spec.description, episodes=_nulls(eps), criteria=criteria, units=units,
        created=datetime.now(timezone.utc).isoformat(timespec="seconds"), mrd_env_version=mrd_env.__version__,
        command=None if command is None else [str(a) for a in command])


#: The estimated in-process seconds of a score's remaining scenarios above which ``backend="auto"`` runs them on the
#: process pool: each spawned worker imports the project and loads its kernels first (4.5-7.5 s on 2 cores at load 3,
#: 10-30 s at load 6-9), which a score of a law's few dozen episodes never earns back — ``mrd-env score`` on
#: car-comfort-v1 and building-seismic-v1 took 2.4-3.3x longer on the pool than in process
#: (experiments/measurements/speed/score_backends.py; docs/your-controller.md). Two workers repay the start-up once they
#: share more than twice its time.
POOL_MIN_SECONDS = 30.0


def _auto(tasks: list, episodes: list[int], jobs: int | None, progress: bool, desc: str) -> list:
    """``backend="auto"``: the first scenario in this process, timed; the others on the process pool only where their
    estimated time in process (the first's per episode, times their episodes) exceeds :data:`POOL_MIN_SECONDS` and
    there are at least two workers for them — else in this process too."""
    import time

    from mrd_env.executor import default_jobs, pool_refusal, run_tasks

    t0 = time.perf_counter()
    out = run_tasks(tasks[:1], backend="serial", progress=progress, desc=desc, retry=False)
    rest = tasks[1:]
    if not rest:
        return out
    estimate = (time.perf_counter() - t0) / max(episodes[0], 1) * sum(episodes[1:])
    workers = min(jobs or default_jobs(), len(rest))
    pool = workers > 1 and estimate > POOL_MIN_SECONDS and pool_refusal() is None
    return out + run_tasks(rest, backend="pool" if pool else "serial", jobs=jobs, progress=progress, desc=desc,
                           retry=False)


#: The text tables' header of the mean of the episodes' shares (the summary's ``share``), beside the pooled share.
MEAN_SHARE = "mean share"
#: What a paired comparison's table shows.
PAIRED_HEADING = ("difference of the pooled shares on the same episodes, Σ(R_a − R_b) / Σ(R_c − R_p) [paired bootstrap "
                  "95 % interval]; episodes won: those where R_a is above R_b; ahead or behind where the interval excludes 0, "
                  "else a tie")


def interval_cell(m: float, lo: float, hi: float, fmt: str = ".3f") -> str:
    """``mean [lo, hi]``, or the mean alone where there is no interval (one episode); ``n/a`` for no number."""
    if not math.isfinite(m):
        return "n/a"
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{m:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]"
    return f"{m:{fmt}}"



def result_filename(suite_id: str, controller: str) -> str:
    """``<suite id>__<controller as a file name>.json``."""
    slug = re.sub(r"[^A-Za-z0-9]+", "_", controller).strip("_").lower() or "controller"
    return f"{suite_id}__{slug}.json"
