"""The half car: a body in heave and pitch on two axles, an MR damper at each, the rear wheel on the front's road.

Its folder holds every fact about it: ``physics.py``, ``env.py``, ``render.py`` and ``profile.py``."""
from ..spec import PlantSpec
from .physics import HALF_CAR_PRESETS, HalfCarParams, half_car

SPEC = PlantSpec(
    name="half_car", id_name="HalfCar", title="half car",
    summary="a sedan in the pitch plane, MR dampers at both axles, ISO 8608 roads",
    former_ids=("mrd_env/HalfCar-v0",))

__all__ = ["SPEC", "HALF_CAR_PRESETS", "HalfCarParams", "half_car"]
