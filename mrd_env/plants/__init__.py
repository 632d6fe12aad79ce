"""Plants coupled to MR dampers: quarter car, half car and N-storey shear building."""
from .base import CoupledPlant, LinearPlant
from .half_car import HALF_CAR_PRESETS, HalfCarParams, half_car
from .quarter_car import QUARTER_CAR_PRESETS, QuarterCarParams, quarter_car
from .shear_building import BUILDING_PRESETS, THREE_STOREY, ShearBuildingParams, shear_building

__all__ = ["CoupledPlant", "LinearPlant", "QUARTER_CAR_PRESETS", "QuarterCarParams", "quarter_car",
           "HALF_CAR_PRESETS", "HalfCarParams", "half_car",
           "BUILDING_PRESETS", "THREE_STOREY", "ShearBuildingParams", "shear_building"]
