"""The exact response of a linear plant to inputs that are linear between samples (first-order hold): the
reference against which controlled responses are normalised (the uncontrolled building of the benchmark)."""
from __future__ import annotations

import numba as nb
import numpy as np
import scipy.linalg


@nb.njit(cache=True)
def _foh_sim(Phi, Ga, Gb, w, X):
    """x_{k+1} = Φ x_k + Γa w_k + Γb (w_{k+1} − w_k) (exact for inputs linear between samples); X[0] given."""
    n = Phi.shape[0]
    m = w.shape[1]
    for k in range(w.shape[0] - 1):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += Phi[i, j] * X[k, j]
            for j in range(m):
                acc += Ga[i, j] * w[k, j] + Gb[i, j] * (w[k + 1, j] - w[k, j])
            X[k + 1, i] = acc


def foh_response(A: np.ndarray, B: np.ndarray, w: np.ndarray, dt: float, x0=None) -> np.ndarray:
    """States x (n_samples, n) of ẋ = A x + B w with w (n_samples, m) linear between samples dt apart."""
    n, m = A.shape[0], B.shape[1]
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n] = A
    M[:n, n:n + m] = B
    M[n:n + m, n + m:] = np.eye(m)
    E = scipy.linalg.expm(M * dt)
    Phi = np.ascontiguousarray(E[:n, :n])
    Ga = np.ascontiguousarray(E[:n, n:n + m])
    Gb = np.ascontiguousarray(E[:n, n + m:] / dt)
    w = np.require(w, np.float64, "CW")  # one compiled variant: numba compiles again for read-only records
    X = np.zeros((w.shape[0], n))
    if x0 is not None:
        X[0] = x0
    _foh_sim(Phi, Ga, Gb, w, X)
    return X
