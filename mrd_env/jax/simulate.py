"""Any coupled system (a plant's :class:`~mrd_env.stepping.SystemMatrices`, or the rig's) over a record of steps in
JAX: the twin of :func:`mrd_env.stepping.run` (one call is one control period of the kernel: the Newton matrix is
not carried in from before it), for cross-checks and gradients."""
from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..stepping.scheme import ATOL, MAX_SUBSTEPS, OK, RTOL, max_level_of
from . import scheme as sc
from .dampers import jax_damper


def plant_arrays(system, dt: float) -> sc.Plant:
    """The :class:`~mrd_env.jax.scheme.Plant` of a :class:`~mrd_env.stepping.SystemMatrices` at step ``dt``."""
    levels = system.levels(dt, max_level_of(MAX_SUBSTEPS))
    return sc.Plant(*(jnp.asarray(a) for a in (system.C, system.D, *levels)))


@functools.partial(jax.jit, static_argnames=("model", "queue", "scheme", "substeps", "newton_iterations"))
def simulate(plant: sc.Plant, P, lag, Y0, U0, V, W, dt, *, model: str, queue: int = 2, scheme: str = "exact",
             substeps: int = 1, newton_iterations: int = 2, atol: float = ATOL, rtol: float = RTOL):
    """Forces (n_steps, nd), states (n_steps, n), statuses and sub-steps (n_steps,) at the end of every step, from
    the states Y0 (n,) and effective commands U0 (nd,) (the commands before the record: U0), with commands V
    (n_steps, nd) held over each step and inputs W (n_steps + 1, nw). ``P`` (nd, n_params), ``lag`` (nd, 3)."""
    m_ = jax_damper(model)
    nd = U0.shape[0]
    exact = scheme == "exact"
    whole, ts = sc.delay_split(lag[:, 2], dt)
    P = sc.param_columns(P)  # split once, outside the steps' loop
    F0, finite = sc.end_forces(m_, plant.C, plant.D, P, Y0, U0, W[0], exact=exact)

    def body(c, r):
        Y, U, F, qu, nsub, work, status = c
        qu = jnp.concatenate([V[r][None], qu[:-1]])
        va, vb = qu[-1], qu[-1]
        for i in range(queue - 2, -1, -1):
            va = jnp.where(whole + 1 == i, qu[i], va)
            vb = jnp.where(whole == i, qu[i], vb)
        st, Yn, Un, Fn, used, nsub_n, work = sc.macro_step(
            m_, plant, P, lag[:, :2], (va, vb, ts), Y, U, F, W[r], W[r + 1], dt, atol, rtol, nsub, work, exact=exact,
            max_level=max_level_of(MAX_SUBSTEPS), substeps=substeps, newton_iterations=newton_iterations)
        ok = status == OK
        Y, U, F = (jnp.where(ok, a, b) for a, b in ((Yn, Y), (Un, U), (Fn, F)))
        status = jnp.where(ok, st, status)
        return (Y, U, F, qu, jnp.where(ok, nsub_n, nsub), work, status), (F, Y, status, used)

    init = (Y0, U0, F0, jnp.tile(U0[None], (queue, 1)), jnp.asarray(1), sc.empty_work(nd, m_.ns) if exact else None,
            jnp.where(finite, OK, sc.NONFINITE))
    _, (F, Y, status, used) = lax.scan(body, init, jnp.arange(V.shape[0]))
    return F, Y, status, used


def run(damper, system, Y0, U0, V, W, dt: float, **options):
    """:func:`simulate` for a :class:`~mrd_env.dampers.DamperModel` and a ``SystemMatrices`` (numpy in, the
    arrays of :func:`simulate` out); ``options``: scheme, substeps, newton_iterations, atol, rtol."""
    nd = system.nd
    lag = np.tile(damper.command.lag_vector(), (nd, 1))
    queue = int(math.floor(damper.command.delay / dt * (1 + 1e-12))) + 2
    return simulate(plant_arrays(system, dt), jnp.asarray(np.tile(damper.params.as_array(), (nd, 1))),
                    jnp.asarray(lag), jnp.asarray(Y0, dtype=jnp.float64), jnp.asarray(U0, dtype=jnp.float64),
                    jnp.asarray(V, dtype=jnp.float64), jnp.asarray(W, dtype=jnp.float64), dt, model=damper.name,
                    queue=queue, **options)
