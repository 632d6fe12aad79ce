"""The plants, one folder each (``mrd_env/plants/<name>/``): the physics with its parameter sets, the environment
assembly, the renderer, the metrics, the nominal references the model-based laws design on, and the experiments'
profile (scenarios, laws, tables). Each folder declares its :class:`~.spec.PlantSpec` once (``SPEC`` in its
``__init__``); the registry below is one line per plant, and the Gymnasium ids, entry points, lazy imports and
the CLI's choices are generated from it (:mod:`.registry`).

>>> from mrd_env.plants import plant
>>> plant("quarter_car").rl_id
'mrd_env/QuarterCar-v1'
"""
from __future__ import annotations

import importlib
import warnings

from ..mechanics import CoupledPlant, LinearPlant
from .spec import PlantSpec

#: The registry: one line per plant, its folder's name.
PLANT_FOLDERS = (
    "shear_building",
    "quarter_car",
    "half_car",
    "isolator",
    "full_car",
)

_SPECS: dict[str, PlantSpec] = {}


def plants() -> dict[str, PlantSpec]:
    """Every plant's spec by name, in registry order (each folder's ``SPEC``)."""
    if not _SPECS:
        for folder in PLANT_FOLDERS:
            spec = importlib.import_module(f"{__name__}.{folder}").SPEC
            if spec.name != folder:
                raise ValueError(f"the spec of mrd_env/plants/{folder}/ is named {spec.name!r}: a plant's name is "
                                 f"its folder's")
            _SPECS[spec.name] = spec
    return dict(_SPECS)


def plant(name: str | PlantSpec) -> PlantSpec:
    """The spec of plant ``name`` (a spec is returned as it is); a former spelling works after a
    ``DeprecationWarning``; ``ValueError`` naming the plants otherwise."""
    if isinstance(name, PlantSpec):
        return name
    every = plants()
    if isinstance(name, str) and name in every:
        return every[name]
    for spec in every.values():
        if name in spec.former_names:
            warnings.warn(f"plant {name!r} is now called {spec.name!r}", DeprecationWarning, stacklevel=2)
            return spec
    raise ValueError(f"plant must be one of {list(every)}, got {name!r}")


def plant_of_env(env) -> PlantSpec:
    """The spec of an environment's plant (scalar or vector, wrapped or not)."""
    return plant(getattr(env, "unwrapped", env).plant_kind)


def plant_of_id(env_id: str) -> PlantSpec | None:
    """The spec whose id (current or former) is ``env_id`` (None if none is)."""
    return next((s for s in plants().values() if env_id in (*s.ids, *s.former_ids)), None)


def suite_definitions() -> dict[str, tuple]:
    """Every suite definition of the plants' profiles (their specs, ``<plant>/suites/specs/``) by its id: {id:
    (plant's name, env id, definition)}; ``ValueError`` if two plants declare the same suite name, or a plant's
    spec names another plant."""
    out, names = {}, {}
    for spec in plants().values():
        for d in spec.profile.suites:
            if d.plant and d.plant != spec.name:
                raise ValueError(f"suite {d.id} is declared by the {spec.name}'s profile but names the plant "
                                 f"{d.plant!r}")
            if d.name in names and names[d.name] != spec.name:
                raise ValueError(f"suite {d.name!r} is declared by two plants ({names[d.name]}, {spec.name})")
            names[d.name] = spec.name
            if d.id in out:
                raise ValueError(f"suite {d.id} is declared twice")
            out[d.id] = (spec.name, _suite_env_id(spec, d, f"suite {d.id}"), d)
    return out


def suite_spec(path) -> tuple:
    """(plant's name, env id, :class:`~mrd_env.suites.SuiteDefinition`) of the suite spec file ``path``
    (:func:`mrd_env.suites.read_spec`): its ``env_id`` one of its plant's ids (left out: the plant's physics id).
    One ``ValueError`` naming the file and the field otherwise."""
    from ..suites import read_spec

    d = read_spec(path)
    spec = plant(d.plant)
    return spec.name, _suite_env_id(spec, d, f"suite spec {path}"), d


def _suite_env_id(spec: PlantSpec, d, where: str) -> str:
    """The environment of the suite ``d`` on the plant ``spec``: its ``env_id`` if one of the plant's, else (none
    given) the plant's physics id (commands in V or A, the references' environment)."""
    if not d.env_id:
        return spec.physics_id
    if d.env_id not in spec.ids:
        raise ValueError(f"{where}: env_id must be one of the {spec.name}'s environments {list(spec.ids)} (or left "
                         f"out: {spec.physics_id}), got {d.env_id[:80]!r}")
    return d.env_id


def suite_definition(name: str) -> tuple:
    """(plant's name, env id, :class:`~mrd_env.suites.SuiteDefinition`) of the suite ``name`` (``name-vN``, or a name: its latest
    version); ``ValueError`` naming the suites otherwise."""
    every = suite_definitions()
    if name in every:
        return every[name]
    versions = sorted((d.version, k) for k, (_, _, d) in every.items() if d.name == name)
    if versions:
        return every[versions[-1][1]]
    raise ValueError(f"suite must be one of {sorted(every)}, got {name!r}")


def __getattr__(name: str):
    """The plants' public names, imported on first use: the environment classes (``QuarterCarEnv``,
    ``QuarterCarVectorEnv``, ...), the parameter classes and presets (``QuarterCarParams``, ...)."""
    for spec in plants().values():
        if name in (spec.env_class, spec.vector_env_class):
            return getattr(spec.module("env"), name)
        folder = spec.module()
        if name in getattr(folder, "__all__", ()) and name != spec.name:
            return getattr(folder, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["PLANT_FOLDERS", "PlantSpec", "plants", "plant", "plant_of_env", "plant_of_id", "suite_definitions",
           "suite_definition", "suite_spec", "CoupledPlant",
           "LinearPlant"]
