"""Identification support: measured records, model-error measures and the test-rig uncertainty budget.

- :mod:`.measures` — E_t, E_x, E_v (review eq. 3), J1, J2 (eqs. 25-26).
- :class:`DamperRecord` and :func:`load_record_csv` (declared units, SI inside) live in :mod:`mrd_env.records`,
  the one container of a damper time series (measured, from the rig or from its sensors); re-exported here.
- :mod:`.uncertainty` — sensors of Table 7, the RSS budget of Table 8, Monte-Carlo propagation.
- :mod:`.prepare`, :mod:`.faults`, :mod:`.align` — records made ready for a fit: uniform grid, faults
  (saturation, spikes, gaps) found and excluded, the force aligned with the motion.
- :mod:`.fit` — :func:`fit_model` (least squares, differential evolution, particle swarm; :mod:`.options`,
  :mod:`.parameters`, :mod:`.problem`, :mod:`.optimisers`, :mod:`.result`); :mod:`.neural` — the neural
  forward model; :mod:`.presets` — JSON presets; :mod:`.sensitivity` — Cramér–Rao bounds.
- :mod:`.compare` — several models fitted on one part of the records (or on other records), scored on the rest.
- :mod:`.propagate` — sensor errors propagated to identified parameters and error measures.
"""
from ..records import UNITS, DamperRecord, load_record_csv
from .compare import compare_models
from .faults import Fault, FaultsExcluded, find_faults
from .fit import fit_model, reference_offset
from .neural import NeuralForwardModel, NeuralOptions
from .options import DataOptions, SearchOptions
from .presets import load_preset, save_preset
from .result import FitInterrupted, FitResult, ParameterAtBound
from .simulate import predict
from .measures import error_displacement, error_measures, error_time, error_velocity, j1, j2
from .propagate import propagate_sensor_errors
from .uncertainty import (TABLE8_DEFAULTS, Contribution, DisplacementSensor, LoadCell, MonteCarloResult,
                          SensorSet, UncertaintyBudget, apply_sensors, as_generator, monte_carlo,
                          rss_budget, table8_contributions)

__all__ = [
    "DamperRecord", "load_record_csv", "UNITS",
    "error_time", "error_displacement", "error_velocity", "j1", "j2", "error_measures",
    "LoadCell", "DisplacementSensor", "SensorSet", "apply_sensors",
    "Contribution", "UncertaintyBudget", "rss_budget", "table8_contributions", "TABLE8_DEFAULTS",
    "MonteCarloResult", "monte_carlo", "as_generator",
    "FitResult", "FitInterrupted", "ParameterAtBound", "fit_model", "reference_offset", "SearchOptions", "DataOptions",
    "NeuralOptions", "NeuralForwardModel", "predict",
    "find_faults", "Fault", "FaultsExcluded", "save_preset", "load_preset", "compare_models",
    "propagate_sensor_errors",
]
