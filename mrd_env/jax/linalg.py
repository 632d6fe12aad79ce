"""The small dense LU of the Newton iterations, unrolled over lists of scalars: the same operations, in the same
order, as :func:`mrd_env.stepping.matrices.lu_factor` / ``lu_solve`` (partial pivoting, first largest pivot),
with the row swaps written as selections so that a vmapped batch pivots each system on its own (an indexed read
or write with a traced index would be a gather or a scatter over the batch). The schemes factorise each damper's
own block with it (ns × ns, elementwise over the dampers: the scalars may be arrays); :mod:`.scheme`."""
from __future__ import annotations

import jax.numpy as jnp


def lu_factor(M):
    """(LU, piv, ok) of the square matrix M (a list of rows of scalars); ``ok`` False where M is singular."""
    n = len(M)
    M = [list(row) for row in M]
    piv = []
    ok = jnp.asarray(True)
    for k in range(n):
        p = jnp.asarray(k, dtype=jnp.int32)
        big = jnp.abs(M[k][k])
        for i in range(k + 1, n):
            bigger = jnp.abs(M[i][k]) > big
            p = jnp.where(bigger, i, p)
            big = jnp.where(bigger, jnp.abs(M[i][k]), big)
        ok = ok & (big != 0.0) & jnp.isfinite(big)
        piv.append(p)
        row_k = M[k]
        new_k = row_k
        for i in range(k + 1, n):
            new_k = [jnp.where(p == i, M[i][c], new_k[c]) for c in range(n)]
        for i in range(k + 1, n):
            M[i] = [jnp.where(p == i, row_k[c], M[i][c]) for c in range(n)]
        M[k] = new_k
        for i in range(k + 1, n):
            M[i][k] = M[i][k] / M[k][k]
            f = M[i][k]
            for c in range(k + 1, n):
                M[i][c] = M[i][c] - f * M[k][c]
    return M, piv, ok


def lu_solve(LU, piv, b):
    """x with M x = b from the factors of :func:`lu_factor` (b a list of scalars)."""
    n = len(b)
    b = list(b)
    for k in range(n):
        bk = b[k]
        new_k = bk
        for i in range(k + 1, n):
            new_k = jnp.where(piv[k] == i, b[i], new_k)
            b[i] = jnp.where(piv[k] == i, bk, b[i])
        b[k] = new_k
    for i in range(n):
        for k in range(i):
            b[i] = b[i] - LU[i][k] * b[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            b[i] = b[i] - LU[i][k] * b[k]
        b[i] = b[i] / LU[i][i]
    return b
