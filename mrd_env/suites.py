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
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from .storage import inside, write_json

#: The suite files' format (bumped when the fields change).
FORMAT = "mrd-env-suite"
FORMAT_VERSION = 1


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


@dataclass(frozen=True)
class SuiteDefinition:
    """What a plant's profile declares of a suite (:attr:`mrd_env.plants.profile.PlantProfile.suites`): everything
    but the references, which ``python -m experiments.scripts.suite_references --suite <name>`` computes once and
    ships in ``mrd_env/plants/<plant>/suites/<name>-v<version>.json``.

    ``options``: the environment options of every episode (damper, damper floors, sensors — ``road_preview``
    among them says the controller has the road preview); ``scenarios``: each scenario's own options and seeds;
    ``criteria``: the episode metrics reported beside the share; ``references_of``: the name of the suite whose
    references this one shares (the same episodes on the same plant, only the sensors differ); ``randomise``: a
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

    @property
    def id(self) -> str:
        return f"{self.name}-v{self.version}"

    def suite(self, plant: str, env_id: str, draws: dict | None = None) -> "Suite":
        """The suite without references (``draws``: a twin's per-episode draws, :func:`draws`)."""
        randomised = _json_options({"bands": self.randomise, "draws": draws or {}}) if self.randomise else {}
        return Suite(name=self.name, version=self.version, plant=plant, env_id=env_id, description=self.description,
                     options=_json_options(self.options), control_dt=float(self.control_dt),
                     scenarios=tuple(SuiteScenario(sc.name, _json_options(sc.options), tuple(int(x) for x in sc.seeds))
                                     for sc in self.scenarios),
                     criteria=tuple(self.criteria), randomised=randomised)


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
        return _json_options({**self.options, **scenario.options, **draw})

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


def from_json(data: dict, where: str = "suite") -> Suite:
    """A :class:`Suite` from its JSON content, after checking its format and digest (``ValueError`` naming
    ``where`` otherwise)."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where} is not an mrd-env suite (format must be {FORMAT!r})")
    if data.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{where}: suite format version {data.get('format_version')!r}, this mrd-env reads "
                         f"{FORMAT_VERSION}")
    if data.get("digest") != content_digest(data):
        raise ValueError(f"{where}: its content does not match its digest (edited or damaged): refused")
    refs = {k: Reference(**{f: (math.nan if v is None else v) for f, v in r.items()})
            for k, r in data["references"].items()}
    return Suite(name=data["name"], version=int(data["version"]), plant=data["plant"], env_id=data["env_id"],
                 description=data["description"], options=data["options"], control_dt=float(data["control_dt"]),
                 scenarios=tuple(SuiteScenario(s["name"], s["options"], tuple(int(x) for x in s["seeds"]))
                                 for s in data["scenarios"]),
                 criteria=tuple(data["criteria"]), references=refs, procedure=data.get("procedure", {}),
                 randomised=data.get("randomised", {}), digest=data["digest"])


def write_suite(suite: Suite, path: str | Path) -> Path:
    """Write ``suite`` to ``path`` atomically, with the digest of its content."""
    data = suite.to_json()
    data["digest"] = content_digest(data)
    return write_json(path, data, indent=1, sort_keys=False, allow_nan=False)


def read_suite(path: str | Path) -> Suite:
    """The suite in the file ``path`` (its format and digest checked)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"suite file {path}: cannot be read ({exc})") from None
    return from_json(data, where=f"suite file {path}")


#: The plants' folders, where each ships its suites (``<plant>/suites/*.json``): found by path, so that this
#: module, which the plants' suite definitions import, imports no plant.
PLANTS_FOLDER = Path(__file__).resolve().parent / "plants"


def suites() -> dict[str, Suite]:
    """Every shipped suite by its id (``name-vN``): the JSON files of each plant folder's ``suites/``."""
    out = {}
    for folder in sorted(PLANTS_FOLDER.glob("*/suites")):
        for path in sorted(folder.glob("*.json")):
            s = read_suite(inside(folder, path.name, what="suite file"))
            if s.plant != folder.parent.name:
                raise ValueError(f"suite file {path}: its plant is {s.plant!r}, not the folder's "
                                 f"{folder.parent.name!r}")
            out[s.id] = s
    return out


def suite(name: str) -> Suite:
    """The shipped suite ``name`` (``car-comfort-v1``; a name without version: its latest), or a suite file's
    path; ``ValueError`` naming the suites otherwise."""
    if isinstance(name, str) and name.endswith(".json"):
        return read_suite(name)
    every = suites()
    if name in every:
        return every[name]
    versions = sorted((s.version, s) for s in every.values() if s.name == name)
    if versions:
        return versions[-1][1]
    raise ValueError(f"suite must be one of {sorted(every)} (or a suite file), got {name!r}")


def _json_options(options: dict) -> dict:
    """Options as a JSON file gives them back (tuples as lists), so that a definition and its file agree."""
    return json.loads(json.dumps(options))


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
        nominal = nominal_values(env_id, {**definition.options, **sc.options})
        for seed in sc.seeds:
            out[sc.label(seed)] = draw_episode(definition.randomise, nominal, i, seed)
    return out
