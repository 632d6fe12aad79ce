"""The small dense LU of the Newton iterations, unrolled over lists of scalars: the same operations, in the same
order, as :func:`mrd_env.stepping.matrices.lu_factor` / ``lu_solve`` (partial pivoting, first largest pivot),
with the row swaps written as selections so that a vmapped batch pivots each system on its own. For the 2×2 and
3×3 systems of one damper this beats a call to LAPACK inside a scan (the prototype's finding). Systems of several
dampers (the full car's 12×12) are factorised on an array instead (:data:`UNROLL_UP_TO`): the same operations, each
element's in the same order, which compiles in seconds where the unrolled selections took minutes. Row swaps are
selections throughout, never indexed reads or writes with a traced index: under ``vmap`` those are gathers and
scatters, which XLA's CPU backend runs as serial loops over the batch."""
from __future__ import annotations

import jax.numpy as jnp


#: The largest system factorised unrolled (scalar selections); larger ones on an array.
UNROLL_UP_TO = 4


def lu_factor(M):
    """(LU, piv, ok) of the square matrix M (a list of rows of scalars); ``ok`` False where M is singular."""
    n = len(M)
    if n > UNROLL_UP_TO:
        return _lu_factor_array(M)
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


def _pick(rows, p, first: int = 0):
    """rows[p] for a traced index p in [first, len(rows)), as a chain of selections: the value itself, exactly
    (under ``vmap`` an indexed read or write of a batch is a gather or a scatter, which XLA's CPU backend runs as
    a serial loop over the batch)."""
    out = rows[-1]
    for i in range(len(rows) - 2, first - 1, -1):
        out = jnp.where(p == i, rows[i], out)
    return out


def _lu_factor_array(M):
    """:func:`lu_factor` on an (n, n) array: the pivot is the first largest (``argmax``), the swap two row
    selections, the elimination M[i, c] − f_i·M[k, c] element by element as the unrolled loops do it."""
    n = len(M)
    A = jnp.stack([jnp.stack([jnp.asarray(x, jnp.float64) for x in row]) for row in M])
    rows = jnp.arange(n)[:, None]
    piv = []
    ok = jnp.asarray(True)
    for k in range(n):
        p = (k + jnp.argmax(jnp.abs(A[k:, k]))).astype(jnp.int32)
        row_k, row_p = A[k], _pick([A[i] for i in range(n)], p, k)
        big = jnp.abs(row_p[k])
        ok = ok & (big != 0.0) & jnp.isfinite(big)
        piv.append(p)
        A = jnp.where(rows == k, row_p, jnp.where(rows == p, row_k, A))
        if k + 1 < n:
            f = A[k + 1:, k] / A[k, k]
            A = A.at[k + 1:, k].set(f)
            A = A.at[k + 1:, k + 1:].set(A[k + 1:, k + 1:] - f[:, None] * A[k, k + 1:][None, :])
    return [[A[i, c] for c in range(n)] for i in range(n)], piv, ok


def lu_solve(LU, piv, b):
    """x with M x = b from the factors of :func:`lu_factor` (b a list of scalars)."""
    n = len(b)
    if n > UNROLL_UP_TO:  # the row swaps as selections of the pivot's entry
        b = list(b)
        for k in range(n):
            bk, bp = b[k], _pick(b, piv[k], k)
            b = b[:k] + [bp] + [jnp.where(piv[k] == i, bk, b[i]) for i in range(k + 1, n)]
    else:
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
