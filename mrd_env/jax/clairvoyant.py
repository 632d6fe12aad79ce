"""The clairvoyant optimum by gradient: an episode's return maximised over its command sequence with
``jax.value_and_grad`` through a plant's JAX twin (the differentiable scheme) and scipy's bounded L-BFGS-B.

The procedure is :func:`mrd_env.optimal.clairvoyant`'s (the CasADi path), with the gradient from JAX in place of
the smoothed CasADi model's: warm starts ranked by their return in the native environment, the optimiser run from
the ``n_starts`` best, command blocks of ``coarse`` control steps first, then every step (the same stop rules:
:func:`mrd_env.optimal.full_knowledge.minimize_lbfgsb`), each result re-simulated in the native environment and
the best kept (a warm start when no optimised sequence beats it). L-BFGS-B rather than an optax first-order method:
the problem is smooth enough for a quasi-Newton method, has box bounds only, and the CasADi path uses the same
solver, so the two differ by their model and gradient alone.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np


@dataclass
class GradientClairvoyant:
    """The result: the best return in the native environment, its commands (n_steps, nd), where they come from
    ("optimiser" or a warm start's name), the warm starts' returns, the runs (the CasADi path's
    :class:`~mrd_env.optimal.full_knowledge.Solve`, its ``terminated`` left False), the wall time (s, compilation
    included) and the compilation's share."""
    ret: float
    commands: np.ndarray
    source: str
    warm_returns: dict
    solves: list = field(default_factory=list)
    wall_time: float = 0.0
    compile_seconds: float = 0.0


#: The jitted value and gradient of each episode-return function (one compilation per function and shapes).
_COMPILED: dict = {}


def _value_and_grad(episode_return):
    if episode_return not in _COMPILED:
        _COMPILED[episode_return] = jax.jit(jax.value_and_grad(lambda V, data: -episode_return(V, data)))
    return _COMPILED[episode_return]


def clairvoyant(episode_return: Callable, replay: Callable[[np.ndarray], float], warm_starts: Mapping[str, np.ndarray],
                v_min: float, v_max: float, *, data=None, n_starts: int = 1, coarse: tuple[int, ...] = (10,),
                max_iter: int = 1000, tol: float = 1e-5) -> GradientClairvoyant:
    """Maximise ``episode_return(V, data)`` (a JAX function of the commands V (n_steps, nd), physical units, and
    of the episode's arrays ``data``, a pytree: passed as an argument, so that the episodes of one set-up share one
    compilation) within [``v_min``, ``v_max``].

    ``replay(commands)``: the native environment's return of a command sequence (the yardstick); ``warm_starts``:
    {name: commands}, ranked by ``replay``; ``n_starts``: how many of the best the optimiser starts from;
    ``coarse``: command blocks (in control steps, each ≥ 2) solved first, longest first; ``max_iter`` per level;
    ``tol``: the final level's relative improvement over 20 iterations that stops it.
    """
    from ..optimal.full_knowledge import COARSE_TOL, COARSE_WINDOW, WINDOW, Solve, blocked, minimize_lbfgsb

    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
        raise ValueError(f"n_starts must be an int >= 0, got {n_starts!r}")
    if not warm_starts:
        raise ValueError("warm_starts must hold at least one command sequence")
    t_start = time.perf_counter()
    starts = {k: np.asarray(v, dtype=np.float64) for k, v in warm_starts.items()}
    shape = next(iter(starts.values())).shape
    for k, v in starts.items():
        if v.shape != shape or v.ndim != 2:
            raise ValueError(f"warm_starts[{k!r}] must have shape {shape} (n_steps, nd), got {v.shape}")
    blocks = sorted({int(b) for b in coarse if 2 <= int(b) < shape[0]}, reverse=True) + [1]
    warm_returns = {k: float(replay(v)) for k, v in starts.items()}
    ranked = sorted(starts, key=lambda k: warm_returns[k], reverse=True)
    best = (warm_returns[ranked[0]], starts[ranked[0]], ranked[0])

    vg = _value_and_grad(episode_return)
    t0 = time.perf_counter()
    fun0 = vg(jnp.asarray(starts[ranked[0]]), data)  # the compilation (or the cache's), timed apart from the solves
    jax.block_until_ready(fun0)
    compile_s = time.perf_counter() - t0

    def fun(V):
        val, g = vg(jnp.asarray(V), data)
        return float(val), np.asarray(g)

    solves = []
    for name in ranked[:n_starts]:
        V = starts[name]
        t0 = time.perf_counter()
        statuses, ok, nit, nev = [], True, 0, 0
        for level, blk in enumerate(blocks):
            final = level == len(blocks) - 1
            fb, Vc0, expand = blocked(fun, V, blk)
            Vc, st, ok_l, it_l, ev_l = minimize_lbfgsb(fb, Vc0, v_min, v_max, max_iter, tol if final else COARSE_TOL,
                                                       WINDOW if final else COARSE_WINDOW, None)
            V = expand(Vc)
            statuses.append(f"{blk}-step blocks: {st}")
            ok, nit, nev = ok and ok_l, nit + it_l, nev + ev_l
            if not ok_l:
                break
        V = np.clip(V, v_min, v_max)
        secs = time.perf_counter() - t0
        ret = float(replay(V))
        solves.append(Solve(name, "; ".join(statuses), ok, nit, nev, secs, -fun(V)[0], ret))
        if ret > best[0]:
            best = (ret, V, "optimiser")
    return GradientClairvoyant(ret=float(best[0]), commands=np.asarray(best[1]), source=best[2],
                               warm_returns=warm_returns, solves=solves, wall_time=time.perf_counter() - t_start,
                               compile_seconds=compile_s)
