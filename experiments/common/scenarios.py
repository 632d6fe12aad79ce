"""The scenarios of the training and teaching experiments, built from a plant's profile (:class:`.plants.PlantProfile`,
where each plant's environment options, training distribution and test scenarios are written): what agents train on
(``profile.training``), what selects the best agent during training (:func:`validation`: the training distribution on
seeds training never draws), and the fixed held-out scenarios the labs (3-5) and two accuracy measurements
(``reward_separation``, ``bound_bracket``) run on (:func:`held_out_scenarios`).

The held-out scenarios are the labs' scenarios, **not a benchmark**: no command scores on them. Controllers are scored
on the frozen suites (:mod:`mrd_env.suites`, ``mrd-env benchmark`` and ``mrd-env score``), whose episodes and
references are stored with them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .plants import PlantProfile, profiles

#: Seeds of validation and test episodes start here; training draws from SB3's seeds (the run's seed + env index),
#: far below.
HELD_OUT_SEED = 1_000_000
#: The car's road-preview sensor where a comparison grants it (MPC with preview): the road height 10, 20, ..., 100 ms
#: ahead of the wheel (0.2–2 m at 20 m/s, what a camera or lidar preview suspension measures).
PREVIEW = tuple(round(0.01 * k, 2) for k in range(1, 11))


def preview_options(plant: PlantProfile, options: dict) -> dict:
    """``options`` with the road-preview sensor added to its sensors (a plant whose profile has ``preview``)."""
    if not plant.preview:
        having = " and the ".join(p.title for p in profiles().values() if p.preview)
        raise ValueError(f"road preview is a sensor of the {having}, not of the {plant.title}")
    sensors = tuple(options.get("sensors") or plant.spec.module("env").DEFAULT_SENSORS)
    return {**options, "sensors": (*sensors, "road_preview"), "preview": PREVIEW}


@dataclass(frozen=True)
class Scenario:
    """An environment set-up scored over ``seeds`` (one vector environment, one episode per seed)."""

    name: str
    env_id: str
    options: dict = field(default_factory=dict)
    seeds: tuple = (0,)

    def label(self, seed: int) -> str:
        return f"{self.name} s{seed}" if len(self.seeds) > 1 else self.name


def validation(plant: PlantProfile, episodes: int = 8) -> list[Scenario]:
    """The training distribution on seeds training never draws (selects the best agent during training)."""
    return [Scenario("validation", plant.env_id, dict(plant.training),
                     tuple(HELD_OUT_SEED + 500_000 + i for i in range(episodes)))]


def held_out_scenarios(plant: PlantProfile, seeds: int = 3, quick: bool = False,
                       plant_options: dict | None = None) -> list[Scenario]:
    """The labs' held-out scenarios (:attr:`.plants.PlantProfile.tests`; not a benchmark: see the module docstring),
    on the plant of every experiment (``plant.options``; e.g. the building's damper in storey 2) or on the environment
    options ``plant_options`` (``{}`` is the environment's default plant, e.g. the lab building with its damper in
    storey 1 as Dyke et al. built it)."""
    env_plant = dict(plant.options if plant_options is None else plant_options)
    s = tuple(HELD_OUT_SEED + i for i in range(1 if quick else seeds))
    return [Scenario(name, plant.env_id, options, s) if seeded else Scenario(name, plant.env_id, options)
            for name, options, seeded in plant.tests(env_plant, quick)]


def base_scenario(label: str) -> str:
    """The scenario of an episode label (without the seed suffix)."""
    head, _, tail = label.rpartition(" s")
    return head if tail.isdigit() and head else label
