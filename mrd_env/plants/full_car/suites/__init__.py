"""The full car's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Their
reference values ship beside this file (``<name>-v<version>.json``), computed by
``python -m experiments.benchmark.references --suite <name>``.

Short and few episodes, said plainly: every episode is 1 s long and each random-road scenario has 3 seeds, not the
quarter car's 3 s and 10 seeds. The references' clairvoyant optimises four command sequences: one solve of a 1 s
class-C episode took 68 s on the 2 shared cores of the machine that computed them (load 5.5), the procedure's two
solves, warm starts and bound 150 s per episode; 10 seeds of 3 s would have taken hours. ISO 8608 class C and D
two-track roads at 20 m/s and class A at 30 m/s, and a 5 cm bump under the left wheels (front at 0.2 s, rear at
0.48 s); the controller runs at 10 ms.
"""
from __future__ import annotations

from ....suites import SuiteDefinition, SuiteScenario

#: The episodes' seeds: the held-out test seeds (``experiments.common.scenarios.HELD_OUT_SEED``, never trained
#: on, never used for validation).
SEEDS = tuple(1_000_000 + i for i in range(3))
#: Every episode's length (s).
EPISODE_SECONDS = 1.0
#: Every controller's control step (s).
CONTROL_DT = 0.01
#: The road-preview sensor the preview suite grants: each wheel's road height 10, 20, ..., 100 ms ahead
#: (``experiments.common.scenarios.PREVIEW``, the quarter car's).
PREVIEW = tuple(round(0.01 * k, 2) for k in range(1, 11))
#: What a test car measures (the environment's default sensors).
SENSORS = ("body_acc", "pitch_acc", "roll_acc", "travel", "travel_rate", "body_vel_at_corners", "wheel_vel",
           "damper_force", "command")
CRITERIA = ("comfort_rms", "acc_weighted_rms", "travel_peak", "tyre_load_ratio")


def _iso(road_class: str, speed: float) -> SuiteScenario:
    return SuiteScenario(f"ISO-{road_class} {speed:g} m/s",
                         {"road": "iso8608", "road_params": {"road_class": road_class, "speed": speed},
                          "episode_seconds": EPISODE_SECONDS}, SEEDS)


SCENARIOS = (_iso("C", 20.0), _iso("D", 20.0), _iso("A", 30.0),
             SuiteScenario("bump 5 cm left", {"road": "bump",
                                              "road_params": {"height": 0.05, "length": 0.5, "speed": 10.0,
                                                              "t_start": 0.2, "side": "left"},
                                              "episode_seconds": EPISODE_SECONDS}, (0,)))

COMFORT = SuiteDefinition(
    name="car-full", version=3,
    description="Full car (the 7-DOF sedan, Spencer–Dyke dampers at the four corners, automotive preset), 10 ms "
                "control, the test car's sensors (no preview): two-track ISO 8608 class C and D roads at 20 m/s and "
                "class A at 30 m/s (3 seeds each) and a 5 cm bump under the left wheels, 1 s each — fewer and "
                "shorter episodes than the quarter car's (a clairvoyant solve over four command sequences costs "
                "about a minute per second of episode). The active bound R_b is the quarter car's method, not "
                "checked separately on the full car. On the bump every clairvoyant solve stopped with L-BFGS-B's "
                "ABNORMAL line search: its R_c is the best of them, not an optimum (a share there is not a share "
                "of the achievable gain). Version 2: the car starts at rest on the roads' initial heights (the "
                "dampers' internal states at rest at the start's strokes, their static forces in the equilibrium, "
                "zero stroke rates); version 1's episodes started with the dampers out of rest. Version 3: the roads no "
                "longer depend on the preview option (version 2's preview twin drove other roads than its references'"
                ").",
    options={"sensors": SENSORS}, control_dt=CONTROL_DT, scenarios=SCENARIOS, criteria=CRITERIA)

PREVIEW_SUITE = SuiteDefinition(
    name="car-full-preview", version=3,
    description="car-full's episodes with the road-preview sensor granted to the controller: each wheel's road "
                "height 10, 20, ..., 100 ms ahead (sensor 'road_preview'), beside the test car's sensors. The same "
                "plant and episodes, so car-full's references.",
    options={"sensors": (*SENSORS, "road_preview"), "preview": PREVIEW}, control_dt=CONTROL_DT,
    scenarios=SCENARIOS, criteria=CRITERIA, references_of="car-full")

SUITES = (COMFORT, PREVIEW_SUITE)
