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


def suites() -> dict[str, Suite]:
    """Every shipped suite by its id (``name-vN``): the JSON files of each plant folder's ``suites/``."""
    from .plants import plants

    out = {}
    for spec in plants().values():
        folder = Path(spec.module().__file__).parent / "suites"
        if not folder.is_dir():
            continue
        for path in sorted(folder.glob("*.json")):
            s = read_suite(inside(folder, path.name, what="suite file"))
            if s.plant != spec.name:
                raise ValueError(f"suite file {path}: its plant is {s.plant!r}, not the folder's {spec.name!r}")
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
