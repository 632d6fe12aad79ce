"""The plants as the commands see them: every plant's profile (:class:`mrd_env.plants.profile.PlantProfile`,
declared in its folder), resolved once per command from a ``--plant`` value and passed down.

The commands read these profiles and never branch on a plant's name; a new plant reaches every command through its
folder and its line in :data:`mrd_env.plants.PLANT_FOLDERS`.
"""
from __future__ import annotations

from mrd_env.plants import plant, plant_of_id, plants
from mrd_env.plants.profile import PlantProfile, TestCase

__all__ = ["PlantProfile", "TestCase", "PLANTS", "profile", "by_env_id", "plant_choices", "chosen_plants"]


def _profiles() -> dict[str, PlantProfile]:
    return {name: spec.profile for name, spec in plants().items()}


class _Profiles(dict):
    """{plant name: profile}, filled on first use (the profiles import their environments' modules)."""

    def _fill(self) -> None:
        if not dict.__len__(self):
            self.update(_profiles())

    def __getitem__(self, key):
        self._fill()
        return dict.__getitem__(self, key)

    def __iter__(self):
        self._fill()
        return dict.__iter__(self)

    def __len__(self):
        self._fill()
        return dict.__len__(self)

    def __contains__(self, key):
        self._fill()
        return dict.__contains__(self, key)

    def keys(self):
        self._fill()
        return dict.keys(self)

    def values(self):
        self._fill()
        return dict.values(self)

    def items(self):
        self._fill()
        return dict.items(self)


#: Every plant's profile by its name.
PLANTS: dict[str, PlantProfile] = _Profiles()


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
    """The values of a ``--plant`` option: every plant, and with ``both`` also "both" and "all"."""
    return sorted(plants()) + (["both", "all"] if both else [])


def chosen_plants(value: str) -> list[str]:
    """The plants of a ``--plant`` value: "both" (the published benchmark's plants), "all" or one plant."""
    published = [n for n, p in PLANTS.items() if p.published]
    if value == "both":
        return published
    if value == "all":
        return [*published, *sorted(set(PLANTS) - set(published))]
    return [profile(value).name]
