"""``mrd-env identify``: fit one damper model to a measured record; table, figure and (optionally) a preset.

The record is read with declared columns and units (SI inside), optionally cut to [--t-start, --t-end], put
on a uniform grid (its own rate: the mean sampling interval, or --fs if given; time stamps rounded in the file
are rebuilt as t0 + k·dt; it is resampled only when --dt asks for another step, and the command says so), split into a fit part (the first --fit-fraction) and a held-back validation part; the
model is fitted on the first and E_t, E_x, E_v (review eq. 3) and J2 (eq. 26) are reported on both.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from mrd_env.dampers import available_dampers, make_damper
from mrd_env.identification.compare import plot_fit, split_records, validate
from mrd_env.identification.data import DamperRecord, load_record_csv
from mrd_env.identification.fit import COMMAND_ETA, METHODS, fit_model, save_preset

from mrd_env.report import write_table

from .records import add_column_arguments, columns_and_units


def add_data_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``identify`` and ``compare-models``: the record and how to read it."""
    p.add_argument("--data", type=Path, required=True, help="CSV file with a header line")
    add_column_arguments(p)
    p.add_argument("--t-start", type=float, default=None, help="keep samples from this time on (s)")
    p.add_argument("--t-end", type=float, default=None, help="keep samples up to this time (s)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--fs", type=float, default=None,
                   help="the record's sampling rate in Hz (e.g. 3004.8): time stamps are rebuilt as t0 + k/fs; an "
                        "error if the time column has another rate (to change the rate, use --dt)")
    g.add_argument("--dt", type=float, default=None,
                   help="simulate on a grid of this step in s: the record is resampled to it when its own rate "
                        "differs (and the command says so)")
    p.add_argument("--fit-fraction", type=float, default=0.6,
                   help="fraction of the record (from its start) used for fitting; the rest validates (0.6)")
    p.add_argument("--method", default="least_squares", choices=METHODS, help="optimiser (default least_squares)")
    p.add_argument("--seed", type=int, default=0, help="seed of the stochastic optimisers (default 0)")
    p.add_argument("--maxiter", type=int, default=None,
                   help="least squares: residual evaluations (200); DE/PSO: generations (60)")
    p.add_argument("--popsize", type=int, default=None, help="DE population multiplier / PSO swarm size")
    p.add_argument("--command-range", default="clip", choices=("clip", "widen", "raise"),
                   help="commands outside the preset's range: clip them (default), widen the range, or refuse")
    p.add_argument("--fit-eta", action="store_true", help="also fit the command lag rate η (1/s)")
    p.add_argument("--warmup", type=float, default=0.0,
                   help="seconds at the start left out of the objective (model states start at rest)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_data_arguments(p)
    p.add_argument("--model", default="spencer_dyke", help=f"damper model, one of {available_dampers()}")
    p.add_argument("--preset", default=None, help="preset giving the initial guess (default: the model's)")
    p.add_argument("--free", default=None,
                   help="comma-separated parameters to fit (default: all but the fixed ones, e.g. n)")
    p.add_argument("--out", type=Path, default=Path("results/identify"), help="output folder")
    p.add_argument("--save-preset", type=Path, default=None, help="write the fitted damper as a JSON preset")


def load_data(args: argparse.Namespace) -> DamperRecord:
    columns, units = columns_and_units(args, args.data, ("t", "x", "command", "force"))
    rec = load_record_csv(args.data, columns, units)
    if args.t_start is not None or args.t_end is not None:
        t0 = rec.t[0] if args.t_start is None else args.t_start
        t1 = rec.t[-1] if args.t_end is None else args.t_end
        rec = rec.slice(t0, t1)
    return rec


def grid_dt(args: argparse.Namespace, rec: DamperRecord) -> float | None:
    """The simulation step: the record's own (None), its declared rate (--fs, checked against the time
    column) or a resampling step (--dt, announced when it changes the rate)."""
    if args.fs is not None:
        if not (math.isfinite(args.fs) and args.fs > 0):
            raise ValueError(f"--fs = {args.fs!r} is invalid: must be > 0 Hz")
        dt = 1.0 / args.fs
        if not on_grid(rec, dt):
            raise ValueError(f"--fs {args.fs:g} Hz does not match the time column of {rec.label!r} (mean rate "
                             f"{1 / rec.dt:.6g} Hz); --fs declares the record's rate, --dt resamples it")
        return dt
    if args.dt is not None:
        if not (math.isfinite(args.dt) and args.dt > 0):
            raise ValueError(f"--dt = {args.dt!r} is invalid: must be > 0 s")
        if not on_grid(rec, args.dt):
            print(f"resampling {rec.label!r} from {1 / rec.dt:.6g} Hz to {1 / args.dt:.6g} Hz (--dt {args.dt:g})")
        return args.dt
    return None


def on_grid(rec: DamperRecord, dt: float) -> bool:
    """True if every time stamp lies within dt/2 of t0 + k·dt (the record is sampled at 1/dt)."""
    k = np.arange(rec.n)
    return bool(np.abs(rec.t - (rec.t[0] + dt * k)).max() <= 0.5 * dt)


def fit_options(args: argparse.Namespace) -> dict:
    return {"maxiter": args.maxiter, "popsize": args.popsize, "command_range": args.command_range,
            "warmup": args.warmup}


def _pct(x: float) -> float:
    return 100.0 * x


def run(args: argparse.Namespace) -> int:
    rec = load_data(args)
    dt = grid_dt(args, rec)
    whole, fits, idx = split_records([rec], args.fit_fraction, dt)
    damper0 = make_damper(args.model, args.preset)
    free = None
    if args.free:
        free = [s.strip() for s in args.free.split(",") if s.strip()]
    if args.fit_eta:
        if free is None:
            from mrd_env.identification.fit import fixed_by_default
            fixed = fixed_by_default(damper0, damper0.params)
            free = [k for k in damper0.params.names() if k not in fixed]
        free = list(free) + [COMMAND_ETA]
    fr = fit_model(args.model, fits, preset=args.preset, free=free, method=args.method, seed=args.seed, dt=dt,
                   progress=not args.no_progress, **fit_options(args))
    v_rows, v_all, forces, _ = validate(fr.damper, whole, idx, dt=dt, command_range=args.command_range)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    f = fr.overall
    rows = [{"part": "fit", "samples": fr.per_record[0]["n"], "E_t %": _pct(f["E_t"]), "E_x %": _pct(f["E_x"]),
             "E_v %": _pct(f["E_v"]), "J2 N": f["J2"]},
            {"part": "validation", "samples": v_rows[0]["n"], "E_t %": _pct(v_all["E_t"]),
             "E_x %": _pct(v_all["E_x"]), "E_v %": _pct(v_all["E_v"]), "J2 N": v_all["J2"]}]
    title = (f"{fr.model} fitted by {fr.method} (seed {fr.seed}) on {rec.label}: {fr.n_evaluations} evaluations, "
             f"{fr.wall_time:.1f} s, {'converged' if fr.converged else 'not converged'}")
    md, csv_path = write_table(rows, out / f"{fr.model}_identify", title=title, floatfmt=".4g")
    units = fr.damper.Params.units()
    values = fr.free_values()
    prow = []
    for k in list(fr.damper.params.names()) + ([COMMAND_ETA] if COMMAND_ETA in fr.free else []):
        is_free = k in fr.free
        init = fr.settings["initial_eta"] if k == COMMAND_ETA else fr.initial[k]
        fitted = values[k] if is_free else fr.params[k]
        lo, hi = fr.bounds.get(k, (float("nan"), float("nan")))
        prow.append({"parameter": k, "unit": units.get(k, "1/s"), "initial": float(init), "fitted": float(fitted),
                     "lower": float(lo), "upper": float(hi),
                     "status": "free" if is_free else f"fixed ({fr.fixed.get(k, 'not in --free')})"})
    pmd, pcsv = write_table(prow, out / f"{fr.model}_params", title=f"{fr.model}: parameters (SI)",
                            floatfmt=".6g")
    fig = plot_fit(whole[0], {fr.model: forces[0]}, out / f"{fr.model}_fit.png", split_index=idx[0],
                   title=f"{fr.model} on {rec.label}, held-back part: E_t = {_pct(v_all['E_t']):.1f} %")
    written = [md, csv_path, pmd, pcsv, fig]
    if args.save_preset is not None:
        written.append(save_preset(fr, args.save_preset))
    print(md.read_text())
    print(pmd.read_text())
    print("wrote " + ", ".join(str(p) for p in written))
    return 0
