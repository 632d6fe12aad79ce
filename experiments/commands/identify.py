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
import sys
from pathlib import Path

from mrd_env.dampers import available_dampers
from mrd_env.identification.compare import fr_data, plot_fit, split_records, validate, validation_offsets
from mrd_env.identification.fit import fit_model
from mrd_env.identification.neural import NAME as NEURAL
from mrd_env.identification.parameters import COMMAND_PARAMS
from mrd_env.identification.prepare import uniform_record
from mrd_env.identification.presets import save_preset
from mrd_env.identification.result import FitInterrupted
from mrd_env.report import write_table

from ..common.fitting import (add_data_arguments, free_with_command, grid_dt, load_data, neural_data, options,
                              reported_warnings)
from ..common.records import parse_pairs


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


def records_and_grid(args: argparse.Namespace):
    """(fit records, whole records to score, first scored sample of each, dt) from --data and --validate."""
    recs = load_data(args)
    dt = grid_dt(args, recs[0])
    if args.validate:
        whole = [uniform_record(r, dt) for r in load_data(args, args.validate)]
        return recs, whole, [0] * len(whole), dt
    whole, fits, idx = split_records(recs, args.fit_fraction, dt, args.faults)
    return fits, whole, idx, dt


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
