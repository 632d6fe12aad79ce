"""The shear building: N storeys on a shaking ground, MR dampers as braces between floors.

Its folder holds every fact about it: ``physics.py`` (equations, the Dyke et al. lab model), ``env.py`` (the
environment: ground motions, signals, reward, episode metrics, the uncontrolled reference), ``render.py``,
``metrics.py`` (responses and the benchmark criteria J1–J6 of a record) and ``profile.py`` (what the experiments
run on it)."""
from ..spec import PlantSpec
from .physics import BUILDING_PRESETS, THREE_STOREY, ShearBuildingParams, shear_building

#: The benchmark's building: its damper in storey 2 (between floors 1 and 2), where the laws can be told apart (in
#: storey 1, the lab model's own place, passive-on is within 0.5 % of the best law).
BENCHMARK_DAMPER_FLOORS = (2,)

SPEC = PlantSpec(
    name="shear_building", id_name="ShearBuilding", title="shear building",
    summary="three-storey lab building on a shake table, MR damper between floors, earthquake records",
    # a list, not a tuple: every registered keyword must survive EnvSpec.to_json/from_json unchanged (issue 37)
    v1_options={"damper_floors": list(BENCHMARK_DAMPER_FLOORS)},
    former_ids=("mrd_env/ShearBuilding-v0",), former_names=("building",))

__all__ = ["SPEC", "BENCHMARK_DAMPER_FLOORS", "BUILDING_PRESETS", "THREE_STOREY", "ShearBuildingParams",
           "shear_building"]
