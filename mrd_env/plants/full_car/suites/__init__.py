"""The full car's frozen benchmark suites (:class:`~mrd_env.suites.SuiteDefinition`; docs/suites.md). Each is
defined by its spec, ``specs/<name>-v<version>.json`` (docs/suites.md, "Your own suite"); its references ship beside
this file (``<name>-v<version>.json``), built from the spec by ``mrd-env suite build specs/<name>-v<version>.json``
(or ``python -m experiments.benchmark.references --suite <name>``), the command a user's suite is built with.

Short and few episodes, said plainly: every episode is 1 s long and each random-road scenario has 3 seeds, not the
quarter car's 3 s and 10 seeds. The references' clairvoyant optimises four command sequences: one solve of a 1 s
class-C episode took 68 s on the 2 shared cores of the machine that computed them (load 5.5), the procedure's two
solves, warm starts and bound 150 s per episode; 10 seeds of 3 s would have taken hours. ISO 8608 class C and D
two-track roads at 20 m/s and class A at 30 m/s, and a 5 cm bump under the left wheels (front at 0.2 s, rear at
0.48 s); the controller runs at 10 ms.
"""
from __future__ import annotations

from pathlib import Path

from ....suites import read_specs

#: The plant's suite definitions, read from their specs (one home for each definition).
SUITES = read_specs(Path(__file__).resolve().parent / "specs")
