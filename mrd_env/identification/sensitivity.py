"""Local identifiability: the Jacobian of the simulated force with respect to the parameters, its singular values
and Cramér–Rao bounds."""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

from ..dampers import DamperModel
from ..errors import SimulationDivergedError
from ..records import DamperRecord
from .parameters import fixed_by_default
from .prepare import as_record, prepare_record
from .simulate import simulate_batch


def sensitivity(damper: DamperModel, records, *, free: Iterable[str] | None = None, noise: float | None = None,
                rel_step: float = 1e-4, dt: float | None = None, command_range: str = "clip",
                warmup: float = 0.0, rcond: float = 1e-8, **integrator_options) -> dict:
    """Local identifiability of ``damper``'s parameters on ``records``: the Jacobian S = ∂F/∂ln p of the
    simulated force samples (central differences), its singular values, and the Cramér–Rao bound on each
    parameter's relative standard deviation for white force noise of standard deviation ``noise`` (N):
    cov(ln p) ≈ noise² (SᵀS)⁻¹.

    Returns {"names", "rel_std" (dict; with noise=None: per newton of noise), "singular_values",
    "condition" (of S with unit-norm columns), "weakest" (the right singular vector of the smallest singular
    value, as {name: component}), "correlation" (2-D array)}. Singular values below ``rcond`` × the largest
    mark exactly unidentifiable combinations (e.g. c1 + c2 x_a + c3 x_a² with x_a fixed): the parameters in them
    get ``rel_std`` = inf. A parameter whose ``rel_std`` is far below the accuracy wanted is well identifiable
    from these records at that noise level.
    """
    cls = type(damper)
    fixed = fixed_by_default(cls, damper.params)
    names = tuple(free) if free is not None else tuple(k for k in cls.Params.names() if k not in fixed)
    bad = [k for k in names if k not in cls.Params.names()]
    if bad:
        raise ValueError(f"unknown parameter name(s) {bad} for model {cls.name!r}")
    if isinstance(records, DamperRecord) or not isinstance(records, (list, tuple)):
        records = [records]
    preps = [prepare_record(as_record(r, i), damper.command, dt=dt, command_range=command_range, warmup=warmup)
             for i, r in enumerate(records)]
    p0 = damper.params.as_array()
    idx = [cls.Params.names().index(k) for k in names]
    k = len(idx)
    P = np.tile(p0, (2 * k, 1))
    dp = np.empty(k)
    for j, i in enumerate(idx):
        dp[j] = rel_step * (abs(p0[i]) if p0[i] != 0 else 1.0)
        P[2 * j, i] += dp[j]
        P[2 * j + 1, i] -= dp[j]
    scale = np.array([abs(p0[i]) if p0[i] != 0 else 1.0 for i in idx])
    cols = []
    Y0 = np.tile(damper.initial_state(), (2 * k, 1))
    for prep in preps:
        F, ok = simulate_batch(cls, damper.command, prep, P, np.tile(damper.command.lag_vector(), (2 * k, 1)), Y0,
                               integrator_options)
        if not ok.all():
            raise SimulationDivergedError(f"a perturbed {cls.name!r} diverged in the sensitivity analysis",
                                          model=cls.name)
        F = F[:, prep.mask]
        cols.append(((F[0::2] - F[1::2]) / (2 * dp[:, None]) * scale[:, None]).T)
    S = np.vstack(cols)
    sigma = 1.0 if noise is None else float(noise)
    # covariance from the SVD of S with unit-norm columns; a (numerically) zero singular value means an exactly
    # unidentifiable combination: every parameter taking part in it gets an infinite bound
    norms = np.linalg.norm(S, axis=0)
    Sn = S / np.where(norms > 0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(Sn, full_matrices=False)
    null = sv <= rcond * sv[0]
    inv2 = np.where(null, 0.0, 1.0 / np.where(null, 1.0, sv) ** 2)
    cov_n = (Vt.T * inv2) @ Vt
    with np.errstate(divide="ignore", invalid="ignore"):
        rel_std = sigma * np.sqrt(np.clip(np.diag(cov_n), 0, None)) / norms
    in_null = np.any(np.abs(Vt[null]) > 1e-6, axis=0) if null.any() else np.zeros(k, dtype=bool)
    rel_std = np.where(in_null | (norms == 0), math.inf, rel_std)
    d = np.sqrt(np.clip(np.diag(cov_n), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov_n / np.outer(np.where(d > 0, d, 1), np.where(d > 0, d, 1))
    return {"names": names, "rel_std": dict(zip(names, rel_std.tolist())), "singular_values": sv,
            "condition": float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf,
            "weakest": dict(zip(names, Vt[-1].tolist())), "correlation": corr}
