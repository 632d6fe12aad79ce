"""The one fixed-step stepping routine used by the rig, the plants, the environments and identification.

It advances a batch of independent systems, each made of a linear plant coupled to ``nd`` dampers of one
model, on a fixed grid (dt = 1 ms by default)::

    q̇   = A q + B_F F + B_w w(t)                   linear plant (q may be empty: the virtual rig)
    x_j  = C_x q + D_x w,  ẋ_j = C_v q + D_v w,  ẍ_j = D_a w     kinematics across damper j
    ṡ_j  = rhs(p_j, s_j, x_j, ẋ_j, u_j)            damper internal states
    F_j  = force(p_j, s_j, x_j, ẋ_j, ẍ_j, u_j)
    u̇_j  = −η_j (u_j − v_j(t − τ_j))                command lag, v held over each step (zero-order hold)

The command dynamics (:mod:`mrd_env.command_lag`: η faster on a rise than on a fall if declared, a pure delay
τ) are integrated exactly (exponentials). The plant and damper states are advanced together
(no lagged coupling) by the two-stage, stiffly accurate, L-stable SDIRK method of Alexander (1977),
γ = 1 − 1/√2, order 2: the Bouc–Wen variable's Jacobian reaches |∂ż/∂z| ≈ 2(β+γ) z_s |ẋ−ẏ| (≈ 10⁴ s⁻¹
at 0.1 m/s for the prototype damper), which makes explicit schemes unstable at 1 ms.

Each stage equation Z = R + hγ f(Z) is solved with the structure of the system: the plant is linear, so
its part is eliminated exactly, q = (I − hγA)⁻¹(R_q + hγ B_w w) + M_q F with M_q = hγ(I − hγA)⁻¹B_F (matrices
computed once per sub-step length, :meth:`SystemMatrices.levels`); what is left is Newton's method on each
damper's internal states and force, nd·(ns + 1) unknowns (3 for a Spencer–Dyke damper), with the damper's
analytic derivatives (``DamperModel.partials``) or, for models without them, forward differences of the
damper's own functions (see ``_kernel_template.py``, where everything is inlined into one compiled function
per driver). After every step the model's ``project`` puts the states back in their invariant set
(z within ±z_s), which stage values may leave, and switches discrete modes. The exogenous input w is
interpolated linearly inside a step.

Accuracy control: each step of ``dt`` is split into 2^k equal sub-steps. Starting from half the previous
step's count, the count doubles (up to ``max_substeps``) until an a-posteriori estimate of the local error
— the SDIRK solution minus the embedded first-order one, filtered through the stage matrix as in Hairer &
Wanner, *Solving ODEs II*, IV.8 — is within ``rtol``·|state| + ``atol`` for every state (defaults
:data:`~mrd_env.stepping.scheme.RTOL` = 0.1 and :data:`~mrd_env.stepping.scheme.ATOL` = 1e-5 in SI units with at
most 8 sub-steps; the resulting force errors against Radau are in docs/stepping.md and in
``tests/stepping/test_integrator_accuracy.py``, ``tests/plants/test_plants.py``). A Newton solve that does not
converge also halves the sub-step. The output grid stays fixed at ``dt`` whatever the splitting, and the
splitting depends only on the state, so runs are reproducible bit for bit.

The package, one job per module (imports only downwards, in this order):

* :mod:`mrd_env.stepping.scheme` — the scheme's constants (γ, default tolerances, a step's statuses);
* :mod:`mrd_env.stepping.matrices` — :class:`SystemMatrices`, the plant's elimination matrices, the LU helpers;
* :mod:`mrd_env.stepping.layout` — where the compiled driver finds each array, constant and per-system field;
* :mod:`mrd_env.stepping.injected` — the damper model's names the templates receive when a kernel is generated;
* :mod:`mrd_env.stepping.codegen` — the code generator and its on-disk cache (templates ``_kernel_template.py`` and
  ``_driver_template.py``);
* :mod:`mrd_env.stepping.driver` — :class:`Driver` and :class:`Processing`: N systems and what an environment
  computes per step;
* :mod:`mrd_env.stepping.stepper` — :class:`Stepper` and :func:`run`: a batch over a record of steps (the rig,
  identification).
"""
from __future__ import annotations

from .codegen import kernel_module
from .driver import PARALLEL_FROM, Driver, Processing, noise_keys
from .layout import BAD_ACTION, DIVERGED, HIST_FULL, HIST_NONE, HIST_PERIOD, RUNNING, TERMINATED, TRUNCATED
from .matrices import SystemMatrices
from .scheme import ATOL, GAMMA, NO_CONVERGENCE, NONFINITE, OK, RTOL, max_level_of
from .stepper import Stepper, diverged_error, run

__all__ = ["ATOL", "BAD_ACTION", "DIVERGED", "Driver", "GAMMA", "HIST_FULL", "HIST_NONE", "HIST_PERIOD",
           "NO_CONVERGENCE", "NONFINITE", "OK", "PARALLEL_FROM", "Processing", "RTOL", "RUNNING", "Stepper",
           "SystemMatrices", "TERMINATED", "TRUNCATED", "diverged_error", "kernel_module", "max_level_of",
           "noise_keys", "run"]
