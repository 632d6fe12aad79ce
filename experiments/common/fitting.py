"""What the commands that fit damper models to measured records share (``identify``, ``compare-models``,
``inverse``): the options naming the records and how to read and fit them (:func:`add_data_arguments`), the records
they give (:func:`load_data`, :func:`grid_dt`), the search and data options (:func:`options`, :func:`neural_data`,
:func:`free_with_command`), the fit's warnings on the console (:func:`reported_warnings`), and :func:`number`, the
argparse type of their numeric options."""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np

from mrd_env.dampers import make_damper
from mrd_env.identification.faults import FaultsExcluded
from mrd_env.identification.fit import OFFSET_REFERENCE, reference_offset
from mrd_env.identification.options import METHODS, DataOptions, SearchOptions
from mrd_env.identification.parameters import COMMAND_ETA, COMMAND_PARAMS, fixed_by_default
from mrd_env.identification.prepare import FAULT_MODES
from mrd_env.identification.result import ParameterAtBound
from mrd_env.records import DamperRecord, load_record_csv
from mrd_env.validation import describe_range

from .records import add_column_arguments, columns_and_units


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


def free_with_command(args: argparse.Namespace, model: str, free: list[str] | None) -> list[str] | None:
    """``free`` (default: the model's) plus the command pseudo-parameters asked for by --fit-eta / --fit-lag."""
    extra = list(COMMAND_PARAMS) if args.fit_lag else [COMMAND_ETA] if args.fit_eta else []
    if not extra or model == "neural":
        return free
    if free is None:
        d = make_damper(model)
        free = [k for k in d.params.names() if k not in fixed_by_default(d, d.params)]
    return list(free) + [k for k in extra if k not in free]


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
