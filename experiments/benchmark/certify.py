"""The clairvoyant optimum of an episode certified by two solution paths (issue 51, item 1).

A suite's R_c is a claim: no controller can do better on the episode. One optimiser's result is only a local
optimum of its own model, and the two paths of the project find different ones (on ``car-comfort-v1``'s bump at the
suite's 10 ms step, the CasADi path ends ABNORMAL at R = −2.508 while the gradient path reaches −2.443, half the
episode's range higher). So an episode's R_c is the better of two independent paths, and it is stored as an optimum
only when the other path cannot beat it:

1. **Independent solves**: the CasADi path (:func:`mrd_env.optimal.clairvoyant`: the smoothed model, L-BFGS-B)
   and the gradient path (:func:`mrd_env.jax.clairvoyant.clairvoyant`: the plant's JAX twin, differentiable scheme,
   the same L-BFGS-B) each run from the ``n_starts`` best warm starts. A path's result is the best of its
   optimiser runs, each re-simulated in the native environment, which alone pays the returns compared here (a warm
   start the optimiser did not beat is no result of the path).
2. **Agreement**: the two paths' results differ by at most :data:`TOLERANCE` of the episode's range R_c − R_p,
   and neither path's runs all ended abnormally. Then the episode is certified in round 1.
3. **More starts** otherwise: each path runs again from ``more_starts`` warm starts and from the other path's
   optimum (at the control step directly: command blocks would blur it), the CasADi path with IPOPT in place of L-BFGS-B (on the bump of ``car-comfort-v1`` L-BFGS-B stops
   ABNORMAL after 7 iterations on the smoothed model where IPOPT reaches the gradient path's optimum within
   0.1 % of the range), and the two results are compared again (round 2).
4. An episode whose paths still disagree is **not certified**: :class:`Certificate` says so, and the suite builder
   refuses to store it as an optimum.

Both paths work at the problem's control step: the suite's own action space, one command per control step held as
the environment holds it. Certification needs the ``jax`` extra (the gradient path).

**Procedure 3** is the same certification with the gradient path's round 1 run for a whole build at once
(:func:`batched_gradient_paths`: every episode's starts in one compiled program,
:func:`mrd_env.jax.clairvoyant.batched_clairvoyant`, a projected L-BFGS on the device in place of scipy's L-BFGS-B
driven from the host), handed to :func:`certified_clairvoyant` as ``first``; round 2 is per episode, its gradient
path by the same batched solver (:data:`PATHS_3`: an episode's starts in one program; on ``building-seismic-v2``
the host-driven path took over 15 min per round-2 episode). On ``car-comfort-v1`` the per-episode gradient path
took about ten times the CasADi path's time and the batch a fifth of it (docs/jax.md).

**Procedure 4** is procedure 3 whose round 2 first starts each path from the other's optimum (``cross_first``):
started there, each path ends at least as high as that optimum, so they certify exactly when neither improves the
other's optimum by more than the tolerance; the more starts run only if they do not.

**Procedure 5** is procedure 4 whose gradient path maximises the twin's return less the CasADi path's exterior
penalty on the limits that end an episode (:data:`mrd_env.optimal.full_knowledge.LIMIT_PENALTY` from
``LIMIT_MARGIN`` of each limit, :attr:`mrd_env.jax.env.EnvParams.limit_penalty`). Without it the gradient path rides
an optimum that touches a limit (a car's stroke) exactly, where the twin's small model error leaves the native
episode over the limit and ended: on ``car-comfort-robust-v2``'s ISO-D s1000012 the twin scored the path's
commands −3.04 and the environment −30.8, where the CasADi path's, kept 2 % inside, scored −2.19.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

#: The largest disagreement of the two paths' returns, as a share of the episode's range R_c − R_p, that certifies.
TOLERANCE = 0.005
#: Command blocks (s) each path solves first, coarse to fine, before every control step.
COARSE_BLOCK = 0.05


@dataclass
class PathResult:
    """One path's runs: ``ret``, the best environment return of its optimiser runs; ``commands``, the best command
    sequence it found that beat every warm start it had, and ``commands_ret`` their return (``commands`` None when
    no run beat its warm starts: the runs still count, as a check of the optimum they started from); each run
    (start, status, success, iterations, function evaluations, the environment's return)."""

    ret: float
    commands: np.ndarray | None
    commands_ret: float
    runs: list = field(default_factory=list)

    @property
    def found(self) -> bool:
        return self.commands is not None

    @property
    def abnormal(self) -> bool:
        """Every run of this path ended without converging."""
        return not any(r["success"] for r in self.runs)

    def to_json(self) -> dict:
        return {"return": float(self.ret), "runs": self.runs}

    def to_kept(self) -> dict:
        """All of it as plain JSON (a build's kept round 1; :meth:`from_kept` reads it back)."""
        return {**self.to_json(), "commands": None if self.commands is None else np.asarray(self.commands).tolist(),
                "commands_return": float(self.commands_ret) if self.found else None}

    @classmethod
    def from_kept(cls, data: dict) -> PathResult:
        found = data["commands"] is not None
        return cls(float(data["return"]), np.asarray(data["commands"], dtype=float) if found else None,
                   float(data["commands_return"]) if found else -np.inf, list(data["runs"]))


@dataclass
class Certificate:
    """The certified clairvoyant of one episode: the better path's return and commands, both paths' results, their
    disagreement (share of the range), the round that certified (1 or 2; 0: not certified)."""

    ret: float
    commands: np.ndarray
    path: str
    paths: dict
    disagreement: float
    rounds: int
    certified: bool

    def to_json(self) -> dict:
        """What the suite file keeps of it (deterministic: no wall times)."""
        return {"path": self.path, "certified": self.certified, "round": self.rounds,
                "disagreement": round(float(self.disagreement), 8),
                "paths": {k: v.to_json() for k, v in self.paths.items()}}


def _runs(solves) -> list[dict]:
    return [{"start": s.start, "status": s.status, "success": bool(s.success), "iterations": int(s.iterations),
             "evaluations": int(s.evaluations), "return": float(s.ret)} for s in solves]


def _blocks(problem) -> int:
    """The coarse level in control steps (at least 2, else none)."""
    return max(int(round(COARSE_BLOCK / problem.control_dt)), 1)


def _path_result(res) -> PathResult:
    """A path's result from a clairvoyant's (see :class:`PathResult`)."""
    runs = _runs(res.solves)
    best = max((r["return"] for r in runs), default=-np.inf)
    if res.source == "optimiser":
        return PathResult(float(best), np.asarray(res.commands, dtype=float), float(res.ret), runs)
    return PathResult(float(best), None, -np.inf, runs)


def casadi_path(problem, starts: dict, n_starts: int, fine_only: bool = False, method: str = "lbfgsb") -> PathResult:
    """The CasADi path from the ``n_starts`` best of ``starts`` (no cache: a certificate is computed, not read);
    ``fine_only``: no coarse level (a start that is another path's optimum would lose its detail in blocks)."""
    from mrd_env.optimal import clairvoyant

    blk = 1 if fine_only else _blocks(problem)
    return _path_result(clairvoyant(problem, warm_starts=starts, n_starts=n_starts, cache=False, progress=False,
                                    method=method, coarse=(blk * problem.control_dt,) if blk >= 2 else ()))


def casadi_ipopt_path(problem, starts: dict, n_starts: int, fine_only: bool = False) -> PathResult:
    """The CasADi path with IPOPT (round 2)."""
    return casadi_path(problem, starts, n_starts, fine_only, method="ipopt")


def gradient_path(problem, starts: dict, n_starts: int, fine_only: bool = False) -> PathResult:
    """The gradient path through the plant's JAX twin from the ``n_starts`` best of ``starts``."""
    from mrd_env.jax import env as je
    from mrd_env.jax.clairvoyant import clairvoyant

    params = je.params_of_problem(problem, scheme="differentiable")
    _, s0 = je.reset(None, params, record=0)
    blk = 1 if fine_only else _blocks(problem)
    return _path_result(clairvoyant(je.episode_return, lambda V: problem.replay(V).ret, starts, problem.v_min,
                                    problem.v_max, data=(params, s0), n_starts=n_starts,
                                    coarse=(blk,) if blk >= 2 else ()))


def _joined(a: PathResult, b: PathResult) -> PathResult:
    """Two results of one path as one: every run, the better commands."""
    c = a if a.commands_ret >= b.commands_ret else b
    return PathResult(max(a.ret, b.ret), c.commands, c.commands_ret, a.runs + b.runs)


def batched_gradient_paths(problems, starts_list, n_starts: int, fine_only: bool = False,
                           limit_penalty: bool = False) -> list[PathResult]:
    """Round 1 of the gradient path on many episodes in one compiled program (procedure 3): each episode's
    ``n_starts`` best of its ``starts`` (ranked by their return in the native environment, as
    :func:`gradient_path` ranks them) solved together by :func:`mrd_env.jax.clairvoyant.batched_clairvoyant` with
    the same command blocks, each result re-simulated in the native environment; one :class:`PathResult` per
    problem, as :func:`gradient_path` returns it. The problems share a plant and its command bounds (one batch is
    one program); their lengths may differ (the shorter are padded); ``fine_only``: as :func:`gradient_path`'s;
    ``limit_penalty`` (procedure 5): the twin's return less the CasADi path's penalty on the limits.
    Problems whose compiled step differs in structure (a robustness twin's drawn command delays) are solved as one
    batch per structure (:func:`mrd_env.jax.clairvoyant.structure_groups`)."""
    from mrd_env.jax.clairvoyant import structure_groups

    problems, starts_list = list(problems), list(starts_list)
    if not problems or len(problems) != len(starts_list):
        raise ValueError(f"problems and starts_list must be non-empty and as long as each other, got "
                         f"{len(problems)} and {len(starts_list)}")
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 1:
        raise ValueError(f"n_starts must be an int >= 1, got {n_starts!r}")
    bounds = {(p.v_min, p.v_max, p.control_dt) for p in problems}
    if len(bounds) != 1:
        raise ValueError(f"the problems of one batch share their command bounds and control step, got {sorted(bounds)}")
    out = [None] * len(problems)
    for group in structure_groups(problems, scheme="differentiable"):
        solved = _one_batch([problems[i] for i in group], [starts_list[i] for i in group], n_starts, fine_only,
                            limit_penalty)
        for i, r in zip(group, solved):
            out[i] = r
    return out


def _one_batch(problems, starts_list, n_starts: int, fine_only: bool, limit_penalty: bool) -> list[PathResult]:
    """:func:`batched_gradient_paths` on problems of one compiled structure: one program."""
    from mrd_env.jax import env as je
    from mrd_env.jax.clairvoyant import batched_clairvoyant, episode_batch
    from mrd_env.optimal.full_knowledge import LIMIT_MARGIN, LIMIT_PENALTY

    rows, warm_best = [], []  # rows: (problem index, start name, its commands)
    for i, (p, starts) in enumerate(zip(problems, starts_list)):
        rets = {k: float(p.replay(v).ret) for k, v in starts.items()}
        ranked = sorted(starts, key=lambda k: rets[k], reverse=True)
        warm_best.append(rets[ranked[0]])
        rows += [(i, k, np.asarray(starts[k], dtype=float)) for k in ranked[:n_starts]]
    batch = episode_batch([problems[i] for i, _, _ in rows], scheme="differentiable")
    data = batch.data
    if limit_penalty:  # a static field: the arrays and the episodes' first states are the same
        data = (replace(data[0], limit_penalty=(LIMIT_PENALTY, LIMIT_MARGIN)), data[1])
    blk = 1 if fine_only else _blocks(problems[0])
    res = batched_clairvoyant(je.episode_return, data, batch.pad([V for *_, V in rows]), problems[0].v_min,
                              problems[0].v_max, coarse=(blk,) if blk >= 2 else ())
    found = [[] for _ in problems]
    for (i, name, _), V, status, ok, nit, nev in zip(rows, batch.unpad(res.commands), res.status, res.success,
                                                     res.iterations, res.evaluations):
        ret = float(problems[i].replay(V).ret)
        found[i].append(({"start": name, "status": status, "success": bool(ok), "iterations": int(np.sum(nit)),
                          "evaluations": int(np.sum(nev)), "return": ret}, V))
    out = []
    for i, runs in enumerate(found):
        best_run, best_V = max(runs, key=lambda r: r[0]["return"])
        beat = best_run["return"] > warm_best[i]  # as the per-episode path: a warm start it did not beat is no result
        out.append(PathResult(best_run["return"], best_V if beat else None, best_run["return"] if beat else -np.inf,
                              [r for r, _ in runs]))
    return out


def batched_gradient_path(problem, starts: dict, n_starts: int, fine_only: bool = False,
                          limit_penalty: bool = False) -> PathResult:
    """:func:`gradient_path` by the batched solver (procedure 3's round 2): the episode's starts in one program."""
    return batched_gradient_paths([problem], [starts], n_starts, fine_only, limit_penalty)[0]


#: The two paths: {name: (round 1, round 2)}.
PATHS = {"casadi": (casadi_path, casadi_ipopt_path), "gradient": (gradient_path, gradient_path)}
#: Procedure 3's: the gradient path by the batched solver in both rounds (round 1 is usually handed over as
#: ``first``, solved for a scenario's episodes together).
PATHS_3 = {"casadi": (casadi_path, casadi_ipopt_path), "gradient": (batched_gradient_path, batched_gradient_path)}
_PENALISED = partial(batched_gradient_path, limit_penalty=True)
#: Procedure 5's: procedure 3's, the gradient path's objective carrying the CasADi path's penalty on the limits.
PATHS_5 = {"casadi": (casadi_path, casadi_ipopt_path), "gradient": (_PENALISED, _PENALISED)}


def certified_clairvoyant(problem, starts: dict, passive: float, *, n_starts: int = 2, more_starts: int = 4,
                          tolerance: float = TOLERANCE, paths=None, first: dict | None = None,
                          cross_first: bool = False) -> Certificate:
    """The clairvoyant optimum of ``problem``'s episode by the procedure of the module docstring.

    ``starts``: {name: commands (n_steps, nd)} (the warm laws and the best constant command); ``passive``: R_p, the
    best constant command's return (the range R_c − R_p scales the tolerance); ``paths``: {name: (round 1's
    fn(problem, starts, n_starts) -> PathResult, round 2's)}, two of them (default :data:`PATHS`); ``first``:
    {name: PathResult} round 1's result of a path computed beforehand (:func:`batched_gradient_paths`), which is
    then not run again in round 1; ``cross_first`` (procedure 4): round 2 starts each path from the other's
    optimum first, by its round-1 solver, and runs the more starts only if that does not certify (on
    ``building-seismic-v2``'s first five round-2 episodes the cross-start runs alone put the paths within 0.17 %
    of the range, where the more starts' IPOPT runs, each stopped at 1 000 iterations, took most of 12–22 min)."""
    if not 0 < tolerance < 1:
        raise ValueError(f"tolerance must be in (0, 1) (a share of the episode's range), got {tolerance!r}")
    if not 1 <= n_starts <= more_starts:
        raise ValueError(f"n_starts must be in [1, more_starts={more_starts}], got {n_starts!r}")
    paths = paths or PATHS
    if len(paths) != 2:
        raise ValueError(f"certification takes two solution paths, got {sorted(paths)}")
    (na, (fa, fa2)), (nb, (fb, fb2)) = paths.items()
    first = first or {}
    if set(first) - set(paths):
        raise ValueError(f"first must name paths of {sorted(paths)}, got {sorted(first)}")
    a = first[na] if na in first else fa(problem, starts, n_starts)
    b = first[nb] if nb in first else fb(problem, starts, n_starts)

    def verdict(a, b, rounds):
        win, name = (a, na) if a.commands_ret >= b.commands_ret else (b, nb)
        top = max(a.ret, b.ret)
        gap = top - passive
        dis = abs(a.ret - b.ret) / gap if gap > 0 else (0.0 if a.ret == b.ret else np.inf)
        ok = bool(win.found and a.runs and b.runs and not (a.abnormal or b.abnormal) and dis <= tolerance
                  and top - win.commands_ret <= tolerance * gap)  # the stored commands reach the agreed optimum
        return Certificate(win.commands_ret, win.commands, name, {na: a, nb: b}, float(dis), rounds if ok else 0, ok)

    first = verdict(a, b, 1)
    if first.certified:
        return first
    if cross_first:  # round 2, first part: each path from the other's optimum, by its round-1 solver
        a1 = _joined(a, fa(problem, {f"{nb} optimum": b.commands}, 1, True)) if b.found else a
        b1 = _joined(b, fb(problem, {f"{na} optimum": a.commands}, 1, True)) if a.found else b
        cross = verdict(a1, b1, 2)
        if cross.certified:
            return cross
        a, b = a1, b1
    # round 2: more starts, and each path from the other's optimum (at the control step only)
    a, b = _joined(a, fa2(problem, starts, more_starts)), _joined(b, fb2(problem, starts, more_starts))
    a2 = _joined(a, fa2(problem, {f"{nb} optimum": b.commands}, 1, True)) if b.found else a
    b2 = _joined(b, fb2(problem, {f"{na} optimum": a.commands}, 1, True)) if a.found else b
    return verdict(a2, b2, 2)
