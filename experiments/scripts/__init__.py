"""Maintenance tools run as ``python -m experiments.scripts.<name>``: the fingerprint a refactor must not move, the
agent export, a preset's derivation and probes. Measurements of speed and accuracy are in
:mod:`experiments.measurements`."""
