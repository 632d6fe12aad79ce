"""The clairvoyant optimum of an episode: the command sequence that maximises the environment's own return when the
whole disturbance is known in advance (Savaresi & Spelta 2007: the full-knowledge optimum bounds what any
semi-active controller can do).

:func:`clairvoyant` poses one episode (:func:`mrd_env.optimal.episode_problem`) as an optimisation over the commands
v_k ∈ [v_min, v_max], each held over its control step, through the environment's own equations:

* **dynamics** — the plant, the damper's internal states and the command lag advanced by the environment's scheme:
  one two-stage L-stable SDIRK step per physics step of 1 ms (RK4 at 1 ms is unstable for the hysteresis), each
  stage solved as the stepping routine solves it (plant eliminated, Newton's method on the damper's states and
  force) with a fixed number of Newton iterations, the lag exact, z projected onto ±z_s after each step (smoothly):
  :meth:`~.casadi_model.CoupledModel.newton_step`. The model's |·| and sgn are smoothed (:mod:`.casadi_model`),
  inside the optimiser only;
* **cost** — the reward's quadratic terms (:attr:`EpisodeProblem.terms`, dt and the episode scale included), the
  ISO 2631 Wk filter as the linear state equation of its second-order sections;
* **limits** — the stroke limits as a smooth exterior penalty from 98 % of the limit (the environment's return,
  re-simulated, decides: a sequence that ends the episode is never kept).

**Method: single shooting with an exact adjoint gradient.** The return is one CasADi expression of the commands (the
step ``mapaccum``-ed over the episode); its gradient comes from reverse-mode AD (one backward sweep, the cost of ~3
simulations); the function and gradient are generated as C, compiled once per set-up (plant, damper, episode
length, control step; the episode's disturbance, initial state and reward scales are inputs) and cached on disk;
the bound-constrained problem is solved by L-BFGS-B (``method="lbfgsb"``, default) or by IPOPT with a limited-memory
Hessian on the same function (``method="ipopt"``). The plant is stable, so single shooting is well conditioned over
a whole episode. Measured alternatives (README, issue 20): direct transcription of the same SDIRK equations
(states and stages as unknowns, IPOPT + MUMPS, exact Hessian) took 0.4 s per iteration for a 1 s car episode and
stalled far from convergence (−0.909 after 300 iterations and 126 s, where single shooting reaches −0.811 in 28 s).

The search starts from warm starts — command sequences: the laws' and agents' own commands on the episode, which the
caller supplies (``mrd_env`` does not import ``controllers``; ``experiments.benchmark.yardstick.warm_starts`` builds them),
plus passive-off and passive-on — from the ``n_starts`` best of them by their environment return. Every result and every
warm start is re-simulated in the environment (:meth:`EpisodeProblem.replay`) and the best is kept: the figure reported
is always the environment's return, and no warm start scores more on that episode, by construction. A failed solve says
so (``status``, ``failed``); the best warm start is then returned, ``source`` naming it.

Results are cached as JSON (:mod:`.cache`), keyed by the episode (environment, options, seed, steps, damper
parameters and command channel), a digest of the plant matrices, the disturbance and the reward's terms, the solver
settings, the warm starts and :data:`VERSION`: a result solved for another plant, damper or road is never returned.
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .casadi_model import CoupledModel, Smoothing, check_supported, symbolic_damper
from .problem import sos_state_space

#: Bumped when the solver changes what it returns for the same key (part of the cache key).
VERSION = 2  # 2: an ABNORMAL end at a stationary point (FLAT_GTOL) is converged
#: Longest episode (physics steps) solved. Memory is no limit (the reverse sweep keeps a few hundred bytes per step:
#: 0.33 GB resident for the whole process at 10 s and at 40 s); wall time is: ~45 ms per function-and-gradient
#: evaluation per 10 000 steps (2-core machine) and 200–900 evaluations per solve, so 120 s episodes take ~5–10 min.
MAX_ROWS = 120_000
#: Weight of the stroke-limit penalty ρ Σ_rows relu(|s|/b − 0.98)².
LIMIT_PENALTY = 1e3
LIMIT_MARGIN = 0.98
#: Stopping rule of L-BFGS-B: the objective improved by less than ``tol`` (relative) over WINDOW iterations; on the
#: coarse levels COARSE_TOL over COARSE_WINDOW (a coarse level only has to give the next one a good start).
WINDOW = 20
COARSE_TOL = 1e-4
COARSE_WINDOW = 10
#: The largest projected gradient (inf-norm) at which a failed line search is convergence, not failure: the
#: differentiable scheme's cost is rough at about 1e-13, so below it no step decreases it (scipy's L-BFGS-B calls
#: the same end "relative reduction of F <= factr·epsmch", or "ABNORMAL" where its BLAS rounds otherwise: on an
#: AVX-512 machine a short car episode's 5-step level ended ABNORMAL at a projected gradient of 4e-10). A short car
#: episode's coarse level ended so at 2.8e-9. Used by both L-BFGS-B paths (this module's and the batched one).
FLAT_GTOL = 1e-6


@dataclass
class Solve:
    """One optimiser run: the warm start it began from, its status, iterations, function evaluations, wall time (s),
    the model's return of its commands (the smoothed model: for information only) and the environment's."""

    start: str
    status: str
    success: bool
    iterations: int
    evaluations: int
    seconds: float
    model_return: float
    ret: float
    terminated: bool = False


@dataclass
class ClairvoyantResult:
    """The clairvoyant optimum of one episode (see the module docstring).

    ``ret``: the environment's return of ``commands`` (n_steps, nd); ``source``: "optimiser" or the warm start that
    scored best; ``warm_returns``: the environment's return of every warm start; ``solves``: every optimiser run;
    ``status``/``iterations``: those of the run whose result is kept (else of the last run); ``wall_time`` (s):
    everything (warm starts, compilation, re-simulations); ``compile_seconds``: of that, generating and compiling
    the model (0 when it came from the disk cache)."""

    ret: float
    commands: np.ndarray
    source: str
    warm_returns: dict[str, float]
    status: str
    iterations: int
    wall_time: float
    solves: list[Solve] = field(default_factory=list)
    method: str = "lbfgsb"
    compile_seconds: float = 0.0
    terminated: bool = False
    key: dict = field(default_factory=dict)

    @property
    def failed(self) -> bool:
        """True when no optimiser run succeeded (the result is then the best warm start, or a failed run's commands if
        they re-simulated better)."""
        return not any(s.success for s in self.solves)

    @property
    def best_warm(self) -> tuple[str, float]:
        name = max(self.warm_returns, key=self.warm_returns.get)
        return name, self.warm_returns[name]

    def to_json(self) -> dict:
        d = asdict(self)
        d["commands"] = np.asarray(self.commands).tolist()
        return json.loads(json.dumps(d, default=float))

    @classmethod
    def from_json(cls, d: Mapping) -> "ClairvoyantResult":
        d = dict(d)
        d["commands"] = np.asarray(d["commands"], dtype=float)
        d["solves"] = [Solve(**s) for s in d.get("solves", [])]
        return cls(**d)


# ------------------------------------------------------------------------------------------------- the episode
def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a, dtype=float))
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:24]


def problem_digest(problem) -> str:
    """A digest of everything the optimum depends on that the options may not spell out: the plant matrices, the
    disturbance, the initial state, the reward's terms and the limits."""
    parts = [problem.A, problem.BF, problem.Bw, problem.Cx, problem.Cv, problem.W, problem.x0, [problem.F_static]]
    for t in problem.terms:
        parts += [t.G, t.weight] + ([t.sos] if t.sos is not None else [])
    for lim in problem.limits:
        parts += [np.atleast_2d(lim.G), [lim.bound]]
    return _digest(*parts)


def _jit_dir() -> Path:
    """The compiled models' folder (``jit/`` of the optimal cache), checked private before use: a library there is
    loaded into this process, so nobody else may write it (:func:`mrd_env.storage.private_folder`)."""
    from ..storage import private_folder
    from .cache import cache_dir

    return private_folder(cache_dir() / "jit")


def compile_function(f, name: str, progress=None):
    """``f`` (a CasADi Function) generated as C, compiled with the system C compiler (``$CC``, default gcc) into a
    shared library cached under the optimal cache's ``jit/`` by a hash of the source, and loaded back
    (``casadi.external``). Returns (function, seconds spent compiling: 0 on a cache hit)."""
    import tempfile

    import casadi as ca

    from ..storage import atomic_path

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / f"{name}.c"
        cg = ca.CodeGenerator(src.name, {"with_header": False})
        cg.add(f)
        cg.generate(tmp + os.sep)
        code = src.read_text()
        digest = hashlib.sha256(code.encode()).hexdigest()[:24]
        out = _jit_dir() / f"{name}-{digest}.so"
        if not out.exists():
            if progress:
                progress(f"compiling the model ({len(code) // 1000} kB of C)")
            cc = os.environ.get("CC", "gcc")
            # a new file of unpredictable name, renamed over ``out`` once compiled: parallel workers never load
            # half a library, and nothing planted at a predictable name is written through
            with atomic_path(out) as tmp_so:
                cmd = [cc, "-O2", "-fPIC", "-shared", str(src), "-o", str(tmp_so), "-lm"]
                try:
                    subprocess.run(cmd, check=True, capture_output=True, text=True)
                except FileNotFoundError as e:
                    raise RuntimeError(f"the clairvoyant solver compiles its model with a C compiler; {cc!r} was "
                                       "not found (install gcc or set CC)") from e
                except subprocess.CalledProcessError as e:
                    raise RuntimeError(f"compiling the model failed: {' '.join(cmd)}\n{e.stderr[-2000:]}") from e
            seconds = time.perf_counter() - t0
        else:
            seconds = 0.0
    return ca.external(f.name(), str(out)), seconds


class ShootingModel:
    """The return of an episode set-up as a compiled function of the commands (see the module docstring).

    ``evaluate(V, data)`` → (model return, penalty, gradient of −return + penalty w.r.t. V (n_steps, nd)),
    ``simulate(V, data)`` → the model's rows (Y, F, U); ``data(problem)`` packs an episode's disturbance, initial state
    and reward scales, the only inputs that differ between the episodes of one set-up."""

    def __init__(self, problem, smoothing: Smoothing | None = None, newton_iterations: int = 4, progress=None):
        import casadi as ca
        import scipy.sparse as sps

        check_supported(problem.damper)
        self.smoothing = smoothing or Smoothing()
        self.sd = symbolic_damper(problem.damper, smoothing=self.smoothing)
        m = self.model = CoupledModel(self.sd, problem.A, problem.BF, problem.Bw, problem.Cx, problem.Cv)
        self.N, self.h, self.n_steps, self.n_sub = problem.n_rows - 1, problem.dt, problem.n_steps, problem.n_sub
        ny, nd, nw, nx = m.ny, m.nd, m.nw, m.nx
        self.F_static = problem.F_static
        self.v_min = problem.v_min
        N = self.N
        # the (delayed) command rows: physics step r holds command ka[r] until ts, kb[r] after (−1: before the episode)
        ia, ib, ts = self.sd.delay_indices(N, self.h)
        rows_step = np.arange(N) // problem.n_sub
        self.ka = np.where(ia >= 0, rows_step[np.maximum(ia, 0)], -1)
        self.kb = np.where(ib >= 0, rows_step[np.maximum(ib, 0)], -1)
        # the reward's terms: unfiltered rows, filtered rows (one filter block per row), their weights as an input
        plain, filt, blocks = [], [], []
        for t in problem.terms:
            (filt if t.sos is not None else plain).append(np.asarray(t.G, float))
            if t.sos is not None:
                blocks += [sos_state_space(t.sos)] * t.G.shape[0]
        Gp = np.vstack(plain) if plain else np.zeros((0, nx + nd + nw))
        Gf = np.vstack(filt) if filt else np.zeros((0, nx + nd + nw))
        self.n_plain, self.n_filt = Gp.shape[0], Gf.shape[0]
        if blocks:
            from scipy.linalg import block_diag

            fA, fB, fC, fD = (block_diag(*[b[i] for b in blocks]) for i in range(4))
        else:
            fA = fB = fC = fD = np.zeros((0, 0))
        nf = fA.shape[0]
        self.nf = nf
        lims = problem.limits
        Gl = np.vstack([np.atleast_2d(L.G) for L in lims]) if lims else np.zeros((0, nx + nd + nw))
        bl = np.array([L.bound for L in lims])

        step = m.newton_step(self.h, ts, newton_iterations, project="smooth")
        S = ca.SX
        ns_acc = ny + nd + nd + nf  # Y, F, u, ξ
        st, inp = S.sym("st", ns_acc), S.sym("in", 2 * nw + 2 * nd)
        wts = S.sym("wts", self.n_plain + self.n_filt)
        Y0, F0, u0, xi = st[:ny], st[ny:ny + nd], st[ny + nd:ny + 2 * nd], st[ny + 2 * nd:]
        w0, w1, va, vb = inp[:nw], inp[nw:2 * nw], inp[2 * nw:2 * nw + nd], inp[2 * nw + nd:]
        Y1, F1, u1 = step(Y0, F0, w0, w1, u0, va, vb)
        zrow = ca.vertcat(Y1[:nx], F1, w1)
        cost = 0
        if self.n_plain:
            sp = ca.mtimes(ca.DM(Gp), zrow)
            cost += ca.dot(wts[:self.n_plain], sp * sp)
        xi1 = S(0, 1)
        if self.n_filt:
            sf = ca.mtimes(ca.DM(Gf), zrow)
            y = ca.mtimes(ca.DM(fC), xi) + ca.mtimes(ca.DM(fD), sf)
            cost += ca.dot(wts[self.n_plain:], y * y)
            xi1 = ca.mtimes(ca.DM(fA), xi) + ca.mtimes(ca.DM(fB), sf)
        pen = 0
        if len(bl):
            over = ca.fmax(ca.fabs(ca.mtimes(ca.DM(Gl), zrow)) / ca.DM(bl) - LIMIT_MARGIN, 0)
            pen = LIMIT_PENALTY * ca.sumsqr(over)
        body = ca.Function("body", [st, inp, wts], [ca.vertcat(Y1, F1, u1, xi1), cost, pen, F1])
        acc = body.mapaccum("acc", N, [0], [0])

        V = ca.MX.sym("V", nd, self.n_steps)
        W = ca.MX.sym("W", nw, N + 1)
        x0 = ca.MX.sym("x0", ns_acc)
        wt = ca.MX.sym("wts", self.n_plain + self.n_filt)

        def selector(k):
            M = sps.csc_matrix((np.ones(N), (k + 1, np.arange(N))), shape=(self.n_steps + 1, N))
            return ca.DM(ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist()), M.data)

        # before the episode the queue holds the initial effective command (x0's u)
        Vx = ca.horzcat(x0[ny + nd:ny + 2 * nd], V)
        Va, Vb = ca.mtimes(Vx, selector(self.ka)), ca.mtimes(Vx, selector(self.kb))
        X, C, P, _ = acc(x0, ca.vertcat(W[:, :N], W[:, 1:], Va, Vb), wt)
        J, Pen = ca.sum2(C), ca.sum2(P)
        fg = ca.Function("clairvoyant_fg", [V, W, x0, wt], [J, Pen, ca.gradient(J + Pen, V)])
        sim = ca.Function("clairvoyant_sim", [V, W, x0, wt], [X])
        self.ny, self.nd, self.nw, self.nx, self.ns_acc = ny, nd, nw, nx, ns_acc
        self.compile_seconds = 0.0
        self.fg, s1 = compile_function(fg, "clairvoyant_fg", progress)
        self.sim, s2 = compile_function(sim, "clairvoyant_sim", progress)
        self.compile_seconds = s1 + s2

    def data(self, problem) -> dict:
        """The episode's inputs: the disturbance, the initial state (plant, damper at rest, the static force, the
        effective command at v_min as the environment resets it, zero filter states) and the reward's weights."""
        Y0 = self.model.initial_state(problem.x0, problem.W[0])
        F0 = np.asarray(self.model.forces(Y0, problem.W[0], np.full(self.nd, problem.v_min))).ravel()
        x0 = np.concatenate([Y0, F0, np.full(self.nd, problem.v_min), np.zeros(self.nf)])
        wp = [np.asarray(t.weight, float) for t in problem.terms if t.sos is None]
        wf = [np.asarray(t.weight, float) for t in problem.terms if t.sos is not None]
        wts = np.concatenate(wp + wf) if (wp or wf) else np.zeros(0)
        return {"W": np.ascontiguousarray(problem.W.T), "x0": x0, "wts": wts}

    def evaluate(self, V, data) -> tuple[float, float, np.ndarray]:
        V = np.asarray(V, dtype=float).reshape(self.n_steps, self.nd)
        J, P, g = self.fg(V.T, data["W"], data["x0"], data["wts"])
        return -float(J), float(P), np.asarray(g).T.reshape(self.n_steps, self.nd)

    def simulate(self, V, data) -> dict:
        """The model's rows 1..N: Y (N, ny), F (N, nd), U (N, nd)."""
        V = np.asarray(V, dtype=float).reshape(self.n_steps, self.nd)
        X = np.asarray(self.sim(V.T, data["W"], data["x0"], data["wts"])).T
        ny, nd = self.ny, self.nd
        return {"Y": X[:, :ny], "F": X[:, ny:ny + nd], "U": X[:, ny + nd:ny + 2 * nd]}


# ------------------------------------------------------------------------------------------------- the solver
def _default_warm_starts(problem) -> dict[str, np.ndarray]:
    shape = (problem.n_steps, problem.nd)
    return {"passive_off": np.full(shape, problem.v_min), "passive_on": np.full(shape, problem.v_max)}


def _as_warm_starts(problem, warm_starts) -> dict[str, np.ndarray]:
    base = _default_warm_starts(problem)
    if warm_starts is None:
        return base
    if isinstance(warm_starts, Mapping):
        out = {**base}
        for name, V in warm_starts.items():
            out[str(name)] = problem.check_commands(V)
        return out
    if isinstance(warm_starts, str):
        warm_starts = [warm_starts]
    out = {}
    for name in warm_starts:
        if name not in base:
            raise ValueError(f"warm start {name!r}: give warm starts as {{name: commands (n_steps, nd)}} "
                             "(experiments.benchmark.yardstick.warm_starts builds them from the laws and agents); by name "
                             f"only {sorted(base)}")
        out[name] = base[name]
    return out


def check_size(problem) -> int:
    """The episode's physics steps; ``ValueError`` beyond :data:`MAX_ROWS`, saying how long an episode may be."""
    check_supported(problem.damper)
    n = problem.n_rows - 1
    if n > MAX_ROWS:
        raise ValueError(f"the clairvoyant solve of this episode ({problem.duration:g} s, {n:,} physics steps of "
                         f"{problem.dt:g} s) is longer than the {MAX_ROWS:,} steps it is sized for: episodes may be up to "
                         f"{MAX_ROWS * problem.dt:g} s long (episode_seconds)")
    return n


class _Stop(Exception):
    pass


def minimize_lbfgsb(fun, V0, lo, hi, max_iter, rtol, window, bar):
    """L-BFGS-B from V0 within [lo, hi], stopped when the objective has improved by less than ``rtol`` (relative)
    over the last ``window`` iterations, or after ``max_iter`` iterations."""
    from scipy.optimize import minimize

    shape = V0.shape
    count = {"evals": 0}
    hist: list[float] = []

    def f(v):
        count["evals"] += 1
        val, grad = fun(v.reshape(shape))
        return val, grad.ravel()

    def cb(intermediate_result):
        hist.append(float(intermediate_result.fun))
        if bar is not None:
            bar.update(1)
        if len(hist) > window and hist[-window - 1] - hist[-1] <= rtol * max(abs(hist[-1]), 1e-12):
            raise StopIteration

    r = minimize(f, V0.ravel(), jac=True, method="L-BFGS-B", bounds=[(lo, hi)] * V0.size, callback=cb,
                 options={"maxiter": int(max_iter), "maxfun": int(3 * max_iter), "ftol": 1e-15, "gtol": 1e-12,
                          "maxcor": 10})
    status = r.message if isinstance(r.message, str) else r.message.decode()
    if len(hist) > window and hist[-window - 1] - hist[-1] <= rtol * max(abs(hist[-1]), 1e-12):
        status = f"converged (improvement < {rtol:g} over {window} iterations)"
    elif status.startswith("ABNORMAL") and projected_gradient(r.x, r.jac, lo, hi) <= FLAT_GTOL:
        status = flat_status()
    ok = bool(r.success) or status.startswith("converged") or "LIMIT" in status.upper()
    return r.x.reshape(shape), status, ok, len(hist), count["evals"]


def projected_gradient(x, g, lo, hi) -> float:
    """The inf-norm of the gradient ``g`` at ``x`` projected on the box [``lo``, ``hi``]: 0 at a stationary point."""
    x = np.asarray(x, dtype=float)
    return float(np.max(np.abs(np.clip(x - np.asarray(g, dtype=float), lo, hi) - x), initial=0.0))


def flat_status() -> str:
    """The status of a run whose line search found no decrease at a point stationary to the cost's rounding."""
    return f"converged (no decrease found, projected gradient below {FLAT_GTOL:g})"


def minimize_ipopt(fun, V0, lo, hi, max_iter, tol, progress):
    """IPOPT (limited-memory Hessian) on the box-constrained problem, through a CasADi callback."""
    import casadi as ca

    shape, n = V0.shape, V0.size
    count = {"evals": 0}
    cache = {}

    def both(v):
        key = v.tobytes()
        if key not in cache:
            count["evals"] += 1
            cache.clear()
            cache[key] = fun(v.reshape(shape))
        return cache[key]

    class Grad(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct("grad_f", {"enable_fd": False})

        def get_n_in(self): return 2   # x and the nominal output
        def get_n_out(self): return 1
        def get_sparsity_in(self, i): return ca.Sparsity.dense(n, 1) if i == 0 else ca.Sparsity.dense(1, 1)
        def get_sparsity_out(self, i): return ca.Sparsity.dense(1, n)

        def eval(self, args):
            return [both(np.asarray(args[0]).ravel())[1].ravel()[None, :]]

    class Obj(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.grad = Grad()
            self.construct("f", {"enable_fd": False})

        def get_n_in(self): return 1
        def get_n_out(self): return 1
        def get_sparsity_in(self, i): return ca.Sparsity.dense(n, 1)
        def get_sparsity_out(self, i): return ca.Sparsity.dense(1, 1)
        def has_jacobian(self): return True
        def get_jacobian(self, name, inames, onames, opts): return self.grad

        def eval(self, args):
            return [both(np.asarray(args[0]).ravel())[0]]

    obj = Obj()
    x = ca.MX.sym("V", n)
    solver = ca.nlpsol("clairvoyant", "ipopt", {"x": x, "f": obj(x)},
                       {"ipopt": {"hessian_approximation": "limited-memory", "limited_memory_max_history": 20,
                                  "max_iter": int(max_iter), "tol": tol, "print_level": 5 if progress else 0,
                                  "print_frequency_iter": 25, "sb": "yes", "mu_strategy": "adaptive"},
                        "print_time": False})
    sol = solver(x0=V0.ravel(), lbx=lo, ubx=hi)
    st = solver.stats()
    status = str(st.get("return_status", "unknown"))
    ok = bool(st.get("success", False)) or status in ("Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded")
    return (np.asarray(sol["x"]).reshape(shape), status, ok, int(st.get("iter_count", -1)), count["evals"])


def _levels(problem, coarse) -> list[int]:
    """Command blocks (in control steps) of the coarse-to-fine sequence: each duration of ``coarse`` (s) that is a
    multiple of at least 2 control steps and shorter than the episode, longest first, then 1 (the control step)."""
    out = []
    for c in sorted(set(coarse or ()), reverse=True):
        b = c / problem.control_dt
        if abs(b - round(b)) < 1e-6 and 2 <= round(b) < problem.n_steps:
            out.append(int(round(b)))
    return out + [1]


def blocked(fun, V, blk):
    """``fun`` over commands held for ``blk`` control steps: (function of the block values, their start from V
    (block means), expansion back to every step)."""
    n, nd = V.shape
    nb = -(-n // blk)
    idx = np.arange(n) // blk
    counts = np.bincount(idx, minlength=nb)[:, None]

    def expand(Vc):
        return np.asarray(Vc).reshape(nb, nd)[idx]

    def fb(Vc):
        val, g = fun(expand(Vc))
        gc = np.zeros((nb, nd))
        np.add.at(gc, idx, g)
        return val, gc

    Vc0 = np.zeros((nb, nd))
    np.add.at(Vc0, idx, V)
    return fb, Vc0 / counts, expand


def cache_key(problem, warm_starts: Mapping[str, np.ndarray], **solver) -> dict:
    """What a cached result must match: the episode (:meth:`EpisodeProblem.key`: environment, options, seed, steps,
    damper parameters and command channel), a digest of the plant, disturbance, reward terms and limits
    (:func:`problem_digest`), :data:`VERSION`, the solver settings and a digest of every warm start."""
    return {**problem.key(), "problem_digest": problem_digest(problem), "version": VERSION, "solver": solver,
            "warm_starts": {k: _digest(v) for k, v in sorted(warm_starts.items())}}


def clairvoyant(problem_or_env_id, *, seed: int | None = None, control_dt: float = 1e-3, warm_starts=None,
                n_starts: int = 1, cache: bool = True, progress: bool = True, method: str = "lbfgsb",
                coarse=(0.01,), max_iter: int = 1000, tol: float = 1e-5, newton_iterations: int = 4,
                smoothing: Smoothing | None = None, **env_options) -> ClairvoyantResult:
    """The clairvoyant optimum of one episode (see the module docstring).

    ``problem_or_env_id``: an :class:`~mrd_env.optimal.EpisodeProblem`, or an environment id with ``seed``,
    ``control_dt`` and ``env_options`` (then :func:`~mrd_env.optimal.episode_problem` builds it).
    ``warm_starts``: {name: commands (n_steps, nd)} (passive-off and passive-on are always added), or names among
    "passive_off", "passive_on"; the optimiser starts from the ``n_starts`` best of them by environment return.
    ``method``: "lbfgsb" (scipy's L-BFGS-B) or "ipopt" (IPOPT, limited-memory Hessian). ``coarse``: command-block
    durations (s) solved first, coarse to fine, each level starting the next (default 10 ms, then the control step:
    the coarse problem converges in tens of iterations and gives the fine one a start near its optimum);
    ``max_iter`` per level; ``tol``: L-BFGS-B stops when the objective improved by less than ``tol`` (relative) over
    the last 20 iterations; ``newton_iterations`` per SDIRK stage; ``smoothing``: the model's ε
    (:class:`~.casadi_model.Smoothing`). ``cache``: read and write the JSON cache (:mod:`.cache`); ``progress``: say
    what is being done, with a bar over the iterations.
    """
    from . import cache as store
    from .problem import EpisodeProblem, episode_problem

    t_start = time.perf_counter()
    if isinstance(problem_or_env_id, EpisodeProblem):
        if seed is not None or env_options:
            raise ValueError("give either an EpisodeProblem or env_id with seed and options, not both")
        problem = problem_or_env_id
    else:
        if seed is None:
            raise ValueError("clairvoyant(env_id, ...) needs seed=")
        problem = episode_problem(problem_or_env_id, seed=seed, control_dt=control_dt, **env_options)
    if method not in ("lbfgsb", "ipopt"):
        raise ValueError(f"method must be 'lbfgsb' or 'ipopt', got {method!r}")
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
        raise ValueError(f"n_starts must be an int >= 0, got {n_starts!r}")
    smoothing = smoothing or Smoothing()
    check_size(problem)
    starts = _as_warm_starts(problem, warm_starts)
    key = cache_key(problem, starts, method=method, n_starts=n_starts, coarse=sorted(coarse or ()), max_iter=max_iter,
                    tol=tol, newton_iterations=newton_iterations, smoothing=asdict(smoothing))
    if cache:
        hit = store.load("clairvoyant", key)
        if hit is not None:
            res = ClairvoyantResult.from_json(hit)
            if progress:
                print(f"clairvoyant: cached result for {problem.env_id} seed {problem.seed}: {res.ret:.6g}")
            return res

    def say(msg):
        if progress:
            print(f"clairvoyant [{time.perf_counter() - t_start:6.1f} s] {msg}", flush=True)

    say(f"{problem.env_id} seed {problem.seed}: {problem.duration:g} s, {problem.n_steps} commands of "
        f"{problem.control_dt:g} s; re-simulating {len(starts)} warm starts")
    warm = {name: problem.replay(V) for name, V in starts.items()}
    warm_returns = {k: float(tr.ret) for k, tr in warm.items()}
    ranked = sorted(starts, key=lambda k: warm_returns[k], reverse=True)
    best_name = ranked[0]
    best = (warm_returns[best_name], starts[best_name], best_name, bool(warm[best_name].terminated))

    solves: list[Solve] = []
    kept = None
    compile_s = 0.0
    if n_starts > 0:
        sm = ShootingModel(problem, smoothing, newton_iterations, progress=say)
        compile_s = sm.compile_seconds
        data = sm.data(problem)
        say("model ready" + (f" (compiled in {compile_s:.1f} s)" if compile_s else " (compiled code from the cache)"))

        def fun(V):
            ret, pen, g = sm.evaluate(V, data)
            return -ret + pen, g

        blocks = _levels(problem, coarse)
        for name in ranked[:n_starts]:
            V = np.asarray(starts[name], float).reshape(problem.n_steps, problem.nd)
            say(f"{method} from {name!r} (environment return {warm_returns[name]:.6g}, model "
                f"{sm.evaluate(V, data)[0]:.6g}); command blocks of {', '.join(f'{b * problem.control_dt:g}' for b in blocks)} s")
            t0 = time.perf_counter()
            statuses, ok, nit, nev = [], True, 0, 0
            for level, blk in enumerate(blocks):
                final = level == len(blocks) - 1
                bar = None
                if progress:
                    from tqdm.auto import tqdm

                    bar = tqdm(total=max_iter, desc=f"{name}, blocks of {blk * problem.control_dt:g} s", unit="it",
                               leave=False, mininterval=2.0)
                lo, hi = problem.v_min, problem.v_max
                fb, Vc0, expand = blocked(fun, V, blk)
                try:
                    if method == "lbfgsb":
                        Vc, st, ok_l, it_l, ev_l = minimize_lbfgsb(fb, Vc0, lo, hi, max_iter, tol if final else COARSE_TOL,
                                                           WINDOW if final else COARSE_WINDOW, bar)
                    else:
                        Vc, st, ok_l, it_l, ev_l = minimize_ipopt(fb, Vc0, lo, hi, max_iter, 1e-8 if final else 1e-6, progress)
                    V = expand(Vc)
                except Exception as e:  # a failed run is recorded; the warm starts still stand
                    st, ok_l, it_l, ev_l = f"error: {type(e).__name__}: {e}", False, 0, 0
                finally:
                    if bar is not None:
                        bar.close()
                statuses.append(f"{blk * problem.control_dt:g} s: {st}")
                ok, nit, nev = ok and ok_l, nit + it_l, nev + ev_l
                if not ok_l:
                    break
            secs = time.perf_counter() - t0
            V = np.clip(V, problem.v_min, problem.v_max)
            tr = problem.replay(V)
            s = Solve(name, "; ".join(statuses), ok, nit, nev, secs, sm.evaluate(V, data)[0], float(tr.ret),
                      bool(tr.terminated))
            solves.append(s)
            say(f"{method} from {name!r}: {s.status}, {nit} iterations ({nev} evaluations) in {secs:.1f} s; model "
                f"return {s.model_return:.6g}, environment return {s.ret:.6g}"
                + (" — TERMINATED (limit), discarded" if tr.terminated else ""))
            if tr.ret > best[0] and not tr.terminated:
                best = (float(tr.ret), V, "optimiser", False)
                kept = s
    last = kept or (solves[-1] if solves else None)
    res = ClairvoyantResult(ret=float(best[0]), commands=np.asarray(best[1], float).reshape(problem.n_steps, problem.nd),
                            source=best[2], warm_returns=warm_returns, status=last.status if last else "not solved",
                            iterations=last.iterations if last else 0, wall_time=time.perf_counter() - t_start,
                            solves=solves, method=method, compile_seconds=compile_s, terminated=bool(best[3]), key=key)
    if solves and res.failed:
        say(f"the optimiser failed ({'; '.join(s.status for s in solves)}): the result is {res.source!r}")
    say(f"done in {res.wall_time:.1f} s: return {res.ret:.6g} from {res.source} (best warm start {best_name!r} "
        f"{warm_returns[best_name]:.6g})")
    if cache:
        store.store("clairvoyant", key, res.to_json())
    return res
