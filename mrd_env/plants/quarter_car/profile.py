"""What the experiments run on the quarter car (:class:`~mrd_env.plants.profile.PlantProfile`).

Quarter car — training: a new ISO 8608 road per episode, class B, C or D at a speed drawn in [10, 30] m/s;
validation: the same distribution with seeds training never draws; test (the labs' held-out scenarios): class C and
D at 20 m/s (unseen seeds), class A at 30 m/s (a class never trained on) and a 5 cm bump (a road shape never trained
on).
"""
from __future__ import annotations

from ..profile import PlantProfile, TestCase
from . import SPEC
from .suites import SUITES
from .physics import quarter_car


def road_tests(plant: dict, quick: bool, bump: bool = True) -> list[TestCase]:
    """ISO 8608 class C and D at 20 m/s (unseen seeds), class A at 30 m/s (an unseen class) and, with ``bump``, a
    5 cm bump (an unseen shape): the test roads of a car."""
    dur = 3.0 if quick else 10.0
    out = [(f"ISO-{c} 20 m/s", dict(**plant, road="iso8608", road_params={"road_class": c, "speed": 20.0},
                                    episode_seconds=dur), True) for c in ("C", "D")]
    if not quick:
        out.append(("ISO-A 30 m/s", dict(**plant, road="iso8608", road_params={"road_class": "A", "speed": 30.0},
                                         episode_seconds=dur), True))
        if bump:
            out.append(("bump 5 cm", dict(**plant, road="bump",
                                          road_params={"height": 0.05, "length": 0.5, "speed": 10.0},
                                          episode_seconds=3.0), False))
    return out


def _quarter_car_tests(plant: dict, quick: bool) -> list[TestCase]:
    return road_tests(plant, quick)


def passive_car(options: dict) -> tuple[str, dict]:
    """The conventional passive car of a set-up (its environment options, :attr:`PlantProfile.passive_reference`):
    its name and the options that replace the MR damper by the preset's passive damper — a Bingham damper of viscous
    coefficient ``passive_c`` and no friction."""
    c = quarter_car(options.get("plant_preset", "set_a")).passive_c
    return f"passive_ref (c={c:g})", {"damper": "bingham",
                                      "damper_params": dict(fc_a=0.0, fc_b=0.0, c0a=c, c0b=0.0, f0=0.0)}


_REWARD_MPC = {"weights": "reward", "f_max": 1e5}
CAR_LAWS = ("passive_off", "passive_on", "skyhook_on_off", "skyhook_continuous", "groundhook", "hybrid",
             "clipped_optimal")

PROFILE = PlantProfile(
    spec=SPEC,
    options={},
    training={"road": {"kind": "iso8608", "road_class": ["B", "C", "D"], "speed": (10.0, 30.0)},
              "episode_seconds": 10.0},
    disturbance_key="road", tests=_quarter_car_tests,
    laws=("random", *CAR_LAWS),
    benchmark_laws=CAR_LAWS,
    reference_laws=("skyhook_continuous", "passive_off"),
    response=lambda options: "sprung_acc",
    # the objective's MPC at any suite's step; with the reward's own cost (settings tuned on the validation
    # roads, see controllers.mpc.MPC) with road preview at any suite's step and at 1 ms, and without preview
    # at 1 ms. A preview row measures the road ahead (only on a suite that grants the road-preview sensor): the
    # only rows with information the others lack.
    mpc=(("mpc", None, {}, False),
         ("mpc+preview (reward)", None, {**_REWARD_MPC, "force_ref": 200.0, "horizon": 10}, True),
         ("mpc (reward)", 1e-3, {**_REWARD_MPC, "force_ref": 1000.0, "horizon": 10}, False),
         ("mpc+preview (reward)", 1e-3, {**_REWARD_MPC, "force_ref": 1000.0, "horizon": 100}, True)),
    passive_reference=passive_car,
    metric_units={"acc_weighted_rms": "m/s²", "travel_rms": "m", "travel_peak": "m", "tyre_load_rms": "N"},
    preview=True, warm_laws=CAR_LAWS, published=True,
    # the plant of the single-plant commands without --plant: the shipped hyperparameters' reference plant (the
    # half car trains with its entries, ``hyperparams_fallback``)
    train_default=True, suites=SUITES)
