"""The quarter car's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Each is
defined by its spec, ``specs/<name>-v<version>.json`` (docs/suites.md, "Your own suite"); its references ship beside
this file (``<name>-v<version>.json``), built from the spec by ``mrd-env suite build specs/<name>-v<version>.json``
(or ``python -m experiments.benchmark.references --suite <name>``), the command a user's suite is built with.

Every episode is 3 s long (a clairvoyant solve of a 3 s car episode takes 15–40 s on the 2 shared cores of the
machine that computed the references; a 10 s episode would cost three times as much): ISO 8608 class C and D
roads at 20 m/s and class A at 30 m/s, 10 seeds each, and the 5 cm bump; the controller runs at 10 ms.
"""
from __future__ import annotations

from pathlib import Path

from ....suites import read_specs

#: The plant's suite definitions, read from their specs (one home for each definition).
SUITES = read_specs(Path(__file__).resolve().parent / "specs")
#: car-comfort-robust's bands (:func:`mrd_env.suites.draw_episode`), which the JAX twins' tests draw from.
ROBUST_BANDS = next(d.randomise for d in SUITES if d.name == "car-comfort-robust")
