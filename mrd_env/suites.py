"""Benchmark suites: frozen, versioned lists of test episodes with their reference values, shipped in the plants'
folders (``mrd_env/plants/<plant>/suites/<name>-v<version>.json``).

A suite fixes everything a score depends on: the plant and its environment options (damper, sensors — who has
road preview —, control step), the scenarios and their seeds, the criteria, and the **reference values of every
episode** — the best constant command R_p, the clairvoyant return R_c (the full-knowledge optimum found by a fixed,
documented procedure whose warm starts do not depend on what agents happen to be shipped) and the active bound
R_b — with the command that reproduces them. A controller's share of the achievable gain on an episode is
(R − R_p) / (R_c − R_p), scored against these stored values without solving anything.

A suite file is plain JSON: its ``digest`` is the SHA-256 of its canonical content, checked on load, so that an
edited or damaged file is refused; references recomputed by another procedure make a new ``version``. A result
file names the suite, its version and its digest, so that results of different suites are never merged.

A suite file may come from another lab (``mrd-env score --suite their-suite.json``), so reading one runs no code and
trusts nothing in it (:func:`from_json`): it is read as a regular file of at most :data:`MAX_SUITE_BYTES`; every
field's type and range is checked (one ``ValueError`` naming the file and the field); its ``env_id`` must be one
mrd_env registers (an id ``"module:Env"`` would make Gymnasium import that module); a file it names (a measured
road's or a record's ``path``, a damper preset) must be a plain name inside the suite file's folder; and a shipped
suite's id (:func:`shipped_digest`) means the shipped content: a suite of one's own needs a name of its own.
"""
from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

from .storage import inside, read_limited, write_json

#: The suite files' format (bumped when the fields change).
FORMAT = "mrd-env-suite"
FORMAT_VERSION = 1
#: The largest suite file read: 4 MiB, 66 times the largest shipped one (car-preview-robust-v1, 63 662 bytes); a
#: larger file is refused before it is read (a suite file from elsewhere must not exhaust memory).
MAX_SUITE_BYTES = 4 * 1024 ** 2
#: The deepest nesting of objects and lists in a suite file (the shipped ones nest 7 deep, the file itself counted).
MAX_NESTING = 16
#: Seeds are NumPy's: whole numbers in [0, 2**32 - 1].
MAX_SEED = 2 ** 32 - 1


def content_digest(data: dict) -> str:
    """SHA-256 of a suite's content (canonical JSON of everything but ``digest``)."""
    body = {k: v for k, v in data.items() if k != "digest"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class SuiteScenario:
    """A scenario of a suite: the environment options beyond the suite's and the seeds of its episodes (an
    unseeded scenario — a recorded earthquake, a bump — has one episode, seed 0)."""

    name: str
    options: dict
    seeds: tuple[int, ...]

    def label(self, seed: int) -> str:
        return f"{self.name} s{seed}" if len(self.seeds) > 1 else self.name


#: Environment options that only shape what a controller sees (its sensors), never the plant: the references of an
#: episode (command sequences replayed open loop) do not depend on them, so they are computed without them.
SENSOR_OPTIONS = ("sensors", "sensor_noise", "sensor_delay", "history", "preview")


#: The reference procedures a spec may name (``experiments.benchmark.references``): 1, the clairvoyant at 1 ms by one
#: solver (the v1 suites); 2, the clairvoyant at the suite's control step, certified by two solvers (the default);
#: 3, procedure 2 with the gradient solver's first round run for each scenario's episodes together (faster builds);
#: 4, procedure 3 whose round 2 starts each solver from the other's optimum before it runs more starts.
#: 5, procedure 4 whose gradient solver keeps off the limits that end an episode by the CasADi solver's penalty.
PROCEDURES = (1, 2, 3, 4, 5)
#: A spec's procedure when it names none.
DEFAULT_PROCEDURE = 2


@dataclass(frozen=True)
class SuiteDefinition:
    """What a plant's profile declares of a suite (:attr:`mrd_env.plants.profile.PlantProfile.suites`): everything
    but the references, which ``python -m experiments.benchmark.references --suite <name>`` computes once and
    ships in ``mrd_env/plants/<plant>/suites/<name>-v<version>.json``.

    ``options``: the environment options of every episode (damper, damper floors, sensors — ``road_preview``
    among them says the controller has the road preview); ``scenarios``: each scenario's own options and seeds;
    ``criteria``: the episode metrics reported beside the share; ``references_of``: the suite whose references
    this one shares (the same episodes on the same plant, only the sensors differ): an id (``car-comfort-v1``), or a
    name, meaning that name at this suite's own version (:attr:`references_id`); ``randomise``: a
    robustness twin's bands (:func:`draw_episode`: drawn per episode from ``randomise["seed"]``, stored in the
    suite file)."""

    name: str
    version: int
    description: str
    options: dict
    control_dt: float
    scenarios: tuple[SuiteScenario, ...]
    criteria: tuple[str, ...]
    references_of: str = ""
    randomise: dict = field(default_factory=dict)
    #: the plant's folder name and the environment id a spec names ("": the plant's physics id, resolved by
    #: :func:`mrd_env.plants.suite_spec`)
    plant: str = ""
    env_id: str = ""
    #: the reference procedure its references are computed by (:data:`PROCEDURES`)
    procedure: int = DEFAULT_PROCEDURE

    @property
    def references_id(self) -> str:
        """The id of the suite whose references this one shares ("" for none): ``references_of`` where it names a
        version, else that name at this suite's version — a twin and its source are versioned together, so a new
        version of the source (``car-comfort-v2``) leaves the twins of the old one (``car-preview-v1``) on theirs."""
        ref = self.references_of
        if not ref or re.fullmatch(r".+-v[0-9]+", ref):
            return ref
        return f"{ref}-v{self.version}"
    #: the folder of the spec file it was read from, where the record files its options name are; "" otherwise
    folder: str = field(default="", compare=False, repr=False)

    @property
    def id(self) -> str:
        return f"{self.name}-v{self.version}"

    def suite(self, plant: str | None = None, env_id: str | None = None, draws: dict | None = None) -> "Suite":
        """The suite without references (``plant``, ``env_id``: the definition's by default; ``draws``: a twin's
        per-episode draws, :func:`draws`). A record file its options name is resolved in the spec's folder."""
        randomised = _json_options({"bands": self.randomise, "draws": draws or {}}) if self.randomise else {}
        return Suite(name=self.name, version=self.version, plant=plant or self.plant, env_id=env_id or self.env_id,
                     description=self.description, options=_json_options(self.options),
                     control_dt=float(self.control_dt),
                     scenarios=tuple(SuiteScenario(sc.name, _json_options(sc.options), tuple(int(x) for x in sc.seeds))
                                     for sc in self.scenarios),
                     criteria=tuple(self.criteria), randomised=randomised, folder=self.folder)

    def to_spec(self) -> dict:
        """The definition as a spec file's content (:func:`read_spec`), seeds that run on written compactly."""
        def seeds(s):
            s = [int(x) for x in s]
            if len(s) > 2 and s == list(range(s[0], s[0] + len(s))):
                return {"first": s[0], "count": len(s)}
            return s

        out = {"format": SPEC_FORMAT, "format_version": SPEC_FORMAT_VERSION, "name": self.name,
               "version": self.version, "plant": self.plant, **({"env_id": self.env_id} if self.env_id else {}),
               "description": self.description, "options": _json_options(self.options),
               "control_dt": float(self.control_dt),
               "scenarios": [{"name": sc.name, "options": _json_options(sc.options), "seeds": seeds(sc.seeds)}
                             for sc in self.scenarios],
               "criteria": list(self.criteria)}
        if self.references_of:
            out["references_of"] = self.references_of
        if self.randomise:
            out["randomise"] = _json_options(self.randomise)
        out["procedure"] = int(self.procedure)
        return out


@dataclass(frozen=True)
class Reference:
    """The reference values of one episode (returns as the environment pays them)."""

    passive: float             #: R_p, the best constant command's return
    passive_command: float     #: that command (V or A)
    clairvoyant: float         #: R_c, the clairvoyant optimum found by the suite's procedure, re-simulated
    bound: float = math.nan    #: R_b, the active bound (an upper bound on every semi-active controller's return)
    f_max: float = math.nan    #: the bound's force limit (N)

    def share(self, ret: float) -> float:
        """(R − R_p) / (R_c − R_p): the share of the achievable gain a return captures."""
        gap = self.clairvoyant - self.passive
        return (ret - self.passive) / gap if gap > 0 else math.nan


@dataclass(frozen=True)
class Suite:
    """A frozen benchmark suite (see the module docstring)."""

    name: str
    version: int
    plant: str
    env_id: str
    description: str
    options: dict                                   #: environment options of every episode
    control_dt: float                               #: every controller's control step (s)
    scenarios: tuple[SuiteScenario, ...]
    criteria: tuple[str, ...]                       #: the episode metrics reported beside the share
    references: dict = field(default_factory=dict)  #: episode label → Reference
    procedure: dict = field(default_factory=dict)   #: how the references were computed, and the command
    randomised: dict = field(default_factory=dict)  #: a robustness twin's draws ({} for a nominal suite)
    digest: str = ""
    #: the folder of the file it was read from, where the files its options name are (:func:`named_files`); ""
    #: for a suite made in code
    folder: str = field(default="", compare=False, repr=False)

    @property
    def id(self) -> str:
        return f"{self.name}-v{self.version}"

    def episodes(self) -> list[tuple[SuiteScenario, int]]:
        return [(sc, seed) for sc in self.scenarios for seed in sc.seeds]

    def labels(self) -> list[str]:
        """Every episode's label, in order (the keys of :attr:`references`)."""
        return [sc.label(seed) for sc, seed in self.episodes()]

    def episode_options(self, scenario: SuiteScenario, seed: int) -> dict:
        """The environment options of an episode as a controller is scored on it (the suite's, the scenario's and,
        for a robustness twin, the episode's stored draw; the control step is :attr:`control_dt`)."""
        draw = self.randomised.get("draws", {}).get(scenario.label(seed), {}) if self.randomised else {}
        options = _json_options({**self.options, **scenario.options, **draw})
        if self.folder:  # a file an option names is the one in the suite file's folder (checked again: links move)
            for keys, name in named_files(options):
                target = options
                for k in keys[:-1]:
                    target = target[k]
                target[keys[-1]] = str(confined_file(self.folder, name, f"suite {self.id}: {_field(keys)}"))
        return options

    def reference_options(self, scenario: SuiteScenario, seed: int) -> dict:
        """The environment options the references of an episode are computed on: :meth:`episode_options` without
        the sensor options (:data:`SENSOR_OPTIONS`), which do not change an open-loop command sequence's return."""
        return {k: v for k, v in self.episode_options(scenario, seed).items() if k not in SENSOR_OPTIONS}

    def definition_json(self) -> dict:
        """The suite's definition (everything but its references, procedure and digest), as JSON: what a new
        version must change."""
        return {k: v for k, v in self.to_json().items() if k not in ("references", "procedure", "digest")}

    def complete(self) -> bool:
        """Every episode has its reference."""
        return set(self.labels()) <= set(self.references)

    def reference(self, label: str) -> Reference:
        try:
            return self.references[label]
        except KeyError:
            raise ValueError(f"suite {self.id} has no reference for episode {label!r}") from None

    def to_json(self) -> dict:
        return {"format": FORMAT, "format_version": FORMAT_VERSION, "name": self.name, "version": self.version,
                "plant": self.plant, "env_id": self.env_id, "description": self.description,
                "options": self.options, "control_dt": self.control_dt,
                "scenarios": [{"name": s.name, "options": s.options, "seeds": list(s.seeds)} for s in self.scenarios],
                "criteria": list(self.criteria),
                "references": {k: {f: (None if isinstance(v, float) and math.isnan(v) else v)
                                   for f, v in vars(r).items()} for k, r in self.references.items()},
                "procedure": self.procedure, "randomised": self.randomised}


#: A suite file's fields (``procedure`` and ``randomised`` may be left out: {}).
FIELDS = ("format", "format_version", "name", "version", "plant", "env_id", "description", "options", "control_dt",
          "scenarios", "criteria", "references", "digest")
OPTIONAL_FIELDS = ("procedure", "randomised")
#: An episode's reference: these three are numbers; ``bound`` and ``f_max`` numbers or null (not computed).
REFERENCE_NUMBERS = ("passive", "passive_command", "clairvoyant")
REFERENCE_FIELDS = REFERENCE_NUMBERS + ("bound", "f_max")
#: A suite's name: it is part of file names and table rows.
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
#: A criterion: an episode metric's name.
CRITERION = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")
#: The longest scenario name (it heads a table row), description and file name a suite may hold.
MAX_LABEL, MAX_DESCRIPTION, MAX_FILE_NAME = 200, 10_000, 4096
#: The highest suite version.
MAX_VERSION = 10 ** 6
#: The most scenarios, and episodes, a suite holds (the shipped suites: at most 4 and 31); a result file of the
#: suite is held to the same bounds (:mod:`experiments.benchmark.ranking`).
MAX_SCENARIOS, MAX_EPISODES = 500, 5_000


def from_json(data: dict, where: str = "suite", folder: str | Path | None = None, *, shipped: bool = False) -> Suite:
    """A :class:`Suite` from its JSON content, after checking everything in it, before anything is imported or made:
    its structure field by field (:func:`check_structure`), its digest, its environment (an id mrd_env registers,
    of its plant), that a shipped suite's id holds the shipped content (:func:`check_shipped_id`; not for the
    package's own files, ``shipped``), and that every file its options name is a regular file inside ``folder``,
    the suite file's (a suite given without a folder names no file). A one-line ``ValueError`` naming ``where`` and
    the field otherwise."""
    check_structure(data, where)
    if data["digest"] != content_digest(data):
        raise ValueError(f"{where}: its content does not match its digest (edited or damaged): refused")
    _check_environment(data["plant"], data["env_id"], where)
    if not shipped:
        check_shipped_id(f"{data['name']}-v{data['version']}", data["digest"], where)
    for keys, name in _files_named(data):
        if folder is None:
            raise ValueError(f"{where}: {_field(keys)} names the file {_shown(name)}: only a suite read from its "
                             "file names files (in that file's folder)")
        confined_file(folder, name, f"{where}: {_field(keys)}")
    refs = {k: Reference(**{f: (math.nan if v is None else float(v)) for f, v in r.items()})
            for k, r in data["references"].items()}
    return Suite(name=data["name"], version=data["version"], plant=data["plant"], env_id=data["env_id"],
                 description=data["description"], options=data["options"], control_dt=float(data["control_dt"]),
                 scenarios=tuple(SuiteScenario(s["name"], s["options"], tuple(s["seeds"])) for s in data["scenarios"]),
                 criteria=tuple(data["criteria"]), references=refs, procedure=data.get("procedure", {}),
                 randomised=data.get("randomised", {}), digest=data["digest"],
                 folder=str(Path(folder).resolve()) if folder is not None else "")


def check_structure(data, where: str = "suite") -> None:
    """``ValueError`` (one line naming ``where`` and the field) unless ``data`` is a suite file's content of the
    right structure: every field of :data:`FIELDS` and no other; a name of :data:`NAME`; whole numbers where
    whole numbers belong (versions; seeds in [0, 2**32 - 1], NumPy's); finite numbers elsewhere (a positive
    ``control_dt``); options as objects of names; one reference, of :data:`REFERENCE_FIELDS`, per episode at most;
    nothing nested deeper than :data:`MAX_NESTING`. The environment is checked by :func:`from_json`."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where} is not an mrd-env suite (format must be {FORMAT!r})")
    version = data.get("format_version")
    if type(version) is not int or version != FORMAT_VERSION:
        raise ValueError(f"{where}: suite format version {_shown(version)}, this mrd-env reads {FORMAT_VERSION}")
    missing = [k for k in FIELDS if k not in data]
    unknown = [k for k in data if k not in FIELDS + OPTIONAL_FIELDS]
    if missing or unknown:
        what = f"lacks the field(s) {missing}" if missing else f"has unknown field(s) {[_shown(k) for k in unknown[:5]]}"
        raise ValueError(f"{where}: {what}; a suite file has {list(FIELDS + OPTIONAL_FIELDS)}")

    def fail(field: str, want: str, got) -> None:
        raise ValueError(f"{where}: {field} must be {want}, got {_shown(got)}")

    for key in ("name", "plant", "env_id", "description"):
        if not isinstance(data[key], str):
            fail(key, "text", data[key])
    if not NAME.fullmatch(data["name"]):
        fail("name", "1 to 64 letters, digits, '.', '_' or '-' (starting with a letter or digit)", data["name"])
    if len(data["description"]) > MAX_DESCRIPTION:
        fail("description", f"at most {MAX_DESCRIPTION} characters", f"{len(data['description'])} characters")
    if type(data["version"]) is not int or not 1 <= data["version"] <= MAX_VERSION:
        fail("version", f"a whole number in [1, {MAX_VERSION}]", data["version"])
    if not isinstance(data["digest"], str) or not re.fullmatch(r"[0-9a-f]{64}", data["digest"]):
        fail("digest", "a SHA-256 (64 hexadecimal digits)", data["digest"])
    _check_options(data["options"], where, "options")
    dt = data["control_dt"]
    if not _finite(dt) or dt <= 0:
        fail("control_dt", "a positive finite number of seconds", dt)

    scenarios = data["scenarios"]
    if not isinstance(scenarios, list) or not scenarios or len(scenarios) > MAX_SCENARIOS:
        fail("scenarios", f"a non-empty list of at most {MAX_SCENARIOS} scenarios",
             scenarios if not isinstance(scenarios, list) else f"{len(scenarios)} scenarios")
    labels: list[str] = []
    for i, sc in enumerate(scenarios):
        at = f"scenarios[{i}]"
        if not isinstance(sc, dict) or set(sc) != {"name", "options", "seeds"}:
            fail(at, "an object of name, options and seeds", sc if not isinstance(sc, dict) else sorted(sc, key=str))
        name = sc["name"]
        if not isinstance(name, str) or not name.strip() or len(name) > MAX_LABEL or not name.isprintable():
            fail(f"{at}.name", f"text on one line of 1 to {MAX_LABEL} characters", name)
        at = f"{at} ({name!r})"
        _check_options(sc["options"], where, f"{at}.options")
        seeds = sc["seeds"]
        if not isinstance(seeds, list) or not seeds:
            fail(f"{at}.seeds", "a non-empty list of seeds", seeds)
        if len(labels) + len(seeds) > MAX_EPISODES:
            fail(f"{at}.seeds", f"at most {MAX_EPISODES} episodes in the whole suite",
                 f"{len(labels) + len(seeds)} episodes")
        for j, seed in enumerate(seeds):
            if type(seed) is not int or not 0 <= seed <= MAX_SEED:
                fail(f"{at}.seeds[{j}]", f"a whole number in [0, {MAX_SEED}] (NumPy's seeds)", seed)
        if len(set(seeds)) != len(seeds):
            fail(f"{at}.seeds", "distinct seeds", seeds)
        one = SuiteScenario(name, {}, tuple(seeds))
        labels += [one.label(seed) for seed in seeds]
    if len(set(labels)) != len(labels):
        twice = sorted({x for x in labels if labels.count(x) > 1})[:3]
        fail("scenarios", "scenarios whose names give distinct episode labels", twice)
    episodes = set(labels)

    criteria = data["criteria"]
    if not isinstance(criteria, list) or not all(isinstance(c, str) and CRITERION.fullmatch(c) for c in criteria) \
            or len(set(criteria)) != len(criteria):
        fail("criteria", "a list of distinct episode metric names", criteria)

    refs = data["references"]
    if not isinstance(refs, dict):
        fail("references", "an object {episode label: reference}", refs)
    for label, ref in refs.items():
        if label not in episodes:
            fail("references", f"references of the suite's episodes (e.g. {labels[0]!r})", label)
        at = f"references[{label!r}]"
        if not isinstance(ref, dict) or set(ref) != set(REFERENCE_FIELDS):
            fail(at, f"an object of {list(REFERENCE_FIELDS)}", ref if not isinstance(ref, dict)
                 else sorted(ref, key=str))
        for f in REFERENCE_FIELDS:
            v = ref[f]
            if not (_finite(v) or (v is None and f not in REFERENCE_NUMBERS)):
                fail(f"{at}.{f}", "a finite number" + ("" if f in REFERENCE_NUMBERS else " or null"), v)

    procedure = data.get("procedure", {})
    if not isinstance(procedure, dict):
        fail("procedure", "an object", procedure)
    _check_json(procedure, where, "procedure", 1)
    randomised = data.get("randomised", {})
    if not isinstance(randomised, dict) or not set(randomised) <= {"bands", "draws"}:
        fail("randomised", "an object of bands and draws (or {})", randomised)
    if not isinstance(randomised.get("bands", {}), dict):
        fail("randomised.bands", "an object", randomised["bands"])
    _check_json(randomised.get("bands", {}), where, "randomised.bands", 2)
    drawn = randomised.get("draws", {})
    if not isinstance(drawn, dict):
        fail("randomised.draws", "an object {episode label: options}", drawn)
    for label, options in drawn.items():
        if label not in episodes:
            fail("randomised.draws", f"draws of the suite's episodes (e.g. {labels[0]!r})", label)
        _check_options(options, where, f"randomised.draws[{label!r}]", 3)


def _check_options(options, where: str, field: str, depth: int = 1) -> None:
    """Environment options: an object of option names, plain JSON values inside (checked by the environment)."""
    if not isinstance(options, dict):
        raise ValueError(f"{where}: {field} must be an object of environment options, got {_shown(options)}")
    _check_json(options, where, field, depth)


def _check_json(value, where: str, field: str, depth: int) -> None:
    """``ValueError`` unless ``value`` is plain JSON (objects of text keys, lists, text, finite numbers, true,
    false, null) nested at most :data:`MAX_NESTING` deep in the file (``depth``: its own depth there)."""
    if depth > MAX_NESTING:
        raise ValueError(f"{where}: {field} is nested more than {MAX_NESTING} levels deep")
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, str):
                raise ValueError(f"{where}: {field} must have names (text) as keys, got {_shown(k)}")
            _check_json(v, where, f"{field}.{k}" if re.fullmatch(r"\w+", k) else f"{field}[{k[:60]!r}]", depth + 1)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _check_json(v, where, f"{field}[{i}]", depth + 1)
    elif isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{where}: {field} must be a finite number, got {value!r}")
    elif not (value is None or isinstance(value, (str, int, float))):
        raise ValueError(f"{where}: {field} must be a JSON value, got a {type(value).__name__}")


def _check_environment(plant: str, env_id: str, where: str) -> None:
    """``ValueError`` unless ``env_id`` is an id mrd_env registers (an id ``"module:Env"`` would make Gymnasium
    import that module: a suite runs no code) and ``plant`` one of the plants' folders. (That the id is one of that
    plant's is checked above the plants, where a suite is resolved for scoring:
    :func:`experiments.benchmark.scoring.resolve_suite`; this module imports no plant.)"""
    import gymnasium as gym

    # ``import mrd_env.suites`` ran ``mrd_env/__init__``, which registered every plant's ids
    valid = sorted(k for k in gym.registry if k.startswith("mrd_env/"))
    if env_id not in valid:
        raise ValueError(f"{where}: env_id must be an environment of mrd_env, one of {valid}; got {_shown(env_id)}")
    every = sorted(f.name for f in PLANTS_FOLDER.iterdir() if (f / "__init__.py").is_file())
    if plant not in every:
        raise ValueError(f"{where}: plant must be one of {every}, got {_shown(plant)}")


def named_files(options) -> list[tuple[tuple, object]]:
    """The files an options object names, as (keys to the value, the value): the environment's file options at any
    depth (:data:`mrd_env.envs.build.FILE_KEYS`: a measured road's or a ground motion's ``path`` in
    ``road_params``, ``ground_motion_params``, a mixture's ``sources``; a neural inverse's ``network``) and a
    ``damper`` that names a preset file (:func:`mrd_env.dampers.is_preset_file`)."""
    from .dampers import is_preset_file
    from .envs.build import FILE_KEYS

    out = []

    def walk(value, keys):
        if isinstance(value, dict):
            for k, v in value.items():
                if k in FILE_KEYS or (k == "damper" and is_preset_file(v)):
                    out.append(((*keys, k), v))
                else:
                    walk(v, (*keys, k))
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                walk(v, (*keys, i))

    walk(options, ())
    return out


def _files_named(data: dict) -> list[tuple[tuple, object]]:
    """The files a suite's content names: in its options, each scenario's and each drawn episode's."""
    out = [(("options", *k), v) for k, v in named_files(data["options"])]
    for i, sc in enumerate(data["scenarios"]):
        out += [(("scenarios", i, "options", *k), v) for k, v in named_files(sc["options"])]
    for label, draw in data.get("randomised", {}).get("draws", {}).items():
        out += [(("randomised", "draws", label, *k), v) for k, v in named_files(draw)]
    return out


def confined_file(folder: str | Path, name, what: str) -> Path:
    """``folder / name`` for a file a suite names: a plain name inside the suite file's folder
    (:func:`mrd_env.storage.inside`: no absolute path, no ``..``, no link leaving it) of a regular file (not a
    folder, device, FIFO or socket, which the environment's read would hang on or never finish)."""
    if isinstance(name, str) and (len(name) > MAX_FILE_NAME or "\x00" in name):
        raise ValueError(f"{what} {_shown(name)}: a file name of at most {MAX_FILE_NAME} characters (and no NUL) is "
                         "required")
    path = inside(folder, name, what=what)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ValueError(f"{what} {name!r} in {folder}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{what} {name!r} in {folder}: not a regular file (a folder, device, FIFO or socket): "
                         "refused")
    return path


def _field(keys: tuple) -> str:
    """A field's place in a suite file: ``scenarios[0].options.road_params.path``."""
    out = ""
    for k in keys:
        if isinstance(k, int):
            out += f"[{k}]"
        elif re.fullmatch(r"\w+", k):
            out += f".{k}" if out else k
        else:
            out += f"[{k[:60]!r}]"
    return out


def _finite(value) -> bool:
    """A finite number (not a bool, which JSON does not mix up with numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def _shown(value) -> str:
    """``value`` in an error message: short, whatever a file holds (a 5 MB text, a list nested 900 deep, an
    integer of 10 000 digits)."""
    if isinstance(value, dict):
        return f"an object of {len(value)} field(s)"
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} item(s)"
    if isinstance(value, str):
        return repr(value[:60]) + ("..." if len(value) > 60 else "")
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    if value is None or isinstance(value, (bool, int, float)):
        return repr(value)
    return f"a {type(value).__name__}"


def write_suite(suite: Suite, path: str | Path) -> Path:
    """Write ``suite`` to ``path`` atomically, with the digest of its content."""
    data = suite.to_json()
    data["digest"] = content_digest(data)
    return write_json(path, data, indent=1, sort_keys=False, allow_nan=False)


def read_suite(path: str | Path) -> Suite:
    """The suite in the file ``path``: a regular file of at most :data:`MAX_SUITE_BYTES` (never a FIFO or a
    device), checked by :func:`from_json` (the files it names are in its folder; a shipped file is the package's
    own, the others are held to :func:`check_shipped_id`)."""
    path = Path(path)
    resolved = path.resolve()
    shipped = resolved.parent.name == "suites" and resolved.parent.parent.parent == PLANTS_FOLDER
    return from_json(_load(path), where=f"suite file {path}", folder=path.parent, shipped=shipped)


def _load(path: Path, what: str = "suite file"):
    """The JSON content of the suite file ``path``; ``ValueError`` naming it otherwise."""
    raw = read_limited(path, MAX_SUITE_BYTES, what=what)

    def constant(name):  # NaN and Infinity are not JSON (and not a suite's)
        raise ValueError(f"{name} is not a JSON number")

    try:
        return json.loads(raw.decode("utf-8"), parse_constant=constant)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} {path}: cannot be read (byte {exc.start} is not UTF-8 text)") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{what} {path}: cannot be read (not JSON: {exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise ValueError(f"{what} {path}: cannot be read (nested too deeply; a {what} nests at most "
                         f"{MAX_NESTING} levels)") from None
    except ValueError as exc:
        raise ValueError(f"{what} {path}: cannot be read ({exc})") from None


# ------------------------------------------------------------------------------------------- suite specs

#: A suite spec's format: the definition of a suite (everything but its references), which ``mrd-env suite build``
#: turns into a suite file; the shipped suites' specs are ``mrd_env/plants/<plant>/suites/specs/<id>.json``.
SPEC_FORMAT = "mrd-env-suite-spec"
SPEC_FORMAT_VERSION = 1
SPEC_FIELDS = ("format", "format_version", "name", "version", "plant", "description", "options", "control_dt",
               "scenarios", "criteria")
SPEC_OPTIONAL_FIELDS = ("env_id", "references_of", "randomise", "procedure")
#: A robustness twin's bands (:func:`draw_episode`): ``seed`` and the bands of these groups.
BAND_GROUPS = ("damper_params", "command", "plant_params", "sensor_noise")


def spec_definition(data, where: str = "suite spec", folder: str | Path | None = None) -> SuiteDefinition:
    """The :class:`SuiteDefinition` of a spec's JSON content (docs/suites.md, "Your own suite"), checked whole: the
    fields of :data:`SPEC_FIELDS` (and optionally :data:`SPEC_OPTIONAL_FIELDS`) and no other; each scenario
    {name, options, seeds}, its seeds a list or ``{"first": N, "count": K}`` (N, N + 1, ..., N + K − 1); the rest as
    in a suite file (:func:`check_structure`: names, versions, seeds, at most :data:`MAX_SCENARIOS` scenarios and
    :data:`MAX_EPISODES` episodes); ``randomise`` a twin's bands; a plant among the plants' folders; every file the
    options name a regular file inside ``folder``, the spec's (a spec given without a folder names no file). One
    ``ValueError`` naming ``where`` and the field otherwise. ``env_id`` is checked against the plant by
    :func:`mrd_env.plants.suite_spec` (this module imports no plant)."""
    if not isinstance(data, dict) or data.get("format") != SPEC_FORMAT:
        raise ValueError(f"{where} is not an mrd-env suite spec (format must be {SPEC_FORMAT!r})")
    version = data.get("format_version")
    if type(version) is not int or version != SPEC_FORMAT_VERSION:
        raise ValueError(f"{where}: format_version must be {SPEC_FORMAT_VERSION}, got {_shown(version)}")
    missing = [k for k in SPEC_FIELDS if k not in data]
    unknown = [k for k in data if k not in SPEC_FIELDS + SPEC_OPTIONAL_FIELDS]
    if missing or unknown:
        what = f"lacks the field(s) {missing}" if missing else f"has unknown field(s) {[k[:60] for k in unknown[:5]]}"
        raise ValueError(f"{where}: {what}; a suite spec has {list(SPEC_FIELDS)} and optionally "
                         f"{list(SPEC_OPTIONAL_FIELDS)}")

    def fail(field: str, want: str, got) -> None:
        raise ValueError(f"{where}: {field} must be {want}, got {_shown(got)}")

    scenarios = data["scenarios"]
    if not isinstance(scenarios, list) or not scenarios or len(scenarios) > MAX_SCENARIOS:
        fail("scenarios", f"a non-empty list of at most {MAX_SCENARIOS} scenarios",
             scenarios if not isinstance(scenarios, list) else f"{len(scenarios)} scenarios")
    expanded = []
    for i, sc in enumerate(scenarios):
        if not isinstance(sc, dict) or set(sc) != {"name", "options", "seeds"}:
            fail(f"scenarios[{i}]", "an object of name, options and seeds",
                 sc if not isinstance(sc, dict) else sorted(sc, key=str))
        expanded.append({**sc, "seeds": _spec_seeds(sc["seeds"], f"scenarios[{i}].seeds", fail)})
    env_id = data.get("env_id", "")
    if not isinstance(env_id, str):
        fail("env_id", "an environment id of the plant (text; left out: the plant's physics id)", env_id)
    references_of = data.get("references_of", "")
    if not isinstance(references_of, str) or (references_of and not NAME.fullmatch(references_of)):
        fail("references_of", "the name of a shipped suite with the same episodes", references_of)
    randomise = data.get("randomise", {})
    _check_bands(randomise, fail)
    procedure = data.get("procedure", DEFAULT_PROCEDURE)
    if type(procedure) is not int or procedure not in PROCEDURES:
        fail("procedure", f"one of {list(PROCEDURES)} (the reference procedure; left out: {DEFAULT_PROCEDURE})",
             procedure)
    body = {"format": FORMAT, "format_version": FORMAT_VERSION,
            **{k: data[k] for k in SPEC_FIELDS if k not in ("format", "format_version", "scenarios")},
            "env_id": env_id, "scenarios": expanded, "references": {}, "digest": "0" * 64,
            "randomised": {"bands": randomise} if randomise else {}}
    check_structure(body, where)
    plants = sorted(f.name for f in PLANTS_FOLDER.iterdir() if (f / "__init__.py").is_file())
    if data["plant"] not in plants:
        fail("plant", f"one of {plants}", data["plant"])
    for keys, name in _files_named(body):
        if folder is None:
            raise ValueError(f"{where}: {_field(keys)} names the file {_shown(name)}: only a spec read from its "
                             "file names files (in that file's folder)")
        confined_file(folder, name, f"{where}: {_field(keys)}")
    return SuiteDefinition(name=data["name"], version=data["version"], description=data["description"],
                           options=data["options"], control_dt=float(data["control_dt"]),
                           scenarios=tuple(SuiteScenario(s["name"], s["options"], tuple(s["seeds"]))
                                           for s in expanded),
                           criteria=tuple(data["criteria"]), references_of=references_of, randomise=randomise,
                           plant=data["plant"], env_id=env_id, procedure=procedure,
                           folder=str(Path(folder).resolve()) if folder is not None else "")


def _spec_seeds(seeds, field: str, fail) -> list:
    """A scenario's seeds: a list (checked by :func:`check_structure`) or ``{"first": N, "count": K}``."""
    if isinstance(seeds, list):
        return seeds
    if not isinstance(seeds, dict) or set(seeds) != {"first", "count"}:
        fail(field, 'a list of seeds or {"first": N, "count": K}', seeds)
    first, count = seeds["first"], seeds["count"]
    if type(first) is not int or not 0 <= first <= MAX_SEED:
        fail(f"{field}.first", f"a whole number in [0, {MAX_SEED}] (NumPy's seeds)", first)
    if type(count) is not int or not 1 <= count <= min(MAX_EPISODES, MAX_SEED - first + 1):
        fail(f"{field}.count", f"a whole number in [1, {min(MAX_EPISODES, MAX_SEED - first + 1)}]", count)
    return list(range(first, first + count))


def _check_bands(bands, fail) -> None:
    """A robustness twin's ``randomise`` (:func:`draw_episode`): {} or ``seed`` and bands (lo <= hi, finite)."""
    if not isinstance(bands, dict):
        fail("randomise", "an object of a twin's bands (or left out)", bands)
    if not bands:
        return
    known = ("seed", *BAND_GROUPS, "sensor_delay")
    unknown = [k for k in bands if k not in known]
    if unknown:
        fail("randomise", f"an object of {list(known)}", f"the unknown field(s) {[k[:60] for k in unknown[:5]]}")
    seed = bands.get("seed")
    if type(seed) is not int or not 0 <= seed <= MAX_SEED:
        fail("randomise.seed", f"a whole number in [0, {MAX_SEED}]", seed)
    for group in BAND_GROUPS:
        entries = bands.get(group, {})
        if not isinstance(entries, dict):
            fail(f"randomise.{group}", "an object {name: [lo, hi]}", entries)
        for name, band in entries.items():
            if not (isinstance(band, list) and len(band) == 2 and all(map(_finite, band)) and band[0] <= band[1]):
                fail(f"randomise.{group}.{name}", "[lo, hi], finite numbers with lo <= hi", band)
    delays = bands.get("sensor_delay", [0])
    if not isinstance(delays, list) or not delays or not all(type(k) is int and 0 <= k <= 1000 for k in delays):
        fail("randomise.sensor_delay", "a non-empty list of delays in control steps (whole numbers in [0, 1000])",
             delays)


def read_spec(path: str | Path) -> SuiteDefinition:
    """The :class:`SuiteDefinition` in the spec file ``path`` (:func:`spec_definition`; its record files are in the
    file's folder), read as a suite file is (a regular file of at most :data:`MAX_SUITE_BYTES`)."""
    path = Path(path)
    return spec_definition(_load(path, "suite spec"), where=f"suite spec {path}", folder=path.parent)


def read_specs(folder: str | Path) -> tuple[SuiteDefinition, ...]:
    """The definitions of a plant's shipped suites: every spec file of ``folder`` (``suites/specs/``), by name."""
    folder = Path(folder)
    return tuple(read_spec(inside(folder, p.name, what="suite spec")) for p in sorted(folder.glob("*.json")))


#: The plants' folders, where each ships its suites (``<plant>/suites/*.json``): found by path, so that this
#: module, which the plants' suite definitions import, imports no plant.
PLANTS_FOLDER = Path(__file__).resolve().parent / "plants"


def suites() -> dict[str, Suite]:
    """Every shipped suite by its id (``name-vN``): the JSON files of each plant folder's ``suites/``."""
    out = {}
    for folder in sorted(PLANTS_FOLDER.glob("*/suites")):
        for path in sorted(folder.glob("*.json")):
            if path.name.endswith(BUILD_RECORD_SUFFIX):  # a build's record (wall times, machine), not a suite
                continue
            s = read_suite(inside(folder, path.name, what="suite file"))
            if s.plant != folder.parent.name:
                raise ValueError(f"suite file {path}: its plant is {s.plant!r}, not the folder's "
                                 f"{folder.parent.name!r}")
            out[s.id] = s
    return out


def suite(name: str) -> Suite:
    """The shipped suite ``name`` (``car-comfort-v1``; a name without version: its latest), or a suite file's
    path (:func:`read_suite`); ``ValueError`` naming the suites otherwise."""
    if isinstance(name, str) and name.endswith(".json"):
        return read_suite(name)
    every = suites()
    if name in every:
        return every[name]
    versions = sorted((s.version, s) for s in every.values() if s.name == name)
    if versions:
        return versions[-1][1]
    raise ValueError(f"suite must be one of {sorted(every)} (or a suite file), got {_shown(name)}")


# ------------------------------------------------------------------------------ the shipped suites' digests

#: The shipped suites' digests by id (``{"format": ..., "digests": {id: digest}}``): a shipped id means the shipped
#: content (:func:`check_shipped_id`; the leaderboard's result files too). :func:`write_shipped_digests`
#: regenerates it from the shipped files; ``tests/test_suite_security.py`` checks that it matches them.
SHIPPED_DIGESTS = PLANTS_FOLDER / "suite_digests.json"
DIGESTS_FORMAT = "mrd-env-suite-digests"


@functools.lru_cache(maxsize=1)
def _shipped_digests() -> tuple[tuple[str, str], ...]:
    if not SHIPPED_DIGESTS.exists():  # an installation without the list: the shipped files themselves say it
        return tuple(sorted((sid, s.digest) for sid, s in suites().items()))
    try:
        data = json.loads(read_limited(SHIPPED_DIGESTS, 1 << 20, what="shipped suites' digest list"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        data = None
    digests = data.get("digests") if isinstance(data, dict) and data.get("format") == DIGESTS_FORMAT else None
    if not isinstance(digests, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                                and re.fullmatch(r"[0-9a-f]{64}", v) for k, v in digests.items()):
        raise ValueError(f"{SHIPPED_DIGESTS} is damaged (not a list of suite digests): reinstall mrd-env")
    return tuple(sorted(digests.items()))


def shipped_digests() -> dict[str, str]:
    """{suite id: digest} of every shipped suite (:data:`SHIPPED_DIGESTS`)."""
    return dict(_shipped_digests())


def shipped_digest(suite_id: str) -> str | None:
    """The digest of the shipped suite ``suite_id`` (``car-comfort-v1``), or None if no shipped suite has that
    id."""
    return shipped_digests().get(suite_id) if isinstance(suite_id, str) else None


def check_shipped_id(suite_id: str, digest: str, where: str = "suite") -> None:
    """``ValueError`` (one line naming ``where``) if the suite ``suite_id`` (``name-vN``) of ``digest`` passes
    for a shipped one it is not: a shipped id with another digest (an edited suite whose digest was recomputed),
    or another version of a shipped suite's name than this mrd-env ships. A suite of one's own needs a name of its
    own; results of it then never mix with the shipped suite's."""
    every = shipped_digests()
    want = every.get(suite_id)
    if want is not None:
        if digest != want:
            shown = digest[:12] + "..." if isinstance(digest, str) else _shown(digest)
            raise ValueError(f"{where}: {suite_id} is the id of a shipped suite, whose content differs (digest "
                             f"{shown}, shipped {want[:12]}...): a suite of your own needs a name of its own")
        return
    name = suite_id.rsplit("-v", 1)[0] if isinstance(suite_id, str) else None
    versions = sorted(i for i in every if i.rsplit("-v", 1)[0] == name)
    if versions:
        raise ValueError(f"{where}: {_shown(suite_id)} is not a shipped version of the suite {name!r} (this mrd-env "
                         f"ships {versions}): a suite of your own needs a name of its own")


def write_shipped_digests(path: str | Path | None = None) -> Path:
    """Write {id: digest} of every shipped suite to ``path`` (default :data:`SHIPPED_DIGESTS`), from the shipped
    files: what ``experiments.benchmark.references`` runs after it writes a suite into a plant's folder."""
    digests = {sid: s.digest for sid, s in sorted(suites().items())}
    out = write_json(path or SHIPPED_DIGESTS, {"format": DIGESTS_FORMAT, "digests": digests}, indent=1)
    _shipped_digests.cache_clear()
    return out


def _json_options(options: dict) -> dict:
    """Options as a JSON file gives them back (tuples as lists), so that a definition and its file agree."""
    return json.loads(json.dumps(options))


#: The name of a suite file's build record ends so (``<id>.build.json`` beside ``<id>.json``): what a build cost
#: (wall times, load, machine, backend), which differs from run to run, apart from the suite file, which does not.
BUILD_RECORD_SUFFIX = ".build.json"


def build_record_path(path: str | Path) -> Path:
    """The build record beside the suite file ``path``: ``car-comfort-v1.json`` → ``car-comfort-v1.build.json``."""
    path = Path(path)
    stem = path.name[:-len(".json")] if path.name.endswith(".json") else path.name
    return path.with_name(stem + BUILD_RECORD_SUFFIX)


def suite_path(plant: str, suite: "Suite | SuiteDefinition") -> Path:
    """Where the plant's folder ships the suite: ``mrd_env/plants/<plant>/suites/<name>-v<version>.json``."""
    return PLANTS_FOLDER / plant / "suites" / f"{suite.id}.json"


# --------------------------------------------------------------------------------------------- robustness twins

def nominal_values(env_id: str, options: dict) -> dict:
    """The preset values the bands of a twin scale: {"damper_params": {name: value}, "command": {name: value},
    "plant_params": {name: value}} of the environment ``env_id`` with ``options``."""
    import dataclasses

    import gymnasium as gym

    from . import envs  # noqa: F401  (registers the environments)

    env = gym.make(env_id, **{k: v for k, v in options.items() if k not in SENSOR_OPTIONS})
    try:
        u = env.unwrapped
        p = u.plant_params
        return {"damper_params": dict(vars(u.damper.params)), "command": dict(vars(u.damper.command)),
                "plant_params": {f.name: getattr(p, f.name) for f in dataclasses.fields(p)}}
    finally:
        env.close()


def _factor(rng, band) -> float:
    lo, hi = band
    return float(rng.uniform(lo, hi))


def draw_episode(bands: dict, nominal: dict, scenario_index: int, seed: int) -> dict:
    """One episode's draw of a robustness twin (environment options), from the generator seeded by
    ``(bands["seed"], scenario_index, seed)``, the bands drawn in this order:

    * ``damper_params``: {name: (lo, hi)} — the preset's value × U(lo, hi), each parameter on its own;
    * ``command``: {"eta": (lo, hi)} — the lag rate η × U(lo, hi); {"delay": (lo, hi)} — a pure delay U(lo, hi) s;
      given to the damper as ``damper_params["command"]``;
    * ``plant_params``: {name: (lo, hi)} — a scalar × U(lo, hi); a vector (the masses) × one factor per element;
      a matrix (stiffness, damping) × one factor for the whole matrix;
    * ``sensor_noise``: {sensor: (lo, hi)} — a std U(lo, hi) in the sensor's SI unit;
    * ``sensor_delay``: [k, ...] — one of these delays (control steps), equally likely.
    """
    import numpy as np

    rng = np.random.default_rng([int(bands["seed"]), int(scenario_index), int(seed)])
    out: dict = {}
    dp = {name: nominal["damper_params"][name] * _factor(rng, b) for name, b in bands.get("damper_params", {}).items()}
    cmd = {}
    for name, b in bands.get("command", {}).items():
        cmd[name] = nominal["command"][name] * _factor(rng, b) if name == "eta" else _factor(rng, b)
    if cmd:
        dp["command"] = cmd
    if dp:
        out["damper_params"] = dp
    pp = {}
    for name, b in bands.get("plant_params", {}).items():
        v = np.asarray(nominal["plant_params"][name], dtype=float)
        if v.ndim == 1:
            pp[name] = [float(x * _factor(rng, b)) for x in v]
        else:
            pp[name] = (v * _factor(rng, b)).tolist()
    if pp:
        out["plant_params"] = pp
    noise = {name: _factor(rng, b) for name, b in bands.get("sensor_noise", {}).items()}
    if noise:
        out["sensor_noise"] = noise
    if "sensor_delay" in bands:
        choices = list(bands["sensor_delay"])
        out["sensor_delay"] = int(choices[int(rng.integers(len(choices)))])
    return _json_options(out)


def draws(definition: SuiteDefinition, env_id: str) -> dict:
    """{episode label: draw} of a robustness twin (:func:`draw_episode` for every episode)."""
    if not definition.randomise:
        return {}
    out = {}
    for i, sc in enumerate(definition.scenarios):
        options = {**definition.options, **sc.options}
        if definition.folder:  # a spec's record files are in its folder
            from .envs.build import confine_files

            options = confine_files(options, definition.folder, f"suite {definition.id}")
        nominal = nominal_values(env_id, options)
        for seed in sc.seeds:
            out[sc.label(seed)] = draw_episode(definition.randomise, nominal, i, seed)
    return out
