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
    split = [sc.delay_split(lag[j, 2], dt) for j in range(nd)]
    Y0 = [Y0[i] for i in range(Y0.shape[0])]
    U0 = [U0[j] for j in range(nd)]
    F0, finite = sc.end_forces(m_, plant.C, plant.D, P, Y0, U0, [W[0, k] for k in range(W.shape[1])])

    def body(c, r):
        Y, U, F, qu, nsub, work, status = c
        qu = jnp.concatenate([V[r][None], qu[:-1]])
        cmds = ([qu[split[j][0] + 1, j] for j in range(nd)], [qu[split[j][0], j] for j in range(nd)],
                [split[j][1] for j in range(nd)])
        w0 = [W[r, k] for k in range(W.shape[1])]
        w1 = [W[r + 1, k] for k in range(W.shape[1])]
        st, Yn, Un, Fn, used, nsub_n, work = sc.macro_step(
            m_, plant, P, [[lag[j, 0], lag[j, 1]] for j in range(nd)], cmds, Y, U, F, w0, w1, dt, atol, rtol, nsub,
            work, exact=exact, max_level=max_level_of(MAX_SUBSTEPS), substeps=substeps,
            newton_iterations=newton_iterations)
        ok = status == OK
        keep = lambda new, old: [jnp.where(ok, a, b) for a, b in zip(new, old)]  # noqa: E731
        Y, U, F = keep(Yn, Y), keep(Un, U), keep(Fn, F)
        status = jnp.where(ok, st, status)
        return (Y, U, F, qu, jnp.where(ok, nsub_n, nsub), work, status), (jnp.stack(F), jnp.stack(Y), status, used)

    init = (Y0, U0, F0, jnp.tile(jnp.stack(U0)[None], (queue, 1)), jnp.asarray(1), sc.empty_work(nd, m_.ns),
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
