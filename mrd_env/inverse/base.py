"""The interface of every inverse model: from a desired damper force to the command of the next control step.

An inverse is built for one damper (:class:`~mrd_env.dampers.DamperModel`: its command channel, and for the
model-based inverses its force law) and a control step ``dt``. At each control instant t_k it is called with the
force wanted at the end of the coming step, f_d(t_{k+1}), and what is measured now — the damper stroke x(t_k),
its velocity ẋ(t_k) and, if available, the damper force f(t_k) — and returns the command v (V or A) to hold over
[t_k, t_{k+1}]::

    inv = make_inverse("model", damper, dt=1e-3)
    inv.reset()
    v = inv.command(f_desired, x, v, f_measured=f)      # arrays of N dampers (or scalars), SI units

Calls are batched over N dampers, like the stepping routine: the inputs are scalars or 1-D arrays of one length
N, fixed from the first call after :meth:`Inverse.reset` (a call with another N is an error); ``reset(mask)``
restarts only the dampers in ``mask`` (a vector environment's ended episodes) at the next call. Forces are the
whole damper force (N, positive resisting extension, static preload included). Inverses with memory (an observer
of the damper's states, the lag of their own past commands, a network's input history) assume that consecutive
calls are consecutive control steps.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from ..dampers import DamperModel, make_damper
from ..validation import check_array, check_scalar


def as_damper(damper) -> DamperModel:
    """``damper`` as a DamperModel: an instance, or a registered model name (its default preset)."""
    if isinstance(damper, str):
        return make_damper(damper)
    if not isinstance(damper, DamperModel):
        raise ValueError(f"damper must be a DamperModel or a registered model name, got {type(damper).__name__}")
    return damper


def lag_decay(command, dt: float) -> np.ndarray:
    """(e^(−η_rise dt), e^(−η_fall dt)): the fraction of the gap u − v left after one step of the command lag
    u̇ = −η (u − v) on a rising and on a falling command (``command``: a CommandSpec). The inverses leave out
    the command's pure delay."""
    return np.array([math.exp(-command.eta * dt), math.exp(-command.eta_down * dt)])


def writable_c(a) -> np.ndarray:
    """``a`` as a writable, C-contiguous float64 array, copied only if it is not one: numba compiles a routine once
    per layout and read-only flag of its arguments, so read-only records or strided columns would each cost another
    compilation. (The flag test is cheaper than ``np.require``: it runs several times per control step.)"""
    if type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


def _as_batch(name: str, value, n: int | None) -> np.ndarray:
    """``value`` as a 1-D float64 array of finite reals (a scalar is a batch of one)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1 and np.isfinite(value).all():
        a = np.ascontiguousarray(value)  # the hot path of a control loop: copied only if strided
    else:
        a = np.atleast_1d(check_array(name, value))
        if a.ndim != 1:
            raise ValueError(f"{name} must be a scalar or a 1-D array (one value per damper), got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has {a.shape[0]} values, expected {n} (one per damper, as f_desired)")
    return a


class Inverse(ABC):
    """Base class: input checks, the batch size and the command range. Subclasses implement :meth:`_start`
    (first call after a reset) and :meth:`_command`."""

    name: ClassVar[str] = "inverse"
    #: True if :meth:`command` needs the measured force ``f_measured``.
    needs_force: ClassVar[bool] = False

    def __init__(self, damper, *, dt: float = 1e-3):
        self.damper = as_damper(damper)
        c = self.damper.command
        self.v_min, self.v_max = float(c.v_min), float(c.v_max)
        self.dt = check_scalar("dt", dt, 0.0, 1.0, lo_open=True, unit="s")
        self.N = 0

    def reset(self, mask=None) -> None:
        """Forget the past (observer states, command history): of every damper — the next call starts a new
        batch, of any size — or of the dampers where ``mask`` (N,) is true, restarted at the next call."""
        m = None if mask is None else np.asarray(mask, dtype=bool)
        if m is None or self.N == 0 or m.all():
            self.N = 0
            return
        if m.shape != (self.N,):
            raise ValueError(f"mask must have shape ({self.N},) (one flag per damper), got {m.shape}")
        self._restart |= m

    def command(self, f_desired, x, v, f_measured=None) -> np.ndarray:
        """The command (N,) in the damper's unit, within [v_min, v_max], to hold over the next control step so
        that the damper force at its end is f_desired (N).

        ``x`` stroke (m), ``v`` stroke velocity (m/s) and ``f_measured`` damper force (N) now; each a scalar or
        an array of N values.
        """
        fd = _as_batch("f_desired", f_desired, self.N or None)
        n = fd.shape[0]
        x = _as_batch("x", x, n)
        v = _as_batch("v", v, n)
        if f_measured is None:
            if self.needs_force:
                raise ValueError(f"f_measured is required by the {self.name!r} inverse (the measured damper "
                                 "force, N)")
            fm = None
        else:
            fm = _as_batch("f_measured", f_measured, n)
        if self.N == 0:
            self.N = n
            self._restart = np.ones(n, dtype=bool)
        if self._restart.any():
            self._start(self._restart, x, v, fm)
            self._restart[:] = False
        self.last_command = np.clip(self._command(fd, x, v, fm), self.v_min, self.v_max)
        return self.last_command

    @abstractmethod
    def _start(self, rows: np.ndarray, x: np.ndarray, v: np.ndarray, f_measured: np.ndarray | None) -> None:
        """(Re)start the memory of the dampers in ``rows`` (N,) from the call's measurements; at the first call
        after :meth:`reset` every row, and the memory is sized for ``self.N`` dampers."""

    @abstractmethod
    def _command(self, f_desired: np.ndarray, x: np.ndarray, v: np.ndarray,
                 f_measured: np.ndarray | None) -> np.ndarray:
        """The commands (N,) (clipped to the range by :meth:`command`)."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.damper.name!r}, dt={self.dt:g})"
