"""The fitting problem: free parameters scaled to [0, 1] by their bounds → objective and residuals on all records.

The objective is the review's J2 (eq. 26, RMS force error in N) summed over the records, each optionally
divided by the standard deviation of its measured force (``normalize``); ``weighting="sample"`` pools the
samples instead. A candidate that the parameter dataclass rejects or whose simulation diverges gets the penalty
``PENALTY`` × Σ_r w_r RMS(F_r).
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..dampers import CommandSpec
from ..command_lag import LAG_FALL, LAG_RISE, check_lag
from .parameters import LAG_COLUMN, COMMAND_ETA, COMMAND_ETA_FALL, make_params
from .prepare import PreparedRecord
from .simulate import simulate_batch

PENALTY = 1.0e3          # infeasible/diverged candidates: objective = PENALTY × Σ_r w_r RMS(F_measured,r)


class Problem:
    """Free parameters scaled to [0, 1] by their bounds → objective / residuals on all records."""

    def __init__(self, cls, base_params, command: CommandSpec, free: Sequence[str], lo, hi,
                 preps: Sequence[PreparedRecord], normalize: bool, integrator_options: Mapping,
                 weighting: str = "record"):
        self.cls = cls
        self.command = command
        self.names = cls.Params.names()
        self.base = base_params.as_array()
        self.free = tuple(free)
        self.idx = [self.names.index(k) if k in self.names else -1 - LAG_COLUMN[k] for k in self.free]
        # a symmetric lag whose rate is fitted stays symmetric
        self.tied_fall = COMMAND_ETA in self.free and COMMAND_ETA_FALL not in self.free and command.eta_fall is None
        self.lo = np.asarray(lo, dtype=np.float64)
        self.hi = np.asarray(hi, dtype=np.float64)
        self.preps = list(preps)
        self.integrator_options = dict(integrator_options)
        self.meas = [p.series.force[p.mask] for p in self.preps]
        self.n_obj = [m.size for m in self.meas]
        rms = [float(np.sqrt(np.mean(m ** 2))) for m in self.meas]
        if normalize:
            std = [float(np.std(m)) for m in self.meas]
            for p, s in zip(self.preps, std):
                if not s > 0:
                    raise ValueError(f"normalize=True needs a varying measured force; record {p.series.label!r} has a "
                                     "constant force")
            self.w = [1.0 / s for s in std]
        else:
            self.w = [1.0] * len(self.preps)
        self.rms = rms
        self.pooled = weighting == "sample"
        self.penalty = PENALTY * sum(w * (r + 1e-300) for w, r in zip(self.w, rms))
        self.n_evaluations = 0
        self.n_infeasible = 0
        self.n_diverged = 0
        self.best = math.inf
        self.best_theta = None
        self.interrupted: KeyboardInterrupt | None = None  # set by run_search when Ctrl-C/SIGTERM ended the search

    # scaling
    def decode(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = np.clip(np.atleast_2d(np.asarray(theta, dtype=np.float64)), 0.0, 1.0)
        vals = self.lo + theta * (self.hi - self.lo)
        P = np.tile(self.base, (theta.shape[0], 1))
        lag = np.tile(self.command.lag_vector(), (theta.shape[0], 1))
        for j, i in enumerate(self.idx):
            if i < 0:
                lag[:, -1 - i] = vals[:, j]
            else:
                P[:, i] = vals[:, j]
        if self.tied_fall:
            lag[:, LAG_FALL] = lag[:, LAG_RISE]
        return P, lag

    @staticmethod
    def scale(values: Mapping[str, float], free: Sequence[str], lo, hi) -> np.ndarray:
        """The free parameters' ``values`` in the [0, 1] scale of their bounds."""
        v = np.array([values[k] for k in free], dtype=np.float64)
        return (v - np.asarray(lo, dtype=np.float64)) / (np.asarray(hi, dtype=np.float64) - np.asarray(lo))

    def _feasible(self, p: np.ndarray, lag: np.ndarray):
        try:
            params = make_params(self.cls, p)
            check_lag(lag)
            return self.cls(params, self.command)
        except ValueError:
            return None

    def simulate(self, theta: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """Per record: model forces (S, n_masked); and the mask of feasible, non-diverged candidates."""
        P, lag = self.decode(theta)
        S = P.shape[0]
        self.n_evaluations += S
        dampers = [self._feasible(P[i], lag[i]) for i in range(S)]
        feas = np.array([d is not None for d in dampers], dtype=bool)
        self.n_infeasible += int(S - feas.sum())
        good = feas.copy()
        out = []
        sel = np.flatnonzero(feas)
        ns = len(self.cls.state_names)
        Y0 = np.zeros((S, ns))
        for i in sel:
            Y0[i] = dampers[i].initial_state()
        for prep in self.preps:
            Fr = np.full((S, int(prep.mask.sum())), np.nan)
            if sel.size:
                F, ok = simulate_batch(self.cls, self.command, prep, P[sel], lag[sel], Y0[sel],
                                        self.integrator_options)
                Fr[sel] = F[:, prep.mask]
                good[sel[~ok]] = False
            out.append(Fr)
        self.n_diverged += int(feas.sum() - good.sum())
        return out, good

    def _J(self, forces, good) -> np.ndarray:
        if self.pooled:  # J2 of all samples pooled: sqrt(Σ_r w_r² Σ_k e² / Σ_r N_r)
            sse = sum(w * w * np.sum((Fr - m) ** 2, axis=1) for Fr, m, w in zip(forces, self.meas, self.w))
            J = np.sqrt(sse / sum(self.n_obj))
        else:  # Σ_r w_r J2_r
            J = sum(w * np.sqrt(np.mean((Fr - m) ** 2, axis=1)) for Fr, m, w in zip(forces, self.meas, self.w))
        J = np.array(J, dtype=np.float64)
        J[~good] = self.penalty
        return J

    def objective(self, theta: np.ndarray) -> np.ndarray:
        """The objective for each row of theta (S, k); the penalty for infeasible or diverged candidates."""
        theta = np.atleast_2d(theta)
        forces, good = self.simulate(theta)
        J = self._J(forces, good)
        self._track(theta, J)
        return J

    def residuals(self, theta: np.ndarray, return_good: bool = False):
        """Residual vectors (S, Σ N_r): w_r (F_model − F_measured)/sqrt(N_r), constant penalty if infeasible
        (and the mask of feasible, non-diverged candidates if ``return_good``)."""
        theta = np.atleast_2d(theta)
        forces, good = self.simulate(theta)
        parts = []
        total = sum(self.n_obj)
        for Fr, m, w, n, rms in zip(forces, self.meas, self.w, self.n_obj, self.rms):
            scale = math.sqrt(total if self.pooled else n)
            R = w * (Fr - m) / scale
            R[~good] = w * PENALTY * (rms + 1e-300) / scale
            parts.append(R)
        R = np.concatenate(parts, axis=1)
        J = self._J(forces, good)
        self._track(theta, J)
        return (R, good) if return_good else R

    def _track(self, theta, J):
        i = int(np.argmin(J))
        if J[i] < self.best:
            self.best = float(J[i])
            self.best_theta = np.array(theta[i], dtype=np.float64)
