"""What the registry knows of a plant: its :class:`PlantSpec`, declared once in its folder
(``mrd_env/plants/<name>/__init__.py``). Everything else is generated from it: the Gymnasium ids and entry points,
the vector entry points, the lazy imports, the CLI's ``--plant`` choices.

A spec is plain data that imports nothing heavy, so that ``import mrd_env`` (which registers every plant) stays
cheap; the plant's environment module and its experiment profile are imported on first use.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class PlantSpec:
    """One plant, as the library and the commands see it.

    ``name`` is the plant's one spelling: its folder (``mrd_env/plants/<name>/``), ``--plant <name>``, the
    environment's ``plant_kind`` and the key of every table. ``id_name`` is the same name in Gymnasium's
    CamelCase: the ids ``mrd_env/<id_name>Physical-v0`` (the physics-level set-up: 1 ms control, commands in V or
    A) and ``mrd_env/<id_name>-v1`` (the RL set-up: :data:`mrd_env.envs.RL_DEFAULTS` and ``v1_options``)."""

    name: str
    id_name: str
    title: str                                        #: in prose and figure titles
    summary: str                                      #: one line for ``--help`` and the docs
    #: options of the v1 id beyond :data:`mrd_env.envs.RL_DEFAULTS` (JSON values: lists, not tuples, so that the
    #: specs survive ``EnvSpec.to_json``/``from_json``)
    v1_options: dict = field(default_factory=dict)
    #: former ids, each making the physics-level set-up after a warning (agents saved before keep loading)
    former_ids: tuple[str, ...] = ()
    #: former spellings of ``name`` that ``--plant`` and :func:`mrd_env.plants.plant` still take, with a warning
    former_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name != self.name.lower():
            raise ValueError(f"PlantSpec.name must be a lower-case identifier (the folder's name), got {self.name!r}")
        if not self.id_name.isidentifier() or not self.id_name[:1].isupper():
            raise ValueError(f"PlantSpec.id_name must be a CamelCase identifier, got {self.id_name!r}")

    # --- generated names -------------------------------------------------------------------------------------
    @property
    def package(self) -> str:
        """The plant's folder as a module: ``mrd_env.plants.<name>``."""
        return f"mrd_env.plants.{self.name}"

    @property
    def env_module(self) -> str:
        """The module of the plant's environment classes: ``mrd_env.plants.<name>.env``."""
        return f"{self.package}.env"

    @property
    def env_class(self) -> str:
        return f"{self.id_name}Env"

    @property
    def vector_env_class(self) -> str:
        return f"{self.id_name}VectorEnv"

    @property
    def physics_id(self) -> str:
        """The physics-level id: 1 ms control, commands in V or A, the plant as built."""
        return f"mrd_env/{self.id_name}Physical-v0"

    @property
    def rl_id(self) -> str:
        """The RL id: a 10 ms control step and normalised actions (:data:`mrd_env.envs.RL_DEFAULTS`)."""
        return f"mrd_env/{self.id_name}-v1"

    @property
    def ids(self) -> tuple[str, ...]:
        return (self.physics_id, self.rl_id)

    # --- what is imported on first use -----------------------------------------------------------------------
    def module(self, part: str = "") -> Any:
        """The plant's folder (or one of its modules: ``"env"``, ``"profile"``, ...), imported."""
        return importlib.import_module(f"{self.package}.{part}" if part else self.package)

    @property
    def scalar_env(self) -> type:
        return getattr(self.module("env"), self.env_class)

    @property
    def vector_env(self) -> type:
        return getattr(self.module("env"), self.vector_env_class)

    @property
    def profile(self):
        """The plant as the experiments see it (:class:`mrd_env.plants.profile.PlantProfile`): its scenarios,
        laws, metrics and figures' layout, in ``mrd_env/plants/<name>/profile.py``."""
        return self.module("profile").PROFILE
