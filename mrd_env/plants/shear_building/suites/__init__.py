"""The shear building's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Each is
defined by its spec, ``specs/<name>-v<version>.json`` (docs/suites.md, "Your own suite"); its references ship beside
this file (``<name>-v<version>.json``), built from the spec by ``mrd-env suite build specs/<name>-v<version>.json``
(or ``python -m experiments.benchmark.references --suite <name>``), the command a user's suite is built with.

The benchmark building — the three-storey lab model with its damper in storey 2 (the profile's options) —
controlled at 10 ms: El Centro 1940 N-S and E-W replayed 5× faster (one episode each) and Kanai–Tajimi ground
motions with the nominal parameters (10 seeds), each episode cut to ``EPISODE_SECONDS`` so that one clairvoyant
solve stays under 2 minutes on the 2 shared cores of the machine that computed the references.
"""
from __future__ import annotations

from pathlib import Path

from ....suites import read_specs

#: The plant's suite definitions, read from their specs (one home for each definition).
SUITES = read_specs(Path(__file__).resolve().parent / "specs")
