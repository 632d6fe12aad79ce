"""The linear part of a coupled system and the small dense LU solver the kernel's Newton iterations use."""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from .scheme import GAMMA


@nb.njit(cache=True)
def lu_factor(M, piv):
    """In-place LU with partial pivoting; returns False if M is singular."""
    n = M.shape[0]
    for k in range(n):
        p = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                p = i
        if big == 0.0 or not math.isfinite(big):
            return False
        piv[k] = p
        if p != k:
            for c in range(n):
                tmp = M[k, c]
                M[k, c] = M[p, c]
                M[p, c] = tmp
        for i in range(k + 1, n):
            M[i, k] /= M[k, k]
            f = M[i, k]
            if f != 0.0:
                for c in range(k + 1, n):
                    M[i, c] -= f * M[k, c]
    return True


@nb.njit(cache=True)
def lu_solve(M, piv, b):
    """Solve M x = b in place (b becomes x) with the factors of :func:`lu_factor`."""
    n = M.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        for k in range(i):
            b[i] -= M[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            b[i] -= M[i, k] * b[k]
        b[i] /= M[i, i]


class SystemMatrices:
    """The linear part of a coupled system (see :mod:`mrd_env.stepping`); empty plant for the rig.

    Shapes: A (nq, nq), BF (nq, nd), Bw (nq, nw), Cx/Cv (nd, nq), Dx/Dv/Da (nd, nw).
    """

    def __init__(self, nd: int, nw: int, A=None, BF=None, Bw=None, Cx=None, Dx=None, Cv=None, Dv=None, Da=None):
        nq = 0 if A is None else np.asarray(A).shape[0]

        def mat(a, shape):
            out = np.zeros(shape) if a is None else np.ascontiguousarray(a, dtype=np.float64)
            if out.shape != shape:
                raise ValueError(f"system matrix has shape {out.shape}, expected {shape}")
            return out

        self.nq, self.nd, self.nw = nq, nd, nw
        self.A = mat(A, (nq, nq))
        self.BF = mat(BF, (nq, nd))
        self.Bw = mat(Bw, (nq, nw))
        self.Cx = mat(Cx, (nd, nq))
        self.Dx = mat(Dx, (nd, nw))
        self.Cv = mat(Cv, (nd, nq))
        self.Dv = mat(Dv, (nd, nw))
        self.Da = mat(Da, (nd, nw))
        self._levels: dict = {}

    @classmethod
    def displacement_driven(cls) -> "SystemMatrices":
        """The virtual rig: no plant, one damper whose x, ẋ, ẍ are the inputs w = (x, ẋ, ẍ)."""
        e = np.eye(3)
        return cls(nd=1, nw=3, Dx=e[0:1], Dv=e[1:2], Da=e[2:3])

    @property
    def C(self) -> np.ndarray:
        """[C_x, C_v] stacked (2, nd, nq), as the kernel takes them."""
        return np.ascontiguousarray(np.stack([self.Cx, self.Cv]))

    @property
    def D(self) -> np.ndarray:
        """[D_x, D_v, D_a] stacked (3, nd, nw)."""
        return np.ascontiguousarray(np.stack([self.Dx, self.Dv, self.Da]))

    def levels(self, dt: float, max_level: int) -> tuple[np.ndarray, ...]:
        """The plant's elimination matrices for the sub-step lengths h = dt/2^k, k = 0..max_level, stacked
        along the first axis: (I − hγA)⁻¹, hγ(I − hγA)⁻¹B_w, M_q = hγ(I − hγA)⁻¹B_F and [C_x M_q, C_v M_q]."""
        key = (float(dt), int(max_level))
        hit = self._levels.get(key)
        if hit is None:
            nq, nd, nw = self.nq, self.nd, self.nw
            L = max_level + 1
            Ainv, Bbar, Mq = np.zeros((L, nq, nq)), np.zeros((L, nq, nw)), np.zeros((L, nq, nd))
            PP = np.zeros((L, 2, nd, nd))
            for k in range(L):
                c = GAMMA * dt / 2 ** k
                inv = np.linalg.inv(np.eye(nq) - c * self.A) if nq else np.zeros((0, 0))
                Ainv[k] = inv
                Bbar[k] = c * inv @ self.Bw
                Mq[k] = c * inv @ self.BF
                PP[k, 0] = self.Cx @ Mq[k]
                PP[k, 1] = self.Cv @ Mq[k]
            hit = self._levels[key] = tuple(np.ascontiguousarray(a) for a in (Ainv, Bbar, Mq, PP))
        return hit
