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

import dataclasses
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax


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


# --- a suite's episodes solved together ------------------------------------------------------------------------
#: The batched solver's end of an episode's run: converged by the window rule, converged (projected gradient
#: zero), the iteration or evaluation limit, the line search failed (abnormal, as scipy's ABNORMAL_TERMINATION),
#: the line search failed at a point stationary to the cost's rounding (``mrd_env.optimal.full_knowledge.FLAT_GTOL``: converged).
_RUNNING, _CONVERGED, _STATIONARY, _LIMIT, _ABNORMAL, _FLAT = range(6)
#: Backtracking steps of the line search (scipy's L-BFGS-B: 20).
MAX_LINESEARCH = 20
#: The largest projected gradient (inf-norm) that counts as stationary (the CasADi path's ``gtol``).
GTOL = 1e-12


@dataclass
class EpisodeBatch:
    """Episodes of one structure stacked for :func:`batched_clairvoyant`: ``data`` = (params, first states), every
    leaf with a leading episode axis; ``steps`` (B,), each episode's control steps; ``n_steps``, the padded length
    (an episode's commands past its end change nothing: its return stops there)."""
    data: tuple
    steps: np.ndarray
    n_steps: int

    def pad(self, commands) -> np.ndarray:
        """(B, n_steps, nd) from one command sequence per episode (n_b, nd), each padded with its last row."""
        out = []
        for b, V in enumerate(commands):
            V = np.asarray(V, dtype=np.float64)
            if V.ndim != 2 or len(V) != self.steps[b]:
                raise ValueError(f"commands[{b}] must have shape ({self.steps[b]}, nd), got {V.shape}")
            out.append(np.concatenate([V, np.repeat(V[-1:], self.n_steps - len(V), axis=0)]))
        return np.stack(out)

    def unpad(self, V) -> list[np.ndarray]:
        """Each episode's own commands (n_b, nd) of a padded batch (B, n_steps, nd)."""
        return [np.asarray(V[b, :n]) for b, n in enumerate(self.steps)]


def episode_batch(problems, **scheme) -> EpisodeBatch:
    """The JAX twins of :class:`~mrd_env.optimal.EpisodeProblem` s (:func:`mrd_env.jax.env.params_of_problem`,
    ``scheme`` as it takes it, e.g. ``scheme="differentiable"``), stacked: the shorter episodes' inputs held at
    their last row up to the longest's. ``ValueError`` when the episodes differ in the compiled step's structure
    (the plant, damper, signals, sensors: one batch is one program)."""
    from . import env as je

    problems = list(problems)
    if not problems:
        raise ValueError("problems: the batch needs one episode or more")
    params = [je.params_of_problem(p, **scheme) for p in problems]
    n_steps = max(p.n_steps for p in params)
    rows = max(p.W.shape[1] for p in params)
    padded = []
    for p in params:
        W = jnp.concatenate([p.W, jnp.repeat(p.W[:, -1:], rows - p.W.shape[1], axis=1)], axis=1)
        padded.append(dataclasses.replace(p, W=W, n_steps=n_steps))
    first = jax.tree_util.tree_structure(padded[0])
    for b, p in enumerate(padded[1:], 1):
        if jax.tree_util.tree_structure(p) != first or any(
                np.shape(x) != np.shape(y) for x, y in zip(jax.tree_util.tree_leaves(p),
                                                           jax.tree_util.tree_leaves(padded[0]))):
            differ = [f.name for f in dataclasses.fields(p) if f.name not in ("W", "n_steps")
                      and not _same(getattr(p, f.name), getattr(padded[0], f.name))]
            raise ValueError(f"problems[{b}] ({problems[b].episode_name}) differs from problems[0] in {differ}: "
                             "the episodes of one batch must share the compiled step's structure")
    states = [je.reset(None, p, record=0)[1] for p in padded]
    stack = lambda *xs: jnp.stack(xs)  # noqa: E731
    data = (jax.tree_util.tree_map(stack, *padded), jax.tree_util.tree_map(stack, *states))
    return EpisodeBatch(data, np.array([p.n_steps for p in problems], dtype=int), int(n_steps))


def structure_groups(problems, **scheme) -> list[list[int]]:
    """The indices of ``problems`` grouped by the compiled step's structure (first appearance order): each group
    can be one :func:`episode_batch`. A robustness twin's episodes differ in it where their drawn command delays
    differ (the delay queue's length)."""
    from . import env as je

    groups: list[tuple[object, list[int]]] = []
    for i, p in enumerate(problems):
        params = je.params_of_problem(p, **scheme)
        for first, members in groups:
            if all(_same(getattr(params, f.name), getattr(first, f.name)) for f in dataclasses.fields(params)
                   if f.name not in ("W", "n_steps")):
                members.append(i)
                break
        else:
            groups.append((params, [i]))
    return [members for _, members in groups]


def _same(a, b) -> bool:
    """Whether two fields of EnvParams agree in what a compiled program sees (static values, array shapes)."""
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    if jax.tree_util.tree_structure(a) != jax.tree_util.tree_structure(b) or len(la) != len(lb):
        return False
    return all((np.shape(x) == np.shape(y)) if hasattr(x, "shape") else x == y for x, y in zip(la, lb))


@dataclass
class BatchedClairvoyant:
    """:func:`batched_clairvoyant`'s result, per episode (leading axis B): the commands (B, n_steps, nd) within
    [v_min, v_max], the twin's return of them (to be re-simulated natively: the twin is an approximation), the
    status (each level's, as the per-episode path words it), success, iterations and function evaluations (all
    levels), and the batch's wall time (s) and, of it, the compilation's."""
    commands: np.ndarray
    model_returns: np.ndarray
    status: list
    success: np.ndarray
    iterations: np.ndarray
    evaluations: np.ndarray
    wall_time: float = 0.0
    compile_seconds: float = 0.0


def _two_loop(g, free, S, Yd, count, memory):
    """The L-BFGS direction −H·g on the free variables (the pairs' products restricted to them; the oldest pair
    first out of the ring buffer ``S``, ``Yd`` (memory, n), ``count`` pairs stored so far)."""
    k = jnp.minimum(count, memory)
    q = g * free

    def pair(i):
        j = (count - 1 - i) % memory
        s, y = S[j] * free, Yd[j] * free
        sy = s @ y
        use = (i < k) & (sy > 0)
        return s, y, jnp.where(use, sy, 1.0), use

    def backward(i, c):
        q, alphas = c
        s, y, sy, use = pair(i)
        a = jnp.where(use, (s @ q) / sy, 0.0)
        return q - a * y, alphas.at[i].set(a)

    q, alphas = lax.fori_loop(0, memory, backward, (q, jnp.zeros(memory, q.dtype)))
    s, y, sy, use = pair(0)
    gnorm = jnp.linalg.norm(q)
    # the newest pair's scale (H0 = s·y / y·y); without one, a first step of unit length as scipy's L-BFGS-B takes
    r = q * jnp.where(use, sy / jnp.where(use, y @ y, 1.0), 1.0 / jnp.where(gnorm > 0, gnorm, 1.0))

    def forward(i, r):
        i = memory - 1 - i
        s, y, sy, use = pair(i)
        return r + jnp.where(use, alphas[i] - (y @ r) / sy, 0.0) * s

    return -lax.fori_loop(0, memory, forward, r) * free


def _block_means(V, blk):
    """(n, nd) commands as block values: row i < ceil(n / blk) the mean of block i, the rows after it zero."""
    n = V.shape[0]
    idx = jnp.arange(n) // blk
    return jax.ops.segment_sum(V, idx, n) / jnp.maximum(jax.ops.segment_sum(jnp.ones(n), idx, n), 1.0)[:, None]


def _projected_lbfgs(fg, V0, lo, hi, blocks, *, max_iter, tol, memory):
    """Minimise ``fg(x, blk)``'s value (``fg`` -> (value, gradient); x (n, nd): the values of the command blocks of
    ``blk`` steps in its first rows, the others unused) within [lo, hi] from the commands ``V0`` (n, nd), the
    ``blocks`` levels in turn (longest first, as :func:`clairvoyant`), by projected L-BFGS: the variables at a bound
    that the gradient pushes out are held, the L-BFGS direction taken on the others, the step projected onto the
    box and halved until it decreases the value by Armijo's rule along the projected path. Each level stops by the
    CasADi path's rules (:func:`mrd_env.optimal.full_knowledge.minimize_lbfgsb`): an improvement < its tolerance
    (relative) over its window of iterations, a stationary point, ``max_iter`` iterations or 3 × ``max_iter``
    evaluations, or a failed line search (abnormal: the episode's run ends there). A line search that fails along
    the L-BFGS direction drops the stored pairs and tries the steepest descent once (L-BFGS-B's restart) before it
    counts as failed: the differentiable scheme's cost is rough at the 1e-12 level, and near a level's optimum a
    stale quasi-Newton direction stopped the coarse level of a short car episode after 14 iterations, 31 % of its
    range short of scipy's L-BFGS-B, which restarts.

    One loop, one evaluation of ``fg`` per pass (a level's start or a trial step), so that the program holds one
    copy of the episode's gradient (its compilation is most of the cost). One episode; the caller vmaps it.
    Returns (commands (n, nd), value, each level's status, iterations, evaluations)."""
    from ..optimal.full_knowledge import COARSE_TOL, COARSE_WINDOW, FLAT_GTOL, WINDOW

    n, nd = V0.shape
    last = len(blocks) - 1
    blk_of = jnp.asarray(blocks)
    rtol_of = jnp.asarray([COARSE_TOL] * last + [tol])
    window_of = jnp.asarray([COARSE_WINDOW] * last + [WINDOW])
    ring = max(COARSE_WINDOW, WINDOW) + 1
    size = n * nd
    zeros = jnp.zeros(size)
    x0 = _block_means(V0, blocks[0]).ravel()
    # (x, f, g, direction, step, S, Yd, pairs, level, starting, tries, level's iterations and evaluations, history,
    #  each level's status, iterations, evaluations)
    init = (x0, jnp.asarray(0.0), zeros, zeros, jnp.asarray(1.0), jnp.zeros((memory, size)), jnp.zeros((memory, size)),
            jnp.asarray(0), jnp.asarray(0), jnp.asarray(True), jnp.asarray(0), jnp.asarray(0), jnp.asarray(0),
            jnp.zeros(ring), jnp.full(len(blocks), _RUNNING), jnp.asarray(0), jnp.asarray(0))

    def running(c):
        return c[8] <= last

    def direction(x, g, S, Yd, count):
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        d = _two_loop(g, free, S, Yd, count, memory)
        steepest = -g * free / jnp.maximum(jnp.linalg.norm(g * free), 1e-300)
        return jnp.where(g @ d < 0, d, steepest)

    def iteration(c):
        x, f, g, d, a, S, Yd, count, level, starting, tries, it, ev, hist, statuses, its, evs = c
        blk = blk_of[level]
        xt = jnp.where(starting, x, jnp.clip(x + a * d, lo, hi))
        ft, gt = fg(xt.reshape(n, nd), blk)
        gt = gt.ravel()
        ev, evs = ev + 1, evs + 1
        # a trial step: accepted by Armijo's rule along the projected path, else halved
        ok = starting | (jnp.isfinite(ft) & (ft <= f + 1e-4 * (g @ (xt - x))) & jnp.any(xt != x))
        restart = ~ok & (tries + 1 >= MAX_LINESEARCH) & (count > 0)  # the steepest descent before giving up
        s, y = xt - x, gt - g
        store = ok & ~starting & (s @ y > 2.2e-16 * (y @ y))  # curvature: the pair keeps H positive definite
        j = count % memory
        S, Yd = jnp.where(store, S.at[j].set(s), S), jnp.where(store, Yd.at[j].set(y), Yd)
        count = jnp.where(starting | restart, 0, count + store)
        stepped = ok & ~starting
        it, its = it + stepped, its + stepped
        tries = jnp.where(ok | restart, 0, tries + 1)
        x, f, g = jnp.where(ok, xt, x), jnp.where(ok, ft, f), jnp.where(ok, gt, g)
        hist = jnp.where(starting, jnp.full(ring, ft), jnp.where(stepped, hist.at[it % ring].set(f), hist))
        window = window_of[level]
        old = hist[(it - window) % ring]
        pg = jnp.max(jnp.abs(jnp.clip(x - g, lo, hi) - x))
        failed = jnp.where(pg <= FLAT_GTOL, _FLAT, _ABNORMAL)
        status = jnp.select([tries >= MAX_LINESEARCH, (it > window) & (old - f <= rtol_of[level]
                                                                          * jnp.maximum(jnp.abs(f), 1e-12)),
                             pg <= GTOL, (it >= max_iter) | (ev >= 3 * max_iter)],
                            [failed, _CONVERGED, _STATIONARY, _LIMIT], _RUNNING)
        done = status != _RUNNING
        statuses = statuses.at[level].set(status)
        # the level's end: the next level starts from its commands (block means), unless it failed
        V = x.reshape(n, nd)[jnp.arange(n) // blk]
        nxt = jnp.where(done, jnp.where(status == _ABNORMAL, last + 1, level + 1), level)
        x = jnp.where(done & (nxt <= last), _block_means(V, blk_of[jnp.minimum(nxt, last)]).ravel(),
                      jnp.where(done, V.ravel(), x))
        starting = done
        it, ev = jnp.where(done, 0, it), jnp.where(done, 0, ev)
        d = direction(x, g, S, Yd, count)
        a = jnp.where(ok | restart, 1.0, a * 0.5)
        return x, f, g, d, a, S, Yd, count, nxt, starting, tries, it, ev, hist, statuses, its, evs

    out = lax.while_loop(running, iteration, init)
    x, f, statuses, its, evs = out[0], out[1], out[14], out[15], out[16]
    return x.reshape(n, nd), f, statuses, its, evs


def _status_text(code: int, rtol: float, window: int) -> str:
    from ..optimal.full_knowledge import flat_status

    return {_CONVERGED: f"converged (improvement < {rtol:g} over {window} iterations)",
            _STATIONARY: "converged (projected gradient below 1e-12)", _LIMIT: "iteration limit",
            _FLAT: flat_status(),
            _ABNORMAL: "ABNORMAL: the line search found no decrease", _RUNNING: "not run"}[int(code)]


def _batched_program(episode_return, blocks, max_iter, tol, memory):
    """The jitted program (V0 (B, n, nd), data, lo, hi) -> per episode (commands, return, each level's status,
    iterations, evaluations) of :func:`batched_clairvoyant`."""

    def one(V0, data, lo, hi):
        n = V0.shape[0]

        def fg(x, blk):
            return jax.value_and_grad(lambda x: -episode_return(x[jnp.arange(n) // blk], data))(x)

        V, f, statuses, its, evs = _projected_lbfgs(fg, V0, lo, hi, blocks, max_iter=max_iter, tol=tol,
                                                     memory=memory)
        return jnp.clip(V, lo, hi), -f, statuses, its, evs

    return jax.jit(jax.vmap(one, in_axes=(0, 0, None, None)))


def batched_clairvoyant(episode_return: Callable, data, V0, v_min: float, v_max: float, *,
                        coarse: tuple[int, ...] = (10,), max_iter: int = 1000, tol: float = 1e-5,
                        memory: int = 10) -> BatchedClairvoyant:
    """Maximise ``episode_return(V, data_b)`` over every episode b's commands V within [``v_min``, ``v_max``] at
    once: one compiled program, the vmap over the batch of a projected L-BFGS (:func:`_projected_lbfgs`: bounded
    quasi-Newton, run on the device, ``memory`` pairs) through ``jax.value_and_grad``.

    ``data``: a pytree whose leaves have a leading episode axis B (:class:`EpisodeBatch`'s ``data``); ``V0`` (B,
    n_steps, nd): each episode's start; ``coarse``, ``max_iter``, ``tol``: as :func:`clairvoyant`'s (command
    blocks first, the final level stopped by an improvement < ``tol`` over 20 iterations). The commands are the
    twin's optimum: re-simulate them in the native environment (``EpisodeProblem.replay``) before trusting them."""
    V0 = np.asarray(V0, dtype=np.float64)
    if V0.ndim != 3:
        raise ValueError(f"V0 must have shape (episodes, n_steps, nd), got {V0.shape}")
    if not v_min < v_max:
        raise ValueError(f"v_min must be below v_max, got [{v_min}, {v_max}]")
    for name, v in (("max_iter", max_iter), ("memory", memory)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name} must be an int >= 1, got {v!r}")
    if not 0 < tol < 1:
        raise ValueError(f"tol must be in (0, 1), got {tol!r}")
    lead = {np.shape(x)[0] if np.ndim(x) else None for x in jax.tree_util.tree_leaves(data)}
    if lead != {len(V0)}:
        raise ValueError(f"data's leaves must all have the batch's leading axis {len(V0)}, got {sorted(lead, key=str)}")
    t_start = time.perf_counter()
    blocks = sorted({int(b) for b in coarse if 2 <= int(b) < V0.shape[1]}, reverse=True) + [1]
    key = (episode_return, V0.shape, tuple(blocks), max_iter, tol, memory)
    if key not in _COMPILED:
        _COMPILED[key] = _batched_program(episode_return, tuple(blocks), max_iter, tol, memory)
    args = (jnp.asarray(np.clip(V0, v_min, v_max)), data, jnp.asarray(float(v_min)), jnp.asarray(float(v_max)))
    shapes = (key, jax.tree_util.tree_structure(data),
              tuple((np.shape(x), str(getattr(x, "dtype", type(x)))) for x in jax.tree_util.tree_leaves(data)))
    t0 = time.perf_counter()
    if shapes not in _COMPILED:  # compiled apart from the run, so that the run's time is the solves'
        _COMPILED[shapes] = _COMPILED[key].lower(*args).compile()
    compiled = _COMPILED[shapes]
    compile_s = time.perf_counter() - t0
    V, ret, statuses, its, evs = jax.block_until_ready(compiled(*args))
    from ..optimal.full_knowledge import COARSE_TOL, COARSE_WINDOW, WINDOW

    words, success = [], []
    for row in np.asarray(statuses):
        levels = []
        for level, (blk, code) in enumerate(zip(blocks, row)):
            final = level == len(blocks) - 1
            if code != _RUNNING:
                levels.append(f"{blk}-step blocks: " + _status_text(code, tol if final else COARSE_TOL,
                                                                     WINDOW if final else COARSE_WINDOW))
        words.append("; ".join(levels))
        success.append(all(c != _ABNORMAL for c in row) and row[-1] != _RUNNING)
    return BatchedClairvoyant(np.asarray(V), np.asarray(ret), words, np.array(success), np.asarray(its),
                              np.asarray(evs), time.perf_counter() - t_start, compile_s)
