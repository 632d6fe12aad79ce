"""What the experiments run on the MR isolator (:class:`~mrd_env.plants.profile.PlantProfile`).

MR isolator (a 100 kg suspension seat at 1.5 Hz, one damper; every sensor a law needs by default) — training: a new
random base motion per episode (flat acceleration spectrum 0.5–5 Hz) at an r.m.s. drawn in [0.5, 2] m/s²;
validation: the same distribution with seeds training never draws; test (the labs' held-out scenarios): the random
base at 1 and 2 m/s² (unseen seeds) and, shapes never trained on, a harmonic base at the seat's resonance
(1.5 Hz, 2 cm) and a sine sweep (2 mm, 0.5 → 10 Hz: beyond the training band too). Passive-off and passive-on score
alike on the training distribution; continuous skyhook is the best law at 10 ms (and at 1 ms)."""
from __future__ import annotations

from ..profile import PlantProfile, TestCase
from ..quarter_car import SPEC as QUARTER_CAR
from . import SPEC

#: The classical laws that apply: the base plays the wheel's part for groundhook and the hybrid law.
ISOLATOR_LAWS = ("passive_off", "passive_on", "skyhook_on_off", "skyhook_continuous", "groundhook", "hybrid",
                 "clipped_optimal")


def _isolator_tests(plant: dict, quick: bool) -> list[TestCase]:
    """The random base at 1 and 2 m/s² (unseen seeds), a harmonic base at resonance and a sweep (unseen shapes)."""
    dur = 3.0 if quick else 10.0
    out = [(f"random {a:g} m/s^2", dict(**plant, base_motion={"kind": "random", "acc_rms": a}, episode_seconds=dur),
            True) for a in ((1.0,) if quick else (1.0, 2.0))]
    out.append(("harmonic 1.5 Hz", dict(**plant, base_motion={"kind": "harmonic", "amplitude": 0.02,
                                                              "frequency": 1.5}, episode_seconds=dur), False))
    if not quick:
        out.append(("sweep 0.5-10 Hz", dict(**plant, base_motion={"kind": "sine_sweep", "amplitude": 0.002,
                                                                  "f_start": 0.5, "f_end": 10.0},
                                            episode_seconds=20.0), False))
    return out


PROFILE = PlantProfile(
    spec=SPEC,
    options={},
    training={"base_motion": {"kind": "random", "acc_rms": (0.5, 2.0)}, "episode_seconds": 10.0},
    disturbance_key="base_motion", tests=_isolator_tests,
    laws=("random", *ISOLATOR_LAWS),
    benchmark_laws=ISOLATOR_LAWS,
    reference_laws=("skyhook_continuous", "passive_off"),
    response=lambda options: "payload_acc",
    mpc=(("mpc", None, {}, False),
         ("mpc (reward)", None, {"weights": "reward"}, False)),
    metric_units={"acc_rms": "m/s²", "acc_weighted_rms": "m/s²", "stroke_rms": "m", "stroke_peak": "m",
                  "transmissibility": "-"},
    warm_laws=ISOLATOR_LAWS,
    hyperparams_fallback=QUARTER_CAR.physics_id,
    published=False)
