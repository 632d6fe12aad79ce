"""The quarter car: a sprung and an unsprung mass, the MR damper across the suspension, driven by a road.

Its folder holds every fact about it: ``physics.py`` (equations, parameter sets with sources), ``env.py`` (the
environment: roads, signals, reward, episode metrics, the passive car's reference), ``render.py``, ``metrics.py``
(ride metrics of a record) and ``profile.py`` (what the experiments run on it)."""
from ..spec import PlantSpec
from .physics import QUARTER_CAR_PRESETS, QuarterCarParams, quarter_car

SPEC = PlantSpec(
    name="quarter_car", id_name="QuarterCar", title="quarter car",
    summary="two-mass car suspension with one MR damper, ISO 8608 roads",
    former_ids=("mrd_env/QuarterCar-v0",))

__all__ = ["SPEC", "QUARTER_CAR_PRESETS", "QuarterCarParams", "quarter_car"]
