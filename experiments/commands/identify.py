"""``mrd-env identify``: fit one damper model to a measured record; table, figure and (optionally) a preset.

The record is read with declared columns and units (SI inside), optionally cut to [--t-start, --t-end], put
on a uniform grid (its own rate: the mean sampling interval, or --fs if given; time stamps rounded in the file
are rebuilt as t0 + k·dt; it is resampled only when --dt asks for another step, and the command says so), split
into a fit part (the first --fit-fraction) and a held-back validation part; the model is fitted on the first and
E_t, E_x, E_v (review eq. 3) and J2 (eq. 26) are reported on both. With --validate FILE the model is fitted on
the whole of --data and scored on FILE (another test of the same damper). Faults found in a record (saturated
channels, spikes, gaps, run-aways) are excluded from the fit and the errors, and listed; --align (--force-offset auto)
corrects a constant sample offset between the force and the motion channels, --force-offset N imposes one;
--model neural fits the neural forward model. Parameters fitted onto a bound are flagged in the table and warned.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import sys
import warnings
from pathlib import Path

import numpy as np

from mrd_env.dampers import available_dampers, make_damper
from mrd_env.identification.compare import fr_data, plot_fit, split_records, validate, validation_offsets
from mrd_env.records import DamperRecord, load_record_csv
from mrd_env.identification.faults import FaultsExcluded
from mrd_env.identification.fit import OFFSET_REFERENCE, fit_model, reference_offset
from mrd_env.identification.neural import NAME as NEURAL
from mrd_env.identification.options import METHODS, DataOptions, SearchOptions
from mrd_env.identification.parameters import COMMAND_ETA, COMMAND_PARAMS, fixed_by_default
from mrd_env.identification.prepare import FAULT_MODES, uniform_record
from mrd_env.identification.presets import save_preset
from mrd_env.identification.result import FitInterrupted, ParameterAtBound

from mrd_env.report import write_table
from mrd_env.validation import describe_range

from ..common.records import add_column_arguments, columns_and_units, parse_pairs


def number(cast=float, *, lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False,
           hi_open: bool = False, unit: str = ""):
    """An argparse type: a finite number (``cast``: float or int) in a range; argparse names the option in its
    one-line error ("argument --maxiter: 0 is invalid: must be finite and >= 1")."""
    def parse(text: str):
        try:
            v = cast(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'a whole number' if cast is int else 'a number'}"
                                             ) from None
        if not (math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)):
            limits = describe_range(lo, hi, lo_open, hi_open, unit)
            if cast is int:
                limits = "a whole number " + limits.removeprefix("finite and ")
            raise argparse.ArgumentTypeError(f"{text} is invalid: must be {limits}")
        return v
    return parse


def add_data_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by ``identify`` and ``compare-models``: the record and how to read it."""
    p.add_argument("--data", type=Path, nargs="+", required=True,
                   help="CSV file(s) with a header line (several: one fit over all of them)")
    p.add_argument("--validate", type=Path, nargs="+", default=None, metavar="FILE",
                   help="score the models on these records (other tests of the same damper) after fitting on the "
                        "whole of --data; the table shows the fit and the validation errors")
    add_column_arguments(p)
    p.add_argument("--t-start", type=number(), default=None, help="keep samples from this time on (s)")
    p.add_argument("--t-end", type=number(), default=None, help="keep samples up to this time (s)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--fs", type=number(lo=0.0, lo_open=True, unit="Hz"), default=None,
                   help="the record's sampling rate in Hz (e.g. 3004.8): time stamps are rebuilt as t0 + k/fs; an "
                        "error if the time column has another rate (to change the rate, use --dt)")
    g.add_argument("--dt", type=number(lo=0.0, lo_open=True, unit="s"), default=None,
                   help="simulate on a grid of this step in s: the record is resampled to it when its own rate "
                        "differs (and the command says so)")
    p.add_argument("--fit-fraction", type=number(lo=0.0, hi=1.0, lo_open=True, hi_open=True), default=0.6,
                   help="fraction of the record (from its start) used for fitting; the rest validates (0.6)")
    p.add_argument("--method", default="least_squares", choices=METHODS, help="optimiser (default least_squares)")
    p.add_argument("--seed", type=number(int, lo=0), default=0, help="seed of the stochastic optimisers (default 0)")
    p.add_argument("--maxiter", type=number(int, lo=1), default=None,
                   help="least squares: residual evaluations (200); DE/PSO: generations (60)")
    p.add_argument("--popsize", type=number(int, lo=1), default=None, help="DE population multiplier / PSO swarm size")
    p.add_argument("--command-range", default="clip", choices=("clip", "widen", "raise"),
                   help="commands outside the preset's range: clip them (default), widen the range, or refuse")
    p.add_argument("--fit-eta", action="store_true", help="also fit the command lag rate η (1/s)")
    p.add_argument("--fit-lag", action="store_true",
                   help="also fit the command dynamics: η on a rise, η on a fall (1/s) and a pure delay (s)")
    p.add_argument("--align", action="store_true",
                   help="estimate and correct a constant sample offset between the force and the motion channels "
                        "(the same as --force-offset auto)")
    p.add_argument("--force-offset", default=None, metavar="SAMPLES|auto",
                   help="the force channel's lag behind the stroke and velocity channels, in whole samples "
                        "(positive: the force lags; a time shift, not a force), imposed on every model; auto: "
                        "estimated — by each parametric model's own fit, and for the neural model (which cannot "
                        f"find it) by a {OFFSET_REFERENCE} fit with its command lag first. Default: 0")
    p.add_argument("--faults", default="exclude", choices=FAULT_MODES,
                   help="saturated channels, spikes, gaps and run-aways (a test gone wrong as a whole): exclude them "
                        "from the fit and errors (default, listed on the console), keep them, or refuse the record")
    p.add_argument("--warmup", type=number(lo=0.0, unit="s"), default=0.0,
                   help="seconds at the start left out of the objective (model states start at rest)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_data_arguments(p)
    p.add_argument("--model", default="spencer_dyke",
                   help=f"damper model, one of {available_dampers()}, or neural (the neural forward model)")
    p.add_argument("--preset", default=None, help="preset giving the initial guess (default: the model's)")
    p.add_argument("--free", default=None,
                   help="comma-separated parameters to fit (default: all but the fixed ones, e.g. n)")
    p.add_argument("--bounds", default=None, metavar="NAME=LO:HI,...",
                   help="bounds of free parameters in SI units, e.g. k0=1:2000,c0a=100:1e5 (default: a tenth to "
                        "ten times the initial value, inside the valid range)")
    p.add_argument("--out", type=Path, default=Path("results/identify"), help="output folder")
    p.add_argument("--save-preset", type=Path, default=None, help="write the fitted damper as a JSON preset")


def load_data(args: argparse.Namespace, paths: list[Path] | None = None) -> list[DamperRecord]:
    """The records of ``paths`` (default --data), cut to [--t-start, --t-end]."""
    if args.t_start is not None and args.t_end is not None and not args.t_start < args.t_end:
        raise ValueError(f"--t-start {args.t_start:g} s must be before --t-end {args.t_end:g} s")
    recs = []
    for path in paths or args.data:
        columns, units = columns_and_units(args, path, ("t", "x", "command", "force"))
        rec = load_record_csv(path, columns, units)
        if args.t_start is not None or args.t_end is not None:
            t0 = float(rec.t[0]) if args.t_start is None else args.t_start
            t1 = float(rec.t[-1]) if args.t_end is None else args.t_end
            kept = int(np.count_nonzero((rec.t >= t0) & (rec.t <= t1)))
            if kept < 3:
                raise ValueError(f"--t-start/--t-end keep {kept} samples of {rec.label!r} (need >= 3): the record "
                                 f"spans [{rec.t[0]:g}, {rec.t[-1]:g}] s, the window is [{t0:g}, {t1:g}] s")
            rec = rec.slice(t0, t1)
        recs.append(rec)
    return recs


def grid_dt(args: argparse.Namespace, rec: DamperRecord) -> float | None:
    """The simulation step: the record's own (None), its declared rate (--fs, checked against the time
    column) or a resampling step (--dt, announced when it changes the rate)."""
    if args.fs is not None:
        dt = 1.0 / args.fs
        if not on_grid(rec, dt):
            raise ValueError(f"--fs {args.fs:g} Hz does not match the time column of {rec.label!r} (mean rate "
                             f"{1 / rec.dt:.6g} Hz); --fs declares the record's rate, --dt resamples it")
        return dt
    if args.dt is not None:
        if not on_grid(rec, args.dt):
            print(f"resampling {rec.label!r} from {1 / rec.dt:.6g} Hz to {1 / args.dt:.6g} Hz (--dt {args.dt:g})")
        return args.dt
    return None


def on_grid(rec: DamperRecord, dt: float) -> bool:
    """True if every time stamp lies within dt/2 of t0 + k·dt (the record is sampled at 1/dt)."""
    k = np.arange(rec.n)
    return bool(np.abs(rec.t - (rec.t[0] + dt * k)).max() <= 0.5 * dt)


def force_offset(args: argparse.Namespace) -> int | str:
    """--force-offset (and --align) as a number of samples or "auto"."""
    text = getattr(args, "force_offset", None)
    if text is None:
        return "auto" if args.align else 0
    if text.strip().lower() == "auto":
        return "auto"
    try:
        k = int(text)
    except ValueError:
        raise ValueError(f"--force-offset {text!r} is invalid: give a whole number of samples (the force channel's "
                         "lag behind the motion channels, e.g. -1 or 2; a time shift, not a force) or auto") from None
    if args.align:
        raise ValueError(f"--align estimates the force offset and --force-offset {k} imposes one: give one of them")
    return k


def options(args: argparse.Namespace, dt: float | None) -> tuple[SearchOptions, DataOptions]:
    """The search and data options of the command line."""
    search = SearchOptions(method=args.method, seed=args.seed, maxiter=args.maxiter, popsize=args.popsize,
                           progress=not args.no_progress)
    offset = force_offset(args)
    data = DataOptions(dt=dt, warmup=args.warmup, command_range=args.command_range, faults=args.faults,
                       align=offset == "auto", offset=None if offset == "auto" else offset)
    return search, data


def neural_data(args: argparse.Namespace, fits, data: DataOptions) -> DataOptions:
    """The neural model's data options: with --force-offset auto the offset that a reference fit finds on the fit
    records (the network cannot find it, see mrd_env.identification.align), announced on the console."""
    if not data.align:
        return data
    print(f"finding the force offset for the neural model: a {OFFSET_REFERENCE} fit with its command lag ...")
    k, ref = reference_offset(fits, search=SearchOptions(seed=args.seed, progress=not args.no_progress), data=data)
    print(f"note: force offset {k} samples, found by the {ref.model} fit ({ref.wall_time:.0f} s; "
          f"--force-offset {k} skips that fit next time)")
    return dataclasses.replace(data, align=False, offset=k)


def parse_bounds(text: str | None) -> dict[str, tuple[float, float]] | None:
    """--bounds "k0=1:2000,c0a=100:1e5" as {name: (lo, hi)}."""
    if text is None:
        return None
    out = {}
    for name, span in parse_pairs(text, "--bounds").items():
        try:
            lo, hi = (float(v) for v in span.split(":"))
        except ValueError:
            raise ValueError(f"--bounds: expected NAME=LO:HI (numbers in SI units), got {name}={span}") from None
        out[name] = (lo, hi)
    return out


def free_with_command(args: argparse.Namespace, model: str, free: list[str] | None) -> list[str] | None:
    """``free`` (default: the model's) plus the command pseudo-parameters asked for by --fit-eta / --fit-lag."""
    extra = list(COMMAND_PARAMS) if args.fit_lag else [COMMAND_ETA] if args.fit_eta else []
    if not extra or model == "neural":
        return free
    if free is None:
        d = make_damper(model)
        free = [k for k in d.params.names() if k not in fixed_by_default(d, d.params)]
    return list(free) + [k for k in extra if k not in free]


def records_and_grid(args: argparse.Namespace):
    """(fit records, whole records to score, first scored sample of each, dt) from --data and --validate."""
    recs = load_data(args)
    dt = grid_dt(args, recs[0])
    if args.validate:
        whole = [uniform_record(r, dt) for r in load_data(args, args.validate)]
        return recs, whole, [0] * len(whole), dt
    whole, fits, idx = split_records(recs, args.fit_fraction, dt, args.faults)
    return fits, whole, idx, dt


#: The warnings of a fit that the commands print, one line each (never silently), and their prefix.
REPORTED = {FaultsExcluded: "note", ParameterAtBound: "warning"}


@contextlib.contextmanager
def reported_warnings():
    """Record the :data:`REPORTED` warnings raised inside the block and print them on leaving it, each once."""
    with warnings.catch_warnings(record=True) as caught:
        for category in REPORTED:
            warnings.simplefilter("always", category)
        yield
    seen = []
    for w in caught:
        msg = str(w.message)
        if w.category in REPORTED and msg not in seen:
            seen.append(msg)
            print(f"{REPORTED[w.category]}: {msg}")


def _pct(x: float) -> float:
    return 100.0 * x


def check_model_options(args: argparse.Namespace) -> None:
    """Options that do not apply to --model: refused before any work, naming them."""
    if args.model == NEURAL:
        given = [opt for opt, v in (("--preset", args.preset), ("--free", args.free), ("--bounds", args.bounds),
                                    ("--fit-eta", args.fit_eta or None), ("--fit-lag", args.fit_lag or None))
                 if v is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: parametric models only; the neural model has no named parameters "
                             "(it learns the command lag from the record)")
        if args.method not in ("least_squares", "adam"):
            raise ValueError(f"--method {args.method}: the neural model is trained by adam (give --method adam or "
                             "leave --method out)")
    elif args.method == "adam":
        raise ValueError(f"--method adam trains --model neural only; {args.model} takes least_squares, "
                         "differential_evolution or pso")


def run(args: argparse.Namespace) -> int:
    check_model_options(args)
    fits, whole, idx, dt = records_and_grid(args)
    free = [s.strip() for s in args.free.split(",") if s.strip()] if args.free else None
    free = free_with_command(args, args.model, free)
    search, data = options(args, dt)
    bounds = parse_bounds(args.bounds)
    with reported_warnings():
        if args.model == NEURAL:
            data = neural_data(args, fits, data)
        try:
            fr, stopped = fit_model(args.model, fits, preset=args.preset, free=free, bounds=bounds, search=search,
                                    data=data), None
        except FitInterrupted as exc:  # Ctrl-C or SIGTERM: the best parameters so far are written, then it stops
            fr, stopped = exc.result, exc.__cause__
        v_rows, v_all, forces, _ = validate(fr.damper, whole, idx, data=fr_data(fr, data),
                                            offset=validation_offsets(fr, whole, idx))
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    f = fr.overall
    part = "validation (other record)" if args.validate else "validation"
    rows = [{"part": "fit", "samples": sum(r["n"] for r in fr.per_record), "E_t %": _pct(f["E_t"]),
             "E_x %": _pct(f["E_x"]), "E_v %": _pct(f["E_v"]), "J2 N": f["J2"]},
            {"part": part, "samples": sum(r["n"] for r in v_rows), "E_t %": _pct(v_all["E_t"]),
             "E_x %": _pct(v_all["E_x"]), "E_v %": _pct(v_all["E_v"]), "J2 N": v_all["J2"]}]
    label = ", ".join(r["label"] for r in fr.records)
    title = (f"{fr.model} fitted by {fr.method} (seed {fr.seed}) on {label}: {fr.n_evaluations} evaluations, "
             f"{fr.wall_time:.1f} s, {'converged' if fr.converged else 'not converged'}, force offset "
             f"{fr.settings['offsets']} samples")
    md, csv_path = write_table(rows, out / f"{fr.model}_identify", title=title, floatfmt=".4g")
    written = [md, csv_path]
    if fr.free:
        pmd, pcsv = write_table(parameter_rows(fr), out / f"{fr.model}_params", title=f"{fr.model}: parameters (SI)",
                                floatfmt=".6g")
        written += [pmd, pcsv]
    fig = plot_fit(whole[0], {fr.model: forces[0]}, out / f"{fr.model}_fit.png", split_index=idx[0],
                   title=f"{fr.model} on {whole[0].label}, {part}: E_t = {_pct(v_all['E_t']):.1f} %")
    written.append(fig)
    if args.save_preset is not None:
        written.append(save_preset(fr, args.save_preset))
    for path in written:
        if path.suffix == ".md":
            print(path.read_text())
    print("wrote " + ", ".join(str(p) for p in written))
    if stopped is not None:
        print(f"interrupted after {fr.n_evaluations} evaluations: wrote the best parameters so far (not converged)",
              file=sys.stderr)
        raise stopped
    return 0


def parameter_rows(fr) -> list[dict]:
    """One row per parameter (and fitted command pseudo-parameter): initial, fitted, bounds (empty when fixed),
    and its status: free, at its lower or upper bound, or fixed and why."""
    units = fr.damper.Params.units()
    values = fr.free_values()
    at_bound = fr.bound_status()
    rows = []
    for k in list(fr.damper.params.names()) + [k for k in COMMAND_PARAMS if k in fr.free]:
        row = {"parameter": k, "unit": units.get(k) or COMMAND_PARAMS[k][1], "initial": float(fr.initial[k])}
        if k in fr.free:
            lo, hi = fr.bounds[k]
            row.update(fitted=float(values[k]), lower=float(lo), upper=float(hi), status=at_bound.get(k, "free"))
        else:
            row.update(fitted=float(fr.params[k]), lower="", upper="",
                       status=f"fixed ({fr.fixed.get(k, 'not in --free')})")
        rows.append(row)
    return rows
