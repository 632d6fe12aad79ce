"""The quarter car's physics step next to its limit, the explicit step of the same equations, in the same run
(issue: speed where users wait).

Run: ``python -m experiments.measurements.speed.physics_step [--seconds 20] [--repeats 5] [--out results/bench]``.

Both rows advance the same system — quarter car set A with the automotive Spencer–Dyke damper (the default
``QuarterCarPhysical-v0``), a class-C ISO 8608 road at 20 m/s, the command switching between v_min and v_max every 50 ms —
over one record of ``--seconds`` at dt = 1 ms, one compiled call for the whole record (no per-call overhead):

* **accurate**: the project's stepping routine (:mod:`mrd_env.stepping`: SDIRK2, Newton on the damper's unknowns,
  error control, exact command lag), through :class:`~mrd_env.mechanics.plant.CoupledPlant`;
* **explicit (limit)**: one forward-Euler step per millisecond of the same equations (the same matrices and the
  damper model's own compiled functions, command lag included) — what a step cannot cost less than. It is *not*
  a usable integrator here: the Bouc–Wen state's stiffness (≈ 10⁴ s⁻¹) makes it unstable at 1 ms; only its cost
  is the reference.

Each figure is the median of ``--repeats`` runs, the two rows interleaved in each repeat; the ratio is the median
of the per-repeat ratios. The load average of the machine is printed with the table.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numba as nb
import numpy as np

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def quarter_car_case(seconds: float, dt: float = 1e-3, seed: int = 0):
    """(coupled plant, commands V (1, n, 1), plant inputs w (1, n + 1, 2)) of the benchmark's record."""
    from mrd_env.dampers import make_damper
    from mrd_env.disturbances.road import iso8608_road
    from mrd_env.mechanics.plant import CoupledPlant
    from mrd_env.plants.quarter_car import quarter_car

    damper = make_damper("spencer_dyke", "automotive")
    n = int(round(seconds / dt))
    road = iso8608_road("C", 20.0, seconds + dt, dt=dt, rng=np.random.default_rng(seed))
    w = np.ascontiguousarray(road.data[None, :n + 1, :2])
    c = damper.command
    V = np.where((np.arange(n) // 50) % 2 == 0, c.v_min, c.v_max).reshape(1, n, 1).astype(np.float64)
    plant = CoupledPlant(quarter_car("set_a").plant(), damper, N=1, n_steps=n, dt=dt)
    return plant, V, w


def explicit_kernel(damper):
    """A compiled forward-Euler run of the coupled equations with ``damper``'s own compiled functions."""
    rhs = damper.rhs
    force = damper.force_law
    project = damper.project

    @nb.njit
    def run_explicit(A, BF, Bw, Cx, Cv, Dx, Dv, Da, P, lag, q, s, u, V, W, dt, F_out):
        nq = q.shape[0]
        nd = Cx.shape[0]
        ns = s.shape[0] // max(nd, 1)
        qd = np.empty(nq)
        ds = np.empty(ns)
        F = np.empty(nd)
        xs = np.empty(nd)
        vs = np.empty(nd)
        as_ = np.empty(nd)
        for k in range(V.shape[0]):
            w = W[k]
            for j in range(nd):
                x = 0.0
                v = 0.0
                a = 0.0
                for i in range(nq):
                    x += Cx[j, i] * q[i]
                    v += Cv[j, i] * q[i]
                for m in range(w.shape[0]):
                    x += Dx[j, m] * w[m]
                    v += Dv[j, m] * w[m]
                    a += Da[j, m] * w[m]
                xs[j] = x
                vs[j] = v
                as_[j] = a
                F[j] = force(P, s[j * ns:(j + 1) * ns], x, v, a, u[j])
            for i in range(nq):
                acc = 0.0
                for c in range(nq):
                    acc += A[i, c] * q[c]
                for j in range(nd):
                    acc += BF[i, j] * F[j]
                for m in range(w.shape[0]):
                    acc += Bw[i, m] * w[m]
                qd[i] = acc
            for j in range(nd):
                sj = s[j * ns:(j + 1) * ns]
                rhs(P, sj, xs[j], vs[j], u[j], ds)
                for i in range(ns):
                    sj[i] += dt * ds[i]
                project(P, sj, xs[j], vs[j], u[j])
                eta = lag[0] if V[k, j] > u[j] else lag[1]
                u[j] += dt * eta * (V[k, j] - u[j])
                F_out[k, j] = F[j]
            for i in range(nq):
                q[i] += dt * qd[i]

    return run_explicit


def bench(seconds: float, repeats: int) -> list[dict]:
    plant, V, w = quarter_car_case(seconds)
    n = V.shape[1]
    W = plant.inputs(w)
    d = plant.damper
    s = plant.system
    run_explicit = explicit_kernel(d)
    P = d.params.as_array()
    lag = d.command.lag_vector()
    Wx = np.ascontiguousarray(W[0, :n])

    def explicit():
        q = np.zeros(s.nq)
        st = np.tile(d.initial_state(), s.nd)
        u = np.full(s.nd, d.command.v_min)
        F = np.empty((n, s.nd))
        run_explicit(s.A, s.BF, s.Bw, s.Cx, s.Cv, s.Dx, s.Dv, s.Da, P, lag, q, st, u, V[0], Wx, 1e-3, F)

    def accurate():
        plant.reset()
        plant.step(V, w)

    for f in (explicit, accurate):  # compile (or load from the cache) first
        f()
    times = {"accurate": [], "explicit": []}
    for _ in range(repeats):
        for name, f in (("explicit", explicit), ("accurate", accurate)):
            t0 = time.perf_counter()
            f()
            times[name].append((time.perf_counter() - t0) / n * 1e6)
    ratios = [a / e for a, e in zip(times["accurate"], times["explicit"])]
    load = os.getloadavg()[0]
    return [{"step": "accurate (SDIRK2 + Newton + error control)", "us_per_simulated_ms": float(np.median(times["accurate"])),
             "ratio_to_explicit": float(np.median(ratios)), "load_1min": load},
            {"step": "explicit Euler, same equations (the limit)", "us_per_simulated_ms": float(np.median(times["explicit"])),
             "ratio_to_explicit": 1.0, "load_1min": load}]


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=20.0, help="length of the record (s)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.repeats < 1:
        ap.error("--seconds must be > 0 and --repeats >= 1")
    rows = bench(args.seconds, args.repeats)
    md, _ = write_table(rows, args.out / "physics_step",
                        title="Quarter-car physics step, µs per simulated ms (1 kHz, one call per record)",
                        floatfmt=".3g")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
