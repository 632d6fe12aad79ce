"""The full car: a body in heave, pitch and roll on four suspensions, an MR damper at each corner, on two-track
roads (the rear wheels on the front wheels' tracks wheelbase/speed later).

Its folder holds every fact about it: ``physics.py`` (equations, the parameter set and its source), ``roads.py``
(the two-track roads and the previews), ``metrics.py`` (ISO 2631-1 comfort in heave, pitch and roll; the ride
metrics of a record), ``env.py`` (the environment: signals, reward, episode metrics, the passive car's reference),
``render.py`` and ``profile.py`` (what the experiments run on it)."""
from ..spec import PlantSpec
from .physics import FULL_CAR_PRESETS, FullCarParams, full_car

SPEC = PlantSpec(
    name="full_car", id_name="FullCar", title="full car",
    summary="a sedan in heave, pitch and roll, MR dampers at the four corners, two-track ISO 8608 roads")

__all__ = ["SPEC", "FULL_CAR_PRESETS", "FullCarParams", "full_car"]
