"""One-step model-predictive inverse, for any registered damper model.

The model is run along the measured motion (the observer of :class:`~mrd_env.inverse.observer.ObserverInverse`);
at each control step the command v is the one whose predicted force at the end of the step is nearest the
desired force::

    v_k = argmin_{v ∈ [v_min, v_max]} | F̂(t_{k+1}; s_k, u_k, v, x, ẋ, ẍ) − f_target |

where F̂ is the compiled stepping routine advanced one step from the observer's state s_k and effective
command u_k with v held (the command lag included), along the motion extrapolated at constant acceleration.
The search evaluates ``n_grid`` commands spread evenly over the range (one compiled call for all of them and
all N dampers) and refines inside the grid interval that brackets the target with ``n_refine`` Illinois
(regula falsi) steps; a target out of reach gives the grid command nearest it (an end of the range when the
force is monotone in the command: the clipped solution).

With the true model as the plant and a force the damper can produce, the only errors are the motion's
extrapolation over one step and the search's tolerance.
"""
from __future__ import annotations

import numpy as np

from ..validation import shown
from ..stepping import ATOL, RTOL
from ..validation import check_scalar
from .observer import ObserverInverse


class ModelPredictive(ObserverInverse):
    """Model-predictive inverse (see the module docstring); options of the observer in
    :class:`~mrd_env.inverse.observer.ObserverInverse`."""

    name = "model"

    def __init__(self, damper, *, dt: float = 1e-3, n_grid: int = 5, n_refine: int = 3,
                 force_feedback: float = 0.0, u0: float | None = None, max_substeps: int | None = None,
                 rtol: float = RTOL, atol: float = ATOL):
        super().__init__(damper, dt=dt, force_feedback=force_feedback, u0=u0, max_substeps=max_substeps,
                         rtol=rtol, atol=atol)
        self.n_grid = int(check_scalar("n_grid", n_grid, 2, 1000))
        self.n_refine = int(check_scalar("n_refine", n_refine, 0, 100))
        if self.n_grid != n_grid or self.n_refine != n_refine:
            raise ValueError(f"n_grid and n_refine must be integers, got {shown(n_grid)} and {shown(n_refine)}")
        self.grid = np.linspace(self.v_min, self.v_max, self.n_grid)
        self.predicted = np.zeros(0)

    def _command(self, f_desired, x, v, f_measured):
        self._observe(x, v)
        c, self.predicted = self.observer.nearest_commands(self._target(f_desired, f_measured), self.grid,
                                                           self.n_refine)
        return c
