"""A damper model run along the measured motion, one control step at a time: the observer of the model's
internal states that the simplified-inverse and model-predictive inverses share, and the model's one-step force
predictions for candidate commands.

Each step is the project's stepping routine (:mod:`mrd_env.stepping`: the model's compiled kernel, SDIRK2 with
error control, the command lag u̇ = −η (u − v) integrated exactly) on the virtual rig, called from a small
compiled module generated per damper model (``_onestep_template.py``), so that one call advances a batch of N
dampers or predicts the forces of all candidate commands without returning to Python.
"""
from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np

from ..stepping.codegen import kernel_module, load_generated_module, render
from ..stepping.layout import DamperArrays, PlantArrays, StepControl, SystemState
from ..stepping.matrices import SystemMatrices
from ..stepping.scheme import ATOL, MAX_SUBSTEPS, RTOL, max_level_of
from ..stepping.stepper import diverged_error
from ..validation import check_scalar
from .base import Inverse, writable_c

_RIG = SystemMatrices.displacement_driven()
_MODULES: dict = {}


def onestep_module(model_cls):
    """The compiled one-step module of a damper model class (``advance``, ``step_force``,
    ``nearest_commands`` of ``_onestep_template.py``), generated once and cached on disk like the kernels."""
    module = _MODULES.get(model_cls)
    if module is None:
        kernel = kernel_module(model_cls, compiled=True)  # imported by name below: the module itself
        source = render(Path(__file__).with_name("_onestep_template.py"),
                        f"from {kernel.__name__} import macro_step, ns, workspace_views\n")
        # the kernel's module name carries its own key: a changed model or routine gives a new module here too
        key = hashlib.sha256(source.encode()).hexdigest()[:16]
        module = _MODULES[model_cls] = load_generated_module(f"mrd_env_onestep_{model_cls.name}", source, key)
    return module


class OneStep:
    """N dampers of one model on the rig, advanced one step of ``dt`` at a time along a measured motion.

    ``Y`` (N, ns) internal states, ``U`` (N, 1) effective commands, ``F`` (N, 1) forces (N) at the current motion
    ``W`` (N, 3) = (x, ẋ, ẍ) in SI units.
    """

    def __init__(self, damper, N: int, dt: float, *, max_substeps: int = MAX_SUBSTEPS, rtol: float = RTOL,
                 atol: float = ATOL):
        self.damper = damper
        self.module = onestep_module(type(damper))
        self.N = int(N)
        self.dt = float(dt)
        self.max_substeps = int(max_substeps)
        self.max_level = max_level_of(self.max_substeps)
        self.rtol, self.atol = float(rtol), float(atol)
        ns = damper.n_states
        self._plant = PlantArrays(_RIG.C, _RIG.D, *_RIG.levels(self.dt, self.max_level))
        self.P = damper.params.as_array()[None, :]
        self.lag = damper.command.lag_vector().reshape(1, 3)
        wf, wi = kernel_module(type(damper)).workspace_len(0, 1, ns, 3)
        self._wf = np.zeros(int(wf))
        self._wi = np.zeros(int(wi), dtype=np.int64)
        self.Y = np.zeros((self.N, ns))
        self.U = np.zeros((self.N, 1))
        self.F = np.zeros((self.N, 1))
        self.W = np.zeros((self.N, 3))
        self._nsub = np.ones(self.N, dtype=np.int64)
        self._status = np.zeros(self.N, dtype=np.int64)
        self.t = 0.0

    # copies (pickle, deepcopy, cloudpickle: planning, checkpoints, Ray) carry the state, not the compiled module,
    # which is reloaded from its disk cache by the damper's class
    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "module"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.module = onestep_module(type(self.damper))

    def start(self, W: np.ndarray, u0: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Start from rest at the motion ``W`` (N, 3) with the effective commands ``u0`` (N,) — every damper, or
        those in ``rows`` (N,) — : the rest state switched to the motion (the model's ``project``) and its force,
        as the rig starts a record."""
        d = self.damper
        rows = np.ones(self.N, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        self.W[rows] = W[rows]
        self.U[rows, 0] = u0[rows]
        self._nsub[rows] = 1
        p = self.P[0]
        for b in np.flatnonzero(rows):
            s = d.initial_state()
            x, v, a = (float(w) for w in W[b])
            d.project(p, s, x, v, float(u0[b]))
            self.Y[b] = s
            self.F[b, 0] = d.force_law(p, s, x, v, a, float(u0[b]))

    @property
    def _control(self) -> StepControl:
        return StepControl(self.dt, self.max_level, self.atol, self.rtol)

    def _records(self) -> tuple:
        """(plant, damper, state) as the compiled routines take them (:mod:`mrd_env.stepping.layout`)."""
        return self._plant, DamperArrays(self.P, self.lag), SystemState(self.Y, self.U, self.F)

    def advance(self, command: np.ndarray, x: np.ndarray, v: np.ndarray) -> None:
        """One step with the commands ``command`` (N,) held, the motion going linearly from ``W`` to the
        measured stroke ``x`` and velocity ``v`` (N,) (acceleration: the backward difference of the velocities).
        A step that diverges raises and leaves the state as it was."""
        saved = [a.copy() for a in (self.Y, self.U, self.F, self.W, self._nsub)]
        self.module.advance(*self._records(), self.W, writable_c(command), writable_c(x), writable_c(v), self._control,
                            self._nsub, self._wf, self._wi, self._status)
        if self._status.any():
            b = int(np.flatnonzero(self._status)[0])
            code = int(self._status[b])
            for a, old in zip((self.Y, self.U, self.F, self.W, self._nsub), saved):
                a[...] = old
            self._status[:] = 0
            raise diverged_error(self.damper.name, code, self.t + self.dt, b, self.max_substeps)
        self.t += self.dt

    def nearest_commands(self, target: np.ndarray, grid: np.ndarray, n_refine: int):
        """(commands (N,), predicted forces (N,)): for each damper, the command whose force at the end of the
        next step (the motion extrapolated at constant acceleration) is nearest ``target`` (see
        ``_onestep_template.nearest_commands``)."""
        out = np.empty(self.N)
        predicted = np.empty(self.N)
        self.module.nearest_commands(*self._records(), self.W, writable_c(target), writable_c(grid), int(n_refine),
                                     self._control, self._wf, self._wi, out, predicted)
        return out, predicted

    def step_forces(self, commands: np.ndarray, x1: np.ndarray, v1: np.ndarray) -> np.ndarray:
        """Forces (N, K) at the end of the next step for each of K commands per damper (N, K), the motion going
        to the measured x1, v1 (N,) (acceleration: their backward difference); the state is left unchanged."""
        W1 = np.stack([x1, v1, (v1 - self.W[:, 1]) / self.dt], axis=1)
        out = np.empty(commands.shape)
        self.module.step_forces(*self._records(), self.W, W1, writable_c(commands),
                                self._control, self._wf, self._wi, out)
        return out


class ObserverInverse(Inverse):
    """Base of the inverses that run their damper model along the measured motion (``observer``, a
    :class:`OneStep`): at each call the model is first advanced from the previous measured motion to the new one
    with the command the inverse gave last, so that its internal states (the hysteretic z, Spencer–Dyke's y) and
    effective command follow the damper's.

    The acceleration, needed by the models with an inertance term or an acceleration branch, is the backward
    difference of the measured velocities (0 at the first call); the motion over the coming step is extrapolated
    from x, ẋ, ẍ (constant acceleration). ``force_feedback`` κ in [0, 1] corrects the target by the model's
    current error when the force is measured: f_target = f_d − κ (f_measured − F_model), a disturbance estimate
    held over the step (κ = 0: open loop). ``u0``: the effective command at the first call (default v_min, a
    damper at rest and switched off). ``max_substeps``, ``rtol``, ``atol``: the stepping routine's settings
    (``max_substeps`` per step of ``dt``; default :data:`~mrd_env.stepping.scheme.MAX_SUBSTEPS` per millisecond
    of it, the budget of the environments' own 1 ms steps).
    """

    def __init__(self, damper, *, dt: float = 1e-3, force_feedback: float = 0.0, u0: float | None = None,
                 max_substeps: int | None = None, rtol: float = RTOL, atol: float = ATOL):
        super().__init__(damper, dt=dt)
        self.force_feedback = check_scalar("force_feedback", force_feedback, 0.0, 1.0)
        unit = self.damper.command.unit
        self.u0 = self.v_min if u0 is None else check_scalar("u0", u0, self.v_min, self.v_max, unit=unit)
        if max_substeps is None:  # a 10 ms control step of a stiff damper needs the sub-steps of ten 1 ms steps
            max_substeps = MAX_SUBSTEPS * max(1, math.ceil(self.dt / 1e-3 - 1e-9))
        self._integrator = dict(max_substeps=int(check_scalar("max_substeps", max_substeps, 1, 4096)),
                                rtol=check_scalar("rtol", rtol, 0.0, lo_open=True),
                                atol=check_scalar("atol", atol, 0.0, lo_open=True))
        self.observer: OneStep | None = None

    def _start(self, rows, x, v, f_measured):
        if self.observer is None or self.observer.N != self.N:
            self.observer = OneStep(self.damper, self.N, self.dt, **self._integrator)
            self.last_command = np.full(self.N, self.u0)
        self.last_command[rows] = self.u0
        # the restarted rows are started at the measured motion: the observer's step to it changes nothing,
        # its state being the rest state switched to that motion
        self._fresh = rows.copy()

    def _observe(self, x: np.ndarray, v: np.ndarray) -> None:
        """Advance the observer to the measured motion (x, ẋ) with the last command; the dampers (re)started at
        this call start from rest at it instead."""
        fresh = self._fresh
        if fresh.any():
            W = np.stack([x, v, np.zeros_like(x)], axis=1)
            if not fresh.all():
                self.observer.W[fresh] = W[fresh]  # no motion over the step: the rows restarted below
                self.observer.advance(self.last_command, x, v)
            self.observer.start(W, np.full(self.N, self.u0), fresh)
            self._fresh = np.zeros(self.N, dtype=bool)
        else:
            self.observer.advance(self.last_command, x, v)

    def _target(self, f_desired: np.ndarray, f_measured: np.ndarray | None) -> np.ndarray:
        """f_d corrected by the model's current force error (``force_feedback``)."""
        if f_measured is None or self.force_feedback == 0.0:
            return writable_c(f_desired)
        return f_desired - self.force_feedback * (f_measured - self.observer.F[:, 0])
