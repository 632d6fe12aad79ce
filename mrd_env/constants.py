"""Physical constants, each defined once and imported wherever it is used."""
from __future__ import annotations

#: Standard acceleration of gravity (CGPM 1901), m/s². Static loads (tyre loads, a building's weight), PGA given
#: in g, AT2 records in units of g.
GRAVITY = 9.80665

__all__ = ["GRAVITY"]
