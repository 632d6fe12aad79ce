"""The clipped-optimal on–off law as an inverse (Dyke, Spencer, Sain & Carlson 1996), and its continuous
force-feedback variant.

On–off: the maximum command when the measured force f must grow in magnitude to reach the desired force f_d,
the minimum otherwise::

    v = v_min + (v_max − v_min)·H((f_d − f)·f)                        H the Heaviside step

Continuous (``gain`` g > 0, in command units per newton): the command grows with the force error in the
direction the damper can act on, clipped to the range::

    v = v_min + clip(g·(f_d − f)·sgn(f), 0, v_max − v_min)

(g → ∞ gives the on–off law back.) Both act on forces beyond ``f_static`` (the damper's static preload, e.g.
the accumulator's k1·x0, that a plant balances): f_d and f are shifted by it before the law. They use only the
measured force, not the motion, and have no memory.
"""
from __future__ import annotations

import numpy as np

from ..validation import shown
from ..validation import as_real, check_scalar
from .base import Inverse


class Heaviside(Inverse):
    """On–off (``gain=None``) or continuous force-feedback (``gain`` > 0, command units per N) law."""

    name = "heaviside"
    needs_force = True

    def __init__(self, damper, *, dt: float = 1e-3, gain: float | None = None, f_static: float = 0.0):
        super().__init__(damper, dt=dt)
        unit = self.damper.command.unit
        self.gain = None if gain is None else check_scalar("gain", gain, 0.0, lo_open=True, unit=f"{unit}/N")
        self.f_static = as_real("f_static", f_static)
        if not np.isfinite(self.f_static):
            raise ValueError(f"f_static = {shown(f_static)} is invalid: must be finite (N)")

    def _start(self, rows, x, v, f_measured):
        pass

    def _command(self, f_desired, x, v, f_measured):
        f = f_measured - self.f_static
        err = f_desired - self.f_static - f
        if self.gain is None:
            return self.v_min + (self.v_max - self.v_min) * ((err * f) > 0.0)
        return self.v_min + np.clip(self.gain * err * np.sign(f), 0.0, self.v_max - self.v_min)
