"""The quarter car's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Their
reference values ship beside this file (``<name>-v<version>.json``), computed by
``python -m experiments.benchmark.references --suite <name>``.

Every episode is 3 s long (a clairvoyant solve of a 3 s car episode takes 15–40 s on the 2 shared cores of the
machine that computed the references; a 10 s episode would cost three times as much): ISO 8608 class C and D
roads at 20 m/s and class A at 30 m/s, 10 seeds each, and the 5 cm bump; the controller runs at 10 ms.
"""
from __future__ import annotations

from ....suites import SuiteDefinition, SuiteScenario

#: The episodes' seeds: the held-out test seeds (``experiments.common.scenarios.HELD_OUT_SEED``, never trained
#: on, never used for validation).
SEEDS = tuple(1_000_000 + i for i in range(10))
#: Every episode's length (s).
EPISODE_SECONDS = 3.0
#: Every controller's control step (s).
CONTROL_DT = 0.01
#: The road-preview sensor the preview suite grants: the road height 10, 20, ..., 100 ms ahead of the wheel
#: (``experiments.common.scenarios.PREVIEW``).
PREVIEW = tuple(round(0.01 * k, 2) for k in range(1, 11))
#: What a test car measures (the environment's default sensors).
SENSORS = ("sprung_acc", "unsprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel", "damper_force",
           "command")
CRITERIA = ("acc_weighted_rms", "travel_rms", "travel_peak", "tyre_load_rms")


def _iso(road_class: str, speed: float) -> SuiteScenario:
    return SuiteScenario(f"ISO-{road_class} {speed:g} m/s",
                         {"road": "iso8608", "road_params": {"road_class": road_class, "speed": speed},
                          "episode_seconds": EPISODE_SECONDS}, SEEDS)


SCENARIOS = (_iso("C", 20.0), _iso("D", 20.0), _iso("A", 30.0),
             SuiteScenario("bump 5 cm", {"road": "bump", "road_params": {"height": 0.05, "length": 0.5, "speed": 10.0},
                                         "episode_seconds": EPISODE_SECONDS}, (0,)))

COMFORT = SuiteDefinition(
    name="car-comfort", version=1,
    description="Quarter car (set A, Spencer–Dyke damper, automotive preset), 10 ms control, the test car's "
                "sensors (no preview): ISO 8608 class C and D at 20 m/s and class A at 30 m/s (10 seeds each) and "
                "a 5 cm bump, 3 s each.",
    options={"sensors": SENSORS}, control_dt=CONTROL_DT, scenarios=SCENARIOS, criteria=CRITERIA)

PREVIEW_SUITE = SuiteDefinition(
    name="car-preview", version=1,
    description="car-comfort's episodes with the road-preview sensor granted to the controller: the road height "
                "10, 20, ..., 100 ms ahead of the wheel (sensor 'road_preview'), beside the test car's sensors. "
                "The same plant and episodes, so car-comfort's references.",
    options={"sensors": (*SENSORS, "road_preview"), "preview": PREVIEW}, control_dt=CONTROL_DT,
    scenarios=SCENARIOS, criteria=CRITERIA, references_of="car-comfort")

#: The robustness twin's bands (:func:`mrd_env.suites.draw_episode`), drawn per episode from seed 39.
ROBUST_BANDS = {
    "seed": 39,
    # the damper's force-scaling parameters, each × U(0.85, 1.15) (unit-to-unit and temperature spread)
    "damper_params": {name: (0.85, 1.15) for name in ("c0a", "c0b", "c1a", "c1b", "alpha_a", "alpha_b")},
    # the command lag: η × U(0.7, 1.3) (190 1/s nominal) and a pure delay U(0, 5) ms (the current driver)
    "command": {"eta": (0.7, 1.3), "delay": (0.0, 0.005)},
    # sprung and unsprung masses (load), suspension and tyre stiffnesses (tyre pressure), each × U(0.9, 1.1)
    "plant_params": {name: (0.9, 1.1) for name in ("m_s", "m_u", "k_s", "k_t")},
    # sensor noise std, U(0, hi) in SI units
    "sensor_noise": {"sprung_acc": (0.0, 0.05), "unsprung_acc": (0.0, 0.2), "travel": (0.0, 5e-4),
                     "travel_rate": (0.0, 0.005), "sprung_vel": (0.0, 0.005), "unsprung_vel": (0.0, 0.01),
                     "damper_force": (0.0, 10.0)},
    # the sensors' delay: 0 or 1 control step (0 or 10 ms)
    "sensor_delay": [0, 1],
}

ROBUST = SuiteDefinition(
    name="car-comfort-robust", version=1,
    description="car-comfort's episodes on a car and damper drawn per episode within stated bands (damper "
                "parameters ±15 %, command lag η ±30 % and a delay up to 5 ms, masses and stiffnesses ±10 %, "
                "sensor noise and a sensor delay of 0 or 1 control step); the draws are stored per episode.",
    options={"sensors": SENSORS}, control_dt=CONTROL_DT, scenarios=SCENARIOS, criteria=CRITERIA,
    randomise=ROBUST_BANDS)

PREVIEW_ROBUST = SuiteDefinition(
    name="car-preview-robust", version=1,
    description="car-comfort-robust's episodes (the same drawn cars, dampers, sensor noise and sensor delays) with "
                "the road-preview sensor of car-preview granted to the controller; the preview itself is exact (no "
                "noise band: the draws are car-comfort-robust's, so its references).",
    options={"sensors": (*SENSORS, "road_preview"), "preview": PREVIEW}, control_dt=CONTROL_DT,
    scenarios=SCENARIOS, criteria=CRITERIA, references_of="car-comfort-robust", randomise=ROBUST_BANDS)

SUITES = (COMFORT, PREVIEW_SUITE, ROBUST, PREVIEW_ROBUST)
