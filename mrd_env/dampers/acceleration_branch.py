"""The sign of the acceleration as a discrete mode, for the models whose force follows one of two branches
chosen by sgn(ẍ): the hysteretic bi-viscous model (review §3.3) and the sigmoid model (review Table 4).

The force law is handed ẍ only on the rig (a plant passes 0), so both models estimate it from a filtered
velocity q, a continuous state::

    q̇ = (ẋ − q) / τ,        â = (ẋ − q) / τ ≈ ẍ

and keep the branch σ ≈ sgn(â) as a second state that is **held over each integration step and switched
between steps** (``project``): σ ← tanh(â / a_s), the smoothed sign (a_s = 0: the exact sign; σ = 0 at rest,
before the first motion).

Why a discrete mode rather than σ = tanh(â / a_s) inside the force law: on a plant the damper's own force
sets the acceleration that picks its branch. Switching from the loading to the unloading branch changes the
force by Δ (2 c_pre v0 for the hysteretic bi-viscous model), hence the acceleration across the damper by
Δ/m (m the effective mass of the coupled plant), in the direction that confirms the switch. With σ a
continuous function of q the coupled equations then have a fast *unstable* mode,
λ ≈ (Δ/m) / (τ a_s) − 1/τ — about 7·10⁴ s⁻¹ for the prototype fit on the quarter car — so the switch is a
run-away through an unstable equilibrium that no 1 ms implicit step can follow: Newton's method meets a fold
of the stage equation and fails (the environments stopped after 0.01–0.3 s). The model means an
instantaneous switch of branch (a hybrid system), which is what the held σ is. On the rig, where ẍ is
prescribed and q does not depend on σ, the force at every output time is unchanged: σ is updated from the
state at that time before the force is evaluated. On a plant the branch switches at the end of the
(sub-)step in which â changes sign, up to dt/2^k late.
"""
from __future__ import annotations

import numba as nb

from .base import smooth_sign


@nb.njit(cache=True)
def filter_rhs(xd, q, tau):
    """q̇ = (ẋ − q)/τ (m/s²)."""
    return (xd - q) / tau


@nb.njit(cache=True)
def branch(xd, q, tau, a_s):
    """σ = tanh(â / a_s) with â = (ẋ − q)/τ: the smoothed sign of the acceleration estimate."""
    return smooth_sign((xd - q) / tau, a_s)
