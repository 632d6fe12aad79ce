"""The scenarios of every experiment, in one place: what agents train on, what selects the best agent during
training (validation), and what everything is scored on (the held-out test scenarios, never trained on).

Quarter car — training: a new ISO 8608 road per episode, class B, C or D at a speed drawn in [10, 30] m/s;
validation: the same distribution with seeds training never draws; test: class C and D at 20 m/s (unseen
seeds), class A at 30 m/s (a class never trained on) and a 5 cm bump (a road shape never trained on).

Building (the three-storey lab model with its damper in storey 2, see ``PLANT``) — training: Kanai–Tajimi ground
motions with random ω_g ∈ [10, 25] rad/s, ζ_g ∈ [0.3, 0.8], PGA ∈ [0.1, 0.5] g, and the PEER records of Loma Prieta
1989, San Fernando 1971 and Northridge 1994 scaled to a random PGA in [0.15, 0.45] g, all replayed 5× faster (the
lab model); validation: that distribution, unseen seeds; test: El Centro 1940 N-S and E-W (records never trained
on) and Kanai–Tajimi with the nominal parameters (unseen seeds).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import gymnasium.logger  # noqa: F401  (it installs a DeprecationWarning filter when first imported: ours goes first)

from mrd_env.constants import GRAVITY as G

# The experiments use the physics-level -v0 ids on purpose (laws at 1 ms, commands in V or A; see mrd_env.envs.V1):
# Gymnasium's note that a -v1 exists is for users of gym.make, not for every line of a report. Every command imports
# this module (and so do the sweep's worker processes, through the tasks' modules).
warnings.filterwarnings("ignore", message=r".*mrd_env/\w+-v0 is out of date", category=DeprecationWarning)

ENV_IDS = {"quarter_car": "mrd_env/QuarterCar-v0", "building": "mrd_env/ShearBuilding-v0"}
#: Seeds of validation and test episodes start here; training draws from SB3's seeds (the run's seed + env index),
#: far below.
HELD_OUT_SEED = 1_000_000
#: The plant of every experiment (training, validation, test scenarios, benchmark), as environment options. The
#: building's damper sits in storey 2 (between floors 1 and 2). In storey 1 — the lab model's own place and the
#: environment's default — passive-on is within 0.5 % of the best law at any control rate on the test records
#: (El Centro N-S: passive-on −0.392, clipped-optimal at 1 ms −0.391), so no command policy can be told apart
#: from passive-on; in storey 2 clipped-optimal at 1 ms is 15–18 % better than passive-on on the test records
#: (``tests/test_evolution.py`` checks El Centro N-S).
PLANT = {"quarter_car": {}, "building": {"damper_floors": (2,)}}
#: The car's road-preview sensor where a comparison grants it (MPC with preview): the road height 10, 20, ..., 100 ms
#: ahead of the wheel (0.2–2 m at 20 m/s, what a camera or lidar preview suspension measures).
PREVIEW = tuple(round(0.01 * k, 2) for k in range(1, 11))


def preview_options(plant: str, options: dict) -> dict:
    """``options`` with the road-preview sensor added to its sensors (the car only)."""
    if plant != "quarter_car":
        raise ValueError(f"road preview is a sensor of the quarter car, not of the {plant}")
    from mrd_env.envs.quarter_car import DEFAULT_SENSORS

    sensors = tuple(options.get("sensors") or DEFAULT_SENSORS)
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


TRAINING = {
    "quarter_car": {"road": {"kind": "iso8608", "road_class": ["B", "C", "D"], "speed": (10.0, 30.0)},
                    "episode_seconds": 10.0},
    "building": {**PLANT["building"], "ground_motion": {"kind": "mixture", "sources": [
        {"kind": "kanai_tajimi", "omega_g": (10.0, 25.0), "zeta_g": (0.3, 0.8), "pga": (0.1 * G, 0.5 * G),
         "duration": 10.0},
        {"kind": "peer_records", "names": ["loma_prieta_1989_corralitos_000", "loma_prieta_1989_corralitos_090",
                                           "san_fernando_1971_pacoima_164", "san_fernando_1971_pacoima_254",
                                           "northridge05_1994_sylmar_090", "northridge05_1994_sylmar_360"],
         "pga": (0.15 * G, 0.45 * G)}]}},
}


def validation(plant: str, episodes: int = 8) -> list[Scenario]:
    """The training distribution on seeds training never draws (selects the best agent during training)."""
    return [Scenario("validation", ENV_IDS[plant], dict(TRAINING[plant]),
                     tuple(HELD_OUT_SEED + 500_000 + i for i in range(episodes)))]


def held_out_scenarios(plant: str, seeds: int = 3, quick: bool = False,
                       plant_options: dict | None = None) -> list[Scenario]:
    """The held-out scenarios every controller and agent is scored on, on the plant ``PLANT[plant]`` (or the
    environment options ``plant_options``: ``{}`` is the environment's default plant, e.g. the lab building
    with its damper in storey 1 as Dyke et al. built it)."""
    if plant not in ENV_IDS:
        raise ValueError(f"plant must be 'quarter_car' or 'building', got {plant!r}")
    env_plant = dict(PLANT[plant] if plant_options is None else plant_options)
    s = tuple(HELD_OUT_SEED + i for i in range(1 if quick else seeds))
    dur = 3.0 if quick else 10.0
    if plant == "quarter_car":
        out = [Scenario(f"ISO-{c} 20 m/s", ENV_IDS[plant],
                        dict(**env_plant, road="iso8608", road_params={"road_class": c, "speed": 20.0},
                             episode_seconds=dur), s)
               for c in ("C", "D")]
        if not quick:
            out.append(Scenario("ISO-A 30 m/s", ENV_IDS[plant],
                                dict(**env_plant, road="iso8608", road_params={"road_class": "A", "speed": 30.0},
                                     episode_seconds=dur), s))
            out.append(Scenario("bump 5 cm", ENV_IDS[plant],
                                dict(**env_plant, road="bump",
                                     road_params={"height": 0.05, "length": 0.5, "speed": 10.0},
                                     episode_seconds=3.0)))
        return out
    # the building
    out = [Scenario("El Centro NS (×0.2 time)", ENV_IDS[plant],
                    dict(**env_plant, ground_motion="el_centro", ground_motion_params={"time_scale": 0.2},
                         **({"episode_seconds": 4.0} if quick else {})))]
    if not quick:
        out.append(Scenario("El Centro EW (×0.2 time)", ENV_IDS[plant],
                            dict(**env_plant, ground_motion="el_centro",
                                 ground_motion_params={"component": "EW", "time_scale": 0.2})))
        out.append(Scenario("Kanai–Tajimi", ENV_IDS[plant],
                            dict(**env_plant, ground_motion="kanai_tajimi", episode_seconds=10.0), s))
    return out
