"""The shear building's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Their
reference values ship beside this file (``<name>-v<version>.json``), computed by
``python -m experiments.benchmark.references --suite <name>``.

The benchmark building — the three-storey lab model with its damper in storey 2 (the profile's options) —
controlled at 10 ms: El Centro 1940 N-S and E-W replayed 5× faster (one episode each) and Kanai–Tajimi ground
motions with the nominal parameters (10 seeds), each episode cut to ``EPISODE_SECONDS`` so that one clairvoyant
solve stays under 2 minutes on the 2 shared cores of the machine that computed the references.
"""
from __future__ import annotations

from ....suites import SuiteDefinition, SuiteScenario
from .. import BENCHMARK_DAMPER_FLOORS

SEEDS = tuple(1_000_000 + i for i in range(10))
#: Every episode's length (s): El Centro's strong motion (its first 20 s replayed 5× faster) and its decay.
EPISODE_SECONDS = 4.0
CONTROL_DT = 0.01
SENSORS = ("abs_acc", "drift", "floor_vel", "damper_force", "damper_stroke", "damper_velocity", "ground_acc",
           "command")
CRITERIA = ("J1", "J2", "J3", "J4", "J5", "J6")
OPTIONS = {"damper_floors": BENCHMARK_DAMPER_FLOORS, "sensors": SENSORS}

SCENARIOS = (
    SuiteScenario("El Centro NS (×0.2 time)", {"ground_motion": "el_centro", "ground_motion_params": {"time_scale": 0.2},
                                               "episode_seconds": EPISODE_SECONDS}, (0,)),
    SuiteScenario("El Centro EW (×0.2 time)", {"ground_motion": "el_centro",
                                               "ground_motion_params": {"component": "EW", "time_scale": 0.2},
                                               "episode_seconds": EPISODE_SECONDS}, (0,)),
    SuiteScenario("Kanai–Tajimi", {"ground_motion": "kanai_tajimi", "episode_seconds": EPISODE_SECONDS}, SEEDS))

SEISMIC = SuiteDefinition(
    name="building-seismic", version=1,
    description="The benchmark building (three-storey lab model, Spencer–Dyke damper, spencer1997 preset, in storey "
                "2), 10 ms control, the lab model's sensors: El Centro 1940 N-S and E-W at ×0.2 time (one episode "
                f"each) and Kanai–Tajimi with the nominal parameters (10 seeds), {EPISODE_SECONDS:g} s each.",
    options=OPTIONS, control_dt=CONTROL_DT, scenarios=SCENARIOS, criteria=CRITERIA)

#: The robustness twin's bands (:func:`mrd_env.suites.draw_episode`), drawn per episode from seed 39.
ROBUST_BANDS = {
    "seed": 39,
    "damper_params": {name: (0.85, 1.15) for name in ("c0a", "c0b", "c1a", "c1b", "alpha_a", "alpha_b")},
    # the command lag: η × U(0.7, 1.3) and a pure delay U(0, 2) ms (the records replay 5× faster)
    "command": {"eta": (0.7, 1.3), "delay": (0.0, 0.002)},
    # each floor's mass × U(0.9, 1.1); the stiffness matrix × U(0.9, 1.1); the damping matrix × U(0.8, 1.2)
    "plant_params": {"masses": (0.9, 1.1), "K": (0.9, 1.1), "C": (0.8, 1.2)},
    "sensor_noise": {"abs_acc": (0.0, 0.05), "drift": (0.0, 5e-5), "floor_vel": (0.0, 0.001),
                     "damper_force": (0.0, 5.0), "damper_stroke": (0.0, 5e-5), "damper_velocity": (0.0, 0.001),
                     "ground_acc": (0.0, 0.05)},
    "sensor_delay": [0, 1],
}

ROBUST = SuiteDefinition(
    name="building-seismic-robust", version=1,
    description="building-seismic's episodes on a building and damper drawn per episode within stated bands "
                "(damper parameters ±15 %, command lag η ±30 % and a delay up to 2 ms, floor masses and stiffness "
                "±10 %, damping ±20 %, sensor noise and a sensor delay of 0 or 1 control step); the draws are stored "
                "per episode.",
    options=OPTIONS, control_dt=CONTROL_DT, scenarios=SCENARIOS, criteria=CRITERIA, randomise=ROBUST_BANDS)

#: The six-storey building's episodes (s): half of building-seismic's, El Centro's strongest motion (its first 10 s
#: replayed 5× faster). With four dampers the references of one 4 s episode had not finished after 17 min (load 7.3
#: on the 2 shared cores), so this suite has fewer and shorter episodes.
SIX_STOREY_SECONDS = 2.0
SIX_STOREY_SEEDS = SEEDS[:2]
#: The six-storey building with four dampers (preset ``six_storey``: two dampers in storey 1, two in storey 2), on
#: building-seismic's records and sensors, fewer and shorter episodes: its clairvoyant solves four command sequences.
SIX_STOREY = SuiteDefinition(
    name="building-six-storey", version=1,
    description="The six-storey lab-scale building (preset six_storey, a model of this project, not Jansen & Dyke's) "
                "with four Spencer–Dyke dampers (spencer1997 preset), two in storey 1 and two in storey 2, one "
                "command each, 10 ms control, the lab model's sensors: El Centro 1940 N-S and E-W at ×0.2 time (one "
                f"episode each) and Kanai–Tajimi with the nominal parameters ({len(SIX_STOREY_SEEDS)} seeds), "
                f"{SIX_STOREY_SECONDS:g} s each.",
    options={"plant_preset": "six_storey", "damper_floors": (1, 1, 2, 2), "sensors": SENSORS},
    control_dt=CONTROL_DT, criteria=CRITERIA,
    scenarios=tuple(SuiteScenario(sc.name, {**sc.options, "episode_seconds": SIX_STOREY_SECONDS},
                                  sc.seeds if len(sc.seeds) == 1 else SIX_STOREY_SEEDS) for sc in SCENARIOS))

SUITES = (SEISMIC, ROBUST, SIX_STOREY)
