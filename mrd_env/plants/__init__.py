"""Plants coupled to MR dampers: quarter car and N-storey shear building."""
from .base import CoupledPlant, LinearPlant
from .quarter_car import QUARTER_CAR_PRESETS, QuarterCarParams, quarter_car
from .shear_building import BUILDING_PRESETS, THREE_STOREY, ShearBuildingParams, shear_building

__all__ = ["CoupledPlant", "LinearPlant", "QUARTER_CAR_PRESETS", "QuarterCarParams", "quarter_car",
           "BUILDING_PRESETS", "THREE_STOREY", "ShearBuildingParams", "shear_building"]
