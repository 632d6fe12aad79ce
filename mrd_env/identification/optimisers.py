"""The three optimisers of :func:`~mrd_env.identification.fit.fit_model`, each on the [0, 1]-scaled problem
(:class:`~mrd_env.identification.problem.Problem`), each returning (θ, iterations, converged, message).
"""
from __future__ import annotations

import numpy as np

from .problem import Problem


def run_search(prob: Problem, x0, search, desc: str):
    """(θ, iterations, converged, message, history of the best objective) of ``search.method`` from x0."""
    history: list[float] = []
    it = search.iterations
    try:
        if search.method == "least_squares":
            out = _run_least_squares(prob, x0, it, search.tol, search.diff_step, search.progress, desc, history,
                                     central=(search.jacobian == "central"))
        elif search.method == "differential_evolution":
            out = _run_de(prob, x0, it, search.popsize, search.tol, int(search.seed), search.progress, desc, history)
        else:
            out = _run_pso(prob, x0, it, search.popsize, search.tol, int(search.seed), search.progress, desc,
                           history)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: the best point so far ends the search (fit_model says so)
        if prob.best_theta is None:
            raise
        prob.interrupted = exc
        out = (prob.best_theta.copy(), 0, False, "interrupted: the best parameters found so far")
    return (*out, history)


def _run_least_squares(prob: Problem, x0, maxiter, tol, diff_step, progress, desc, history, central=True):
    from scipy.optimize import least_squares
    from tqdm import tqdm

    h = float(diff_step)
    tol = 1e-8 if tol is None else float(tol)
    k = x0.size
    bar = tqdm(total=maxiter, desc=desc, unit="eval", disable=not progress, leave=False)
    last: dict = {}

    def fun(x):
        r = prob.residuals(x[None, :])[0]
        last["x"], last["r"] = x.copy(), r
        bar.update(1)
        bar.set_postfix(objective=f"{prob.best:.5g}")
        return r

    def jac(x, *args):
        """Finite differences in the [0, 1] scale, all columns simulated as one batch: central where both
        sides lie inside the bounds (and are feasible), one-sided otherwise."""
        f0 = last["r"] if "x" in last and np.array_equal(last["x"], x) else prob.residuals(x[None, :])[0]
        up = np.minimum(x + h, 1.0) - x
        dn = x - np.maximum(x - h, 0.0)
        X = np.vstack([np.tile(x, (k, 1)), np.tile(x, (k, 1))]) if central else np.tile(x, (k, 1))
        X[np.arange(k), np.arange(k)] += up
        if central:
            X[k + np.arange(k), np.arange(k)] -= dn
        R, good = prob.residuals(X, return_good=True)
        Jm = np.zeros((f0.size, k))
        for j in range(k):
            gu = good[j] and up[j] > 0
            gd = central and good[k + j] and dn[j] > 0
            if gu and gd:
                Jm[:, j] = (R[j] - R[k + j]) / (up[j] + dn[j])
            elif gu:
                Jm[:, j] = (R[j] - f0) / up[j]
            elif gd:
                Jm[:, j] = (f0 - R[k + j]) / dn[j]
            elif not central and dn[j] > 0:  # forward point infeasible or at the bound: try the other side
                xb = x.copy()
                xb[j] -= dn[j]
                rb, gb = prob.residuals(xb[None, :], return_good=True)
                if gb[0]:
                    Jm[:, j] = (f0 - rb[0]) / dn[j]
        history.append(prob.best)
        return Jm

    try:
        res = least_squares(fun, x0, jac=jac, bounds=(np.zeros(k), np.ones(k)), method="trf", x_scale=1.0,
                            max_nfev=maxiter, ftol=tol, xtol=tol, gtol=tol)
    finally:
        bar.close()
    return np.clip(res.x, 0.0, 1.0), int(res.njev or 0), res.status > 0, res.message


def _run_de(prob: Problem, x0, maxiter, popsize, tol, seed, progress, desc, history):
    from scipy.optimize import differential_evolution
    from tqdm import tqdm

    k = x0.size
    popsize = 10 if popsize is None else int(popsize)
    bar = tqdm(total=maxiter, desc=desc, unit="gen", disable=not progress, leave=False)

    def func(X):  # X has shape (k, S): one batched simulation per generation
        return prob.objective(np.asarray(X).T)

    def callback(intermediate_result):
        history.append(float(intermediate_result.fun))
        bar.update(1)
        bar.set_postfix(objective=f"{intermediate_result.fun:.5g}")

    try:
        res = differential_evolution(func, [(0.0, 1.0)] * k, maxiter=maxiter, popsize=popsize,
                                     tol=0.01 if tol is None else float(tol), rng=np.random.default_rng(seed),
                                     callback=callback, polish=False, init="latinhypercube", updating="deferred",
                                     vectorized=True, x0=x0)
    finally:
        bar.close()
    return np.clip(res.x, 0.0, 1.0), int(res.nit), bool(res.success), res.message


def _pymoo():
    try:
        from pymoo.algorithms.soo.nonconvex.pso import PSO
        from pymoo.core.problem import Problem
        from pymoo.optimize import minimize
        from pymoo.termination.default import DefaultSingleObjectiveTermination
    except ImportError:
        raise ImportError("method='pso' needs the optional dependency pymoo (pip install 'pymoo>=0.6.1')") from None
    return PSO, Problem, minimize, DefaultSingleObjectiveTermination


def _run_pso(prob: Problem, x0, maxiter, popsize, tol, seed, progress, desc, history):
    PSO, Problem, minimize, Termination = _pymoo()
    from scipy.stats import qmc
    from tqdm import tqdm

    k = x0.size
    pop = max(20, 10 * k) if popsize is None else int(popsize)
    if pop < 2:
        raise ValueError(f"popsize = {popsize!r} is invalid: PSO needs at least 2 particles")
    # the initial swarm: the initial guess plus a Latin hypercube, from our own seeded generator
    X0 = np.vstack([x0[None, :], qmc.LatinHypercube(d=k, rng=np.random.default_rng(seed)).random(pop - 1)])

    class _P(Problem):
        def __init__(self):
            super().__init__(n_var=k, n_obj=1, xl=np.zeros(k), xu=np.ones(k))

        def _evaluate(self, X, out, *args, **kwargs):
            out["F"] = prob.objective(X)[:, None]

    bar = tqdm(total=maxiter, desc=desc, unit="gen", disable=not progress, leave=False)

    def callback(algorithm):
        f = float(algorithm.opt.get("F").min())
        history.append(f)
        bar.update(1)
        bar.set_postfix(objective=f"{f:.5g}")

    term = Termination(ftol=1e-6 if tol is None else float(tol), n_max_gen=maxiter)
    try:
        res = minimize(_P(), PSO(pop_size=pop, sampling=X0), termination=term, seed=seed, callback=callback,
                       verbose=False)
    finally:
        bar.close()
    n_gen = int(res.algorithm.n_gen)
    converged = n_gen < maxiter
    msg = ("swarm converged (pymoo's single-objective termination)" if converged
           else f"maximum number of generations ({maxiter}) reached")
    return np.clip(np.asarray(res.X, dtype=np.float64).ravel(), 0.0, 1.0), n_gen, converged, msg
