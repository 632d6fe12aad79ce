"""The plants as the commands see them: every plant's profile (:class:`mrd_env.plants.profile.PlantProfile`,
declared in its folder), resolved once per command from a ``--plant`` value and passed down.

The commands read these profiles and never branch on a plant's name; a new plant reaches every command through its
folder and its line in :data:`mrd_env.plants.PLANT_FOLDERS`.
"""
from __future__ import annotations

import warnings

from mrd_env.plants import plant, plant_of_id, plants
from mrd_env.plants.profile import PlantProfile, TestCase

__all__ = ["PlantProfile", "TestCase", "profiles", "profile", "by_env_id", "plant_choices", "plant_name",
           "default_plant", "chosen_plants"]


def profiles() -> dict[str, PlantProfile]:
    """Every plant's profile by its name, in registry order (each imports its environment's module on first use)."""
    return {name: spec.profile for name, spec in plants().items()}


def profile(name: str | PlantProfile) -> PlantProfile:
    """The profile of plant ``name`` (a profile is returned as it is); ``ValueError`` naming the plants otherwise."""
    if isinstance(name, PlantProfile):
        return name
    return plant(name).profile


def by_env_id(env_id: str) -> PlantProfile | None:
    """The profile whose environment is ``env_id`` (None if none is)."""
    spec = plant_of_id(env_id)
    return None if spec is None else spec.profile


def plant_choices(both: bool = False) -> list[str]:
    """The values of a ``--plant`` option: every plant, and with ``both`` also "both" and "all" (a former name is
    taken too, :func:`plant_name`, but not offered)."""
    return sorted(plants()) + (["both", "all"] if both else [])


def plant_name(value: str) -> str:
    """A ``--plant`` value in today's spelling (argparse's ``type``, checked against :func:`plant_choices` after it):
    a former name, after its DeprecationWarning on stderr; anything else as it is."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", DeprecationWarning)  # Python hides it outside __main__: a command shows it
        try:
            return plant(value).name
        except ValueError:
            return value  # "both", "all", or a typo that argparse's choices name


def default_plant() -> str:
    """The ``--plant`` of the commands that take one plant (train, tune) when none is given: the plant whose profile
    says so (:attr:`PlantProfile.train_default`)."""
    chosen = [name for name, p in profiles().items() if p.train_default]
    if len(chosen) != 1:
        raise ValueError(f"exactly one plant profile must set train_default, got {chosen}")
    return chosen[0]


def chosen_plants(value: str) -> list[PlantProfile]:
    """The plants of a ``--plant`` value: "both" (the published benchmark's plants), "all" or one plant (a former
    name after a DeprecationWarning)."""
    every = profiles()
    published = [p for p in every.values() if p.published]
    if value == "both":
        return published
    if value == "all":
        return [*published, *(every[n] for n in sorted(every) if not every[n].published)]
    return [profile(value)]
