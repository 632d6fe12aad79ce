"""Identification benchmark (a script, not a test): synthetic recovery for every registered model, and the
real-data comparison when a measured record is given.

    python -m experiments.measurements.accuracy.identification                       # synthetic recovery, all models
    python -m experiments.measurements.accuracy.identification --real /path/to/ranran_50_converted.csv --fs 3004.8
    python -m experiments.measurements.accuracy.identification --skip-synthetic --propagate 20   # sensor-error propagation

Synthetic recovery: each model's default preset is driven on the virtual rig (an 8 s random stroke with the
command switched at random, and sinusoids at four command levels), white force noise of 1 % of the force
standard deviation is added, the fit starts from the preset's free parameters multiplied by random factors in
[0.8, 1.25] (seeded) and runs bounded least squares on the pooled samples (``weighting="sample"``: one noise
level on every record, so this is the maximum-likelihood fit). Per parameter: the recovery error and the Cramér–Rao
bound of its relative standard deviation (:func:`mrd_env.identification.fit.sensitivity`); a parameter with a
bound ≤ 0.5 % is counted as well identifiable.

Real data (``--real``): :func:`mrd_env.identification.compare.compare_models` on the record (fit on the first
--fit-fraction, errors on the rest; or fit on all of it and errors on ``--validate``): every model with its
preset's command lag; Spencer–Dyke (every model with ``--lag-all``) with the command dynamics fitted (η_rise,
η_fall, delay) and the force aligned with the motion; the neural forward model on the force offset that fit
found. The default column mapping is the NEES export's (t, D cm, Y V, F N, V cm/s).
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from mrd_env.dampers import CommandSpec, available_dampers, make_damper
from mrd_env.identification import DamperRecord, load_record_csv
from mrd_env.identification.compare import compare_models
from mrd_env.identification.fit import fit_model
from mrd_env.identification.parameters import fixed_by_default
from mrd_env.identification.sensitivity import sensitivity
from mrd_env.rig import random_test, sinusoidal_test

from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode


def synthetic_records(damper, noise: float = 0.01, seed: int = 5, duration: float = 8.0):
    recs = [random_test(damper, rms=0.004, bandwidth=8.0, duration=duration, switch_rate=2.0, rng=3)]
    lv = np.linspace(damper.command.v_min, damper.command.v_max, 4)
    recs += sinusoidal_test(damper, 0.01, 2.0, lv, cycles=2) + sinusoidal_test(damper, 0.005, 5.0, lv, cycles=4)
    sigma = noise * float(np.std(np.concatenate([r.force for r in recs])))
    rng = np.random.default_rng(seed)
    return [DamperRecord(r.t, r.x, r.command, r.force + sigma * rng.standard_normal(r.force.size), r.v,
                         r.command_unit, label=f"{r.label} #{i}") for i, r in enumerate(recs)], sigma


def perturbed_start(damper, free, seed: int = 1, tries: int = 50) -> dict:
    """The free parameters times random factors in [0.8, 1.25], redrawn until the damper is valid."""
    g = np.random.default_rng(seed)
    for _ in range(tries):
        start = {k: getattr(damper.params, k) * g.uniform(0.8, 1.25) for k in free}
        try:
            type(damper)(damper.params.replace(**start), damper.command)
            return start
        except ValueError:
            continue
    raise ValueError(f"no valid perturbed start for {damper.name!r} in {tries} draws")


def synthetic_recovery(model: str, out: Path, *, noise: float = 0.01, progress: bool = True) -> dict:
    d = make_damper(model)
    recs, sigma = synthetic_records(d, noise)
    fixed = fixed_by_default(d, d.params)
    free = [k for k in d.params.names() if k not in fixed]
    start = perturbed_start(d, free)
    crb = sensitivity(d, recs, noise=sigma)["rel_std"]
    res = fit_model(model, recs, initial=start, search={"progress": progress}, data={"weighting": "sample"})
    rows = []
    for k in free:
        true = getattr(d.params, k)
        rows.append({"parameter": k, "true": true, "start": start[k], "fitted": res.params[k],
                     "error %": 100 * (res.params[k] / true - 1), "CRB std %": 100 * crb[k],
                     "well identifiable": "yes" if crb[k] <= 0.005 else "no"})
    write_table(rows, out / f"synthetic_{model}", title=f"{model}: recovery from 1 % force noise (least squares)",
                floatfmt=".5g")
    well = [r for r in rows if r["well identifiable"] == "yes"]
    return {"model": model, "free params": len(free), "well identifiable": len(well),
            "max |error| well %": max((abs(r["error %"]) for r in well), default=float("nan")),
            "max |error|/CRB": max(abs(r["error %"]) / r["CRB std %"] for r in rows if r["CRB std %"] > 0),
            "E_t %": 100 * res.overall["E_t"], "wall time s": res.wall_time, "evaluations": res.n_evaluations,
            "well-identified parameters": " ".join(r["parameter"] for r in well)}


LAG = ("command_eta", "command_eta_fall", "command_delay")


def real_comparison(path: Path, out: Path, *, models, fs: float | None, fit_fraction: float, method: str,
                    command_range: str, progress: bool, validate: Path | None = None,
                    lag_all: bool = False) -> list[dict]:
    """The real-data table: every model fitted as before (the preset's command lag, no alignment) on the first
    ``fit_fraction`` of the record (or on all of it, scored on ``validate``); Spencer–Dyke with its command
    dynamics fitted (η_rise, η_fall, delay, starting from the preset's symmetric η) and the force aligned with the
    motion; the neural forward model on the force offset that fit found. ``lag_all``: every model the
    Spencer–Dyke way. Faults are excluded (the default). Returns the table's rows."""
    columns = {"t": "t", "x": "D", "command": "Y", "force": "F", "v": "V"}
    units = {"t": "s", "x": "cm", "command": "V", "force": "N", "v": "cm/s"}
    rec = load_record_csv(path, columns, units)
    other = None if validate is None else [load_record_csv(validate, columns, units)]
    dt = None if fs is None else 1.0 / fs
    names = [m for m in (models or available_dampers()) if m != "neural"]
    entries = [_voltage_driven(m, rec.command_unit) for m in names]
    search = {"method": method, "progress": progress}
    data = {"dt": dt, "command_range": command_range}
    common = dict(search=search, fit_fraction=fit_fraction, validation_records=other)

    def lagged(d):
        """``d`` with an asymmetric lag allowed, and its free parameters plus the command dynamics."""
        d = type(d)(d.params, dataclasses.replace(d.command, eta_fall=d.command.eta))
        return d, {"free": [k for k in d.params.names() if k not in fixed_by_default(d, d.params)] + list(LAG)}

    rows = []  # the command-dynamics fits and the network first (a failure there shows early), the table after
    offset = 0
    for d in entries if lag_all else [e for e in entries if getattr(e, "name", e) == "spencer_dyke"]:
        d, opts = lagged(make_damper(d) if isinstance(d, str) else d)
        res = compare_models([rec], [d], data={**data, "align": True}, out=out / f"{d.name}_lag_align",
                             model_options={d.name: opts}, **common)
        row = dict(res.rows[0])
        fit = res.models[0].fit
        if fit is not None:
            c = fit.damper.command
            row["model"] = (f"{d.name} + lag + align (η_rise {c.eta:.0f}/s, η_fall {c.eta_down:.0f}/s, "
                            f"τ {1e3 * c.delay:.2f} ms)")
            if d.name == "spencer_dyke":
                offset = fit.settings["offsets"][0]
        rows.append(row)
    if models is None or "neural" in models:
        res = compare_models([rec], ["neural"], search={"method": "adam", "progress": progress},
                             data={**data, "offset": offset}, fit_fraction=fit_fraction, validation_records=other,
                             out=out / "neural")
        rows.append({**res.rows[0], "model": f"neural (force offset {offset} from Spencer–Dyke)"})
    if names:
        rows = compare_models([rec], entries, data=data, out=out / "preset_lag", **common).rows + rows
    how = "clipped to" if command_range == "clip" else "widening"
    where = (f"fit on all of {path.name}, errors on {validate.name}" if validate is not None
             else f"fit on the first {100 * fit_fraction:g} %, errors on the rest")
    write_table(rows, out / "comparison_all", title=f"{path.name}: {where} ({method}, commands {how} the preset "
                "range; faults excluded)", floatfmt=".4g")
    return rows


def _voltage_driven(model: str, unit: str):
    """Models whose command channel is a current (A) are driven by the record's voltage: the driver's V → A gain
    is absorbed into their per-command coefficients (same numbers, channel relabelled, range covering 0-2.25 V)."""
    d = make_damper(model)
    if d.command.unit == unit:
        return model
    c = d.command
    try:
        return type(d)(d.params, CommandSpec(unit, min(c.v_min, 0.0), max(c.v_max, 2.25), c.eta))
    except ValueError:  # the preset is not valid over the wider range: keep its own (commands clipped)
        return type(d)(d.params, CommandSpec(unit, c.v_min, c.v_max, c.eta))


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--real", type=Path, default=None, help="measured record (NEES export layout)")
    p.add_argument("--fs", type=float, default=3004.8, help="its sampling rate in Hz (simulation grid 1/fs)")
    p.add_argument("--fit-fraction", type=float, default=0.6)
    p.add_argument("--method", default="least_squares")
    p.add_argument("--command-range", default="clip", choices=("clip", "widen"))
    p.add_argument("--models", nargs="+", default=None,
                   help="default: all registered models and the neural forward model")
    p.add_argument("--validate", type=Path, default=None,
                   help="with --real: fit on all of that record, report the errors on this one")
    p.add_argument("--lag-all", action="store_true",
                   help="with --real: fit every model with its command dynamics and the force alignment")
    p.add_argument("--skip-synthetic", action="store_true")
    p.add_argument("--propagate", type=int, default=0, metavar="N",
                   help="also propagate the default sensor errors (review Table 7) to the Spencer–Dyke parameters "
                        "with N Monte-Carlo draws")
    p.add_argument("--out", type=Path, default=Path("results/bench_identification"))
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    models = args.models or available_dampers() + ["neural"]
    progress = not args.no_progress
    if not args.skip_synthetic:
        summary = []
        for m in [m for m in models if m != "neural"]:  # the network has no true parameters to recover
            t0 = time.perf_counter()
            try:
                summary.append(synthetic_recovery(m, out, progress=progress))
            except Exception as exc:  # a benchmark keeps going and reports the failure
                summary.append({"model": m, "free params": 0, "well identifiable": 0,
                                "max |error| well %": math.nan, "max |error|/CRB": math.nan, "E_t %": math.nan,
                                "wall time s": time.perf_counter() - t0, "evaluations": 0,
                                "well-identified parameters": f"failed: {type(exc).__name__}: {exc}"})
            print(summary[-1], flush=True)
        md, _ = write_table(summary, out / "synthetic_summary",
                            title="Synthetic recovery, 1 % force noise, bounded least squares", floatfmt=".3g")
        print(md.read_text())
    if args.propagate:
        from mrd_env.identification.propagate import propagate_sensor_errors
        pr = propagate_sensor_errors("spencer_dyke", n_draws=args.propagate, rng=0, progress=progress,
                                     backend="auto", out=out / "propagation")
        print(pr.files["table_md"].read_text())
    if args.real is not None:
        real_comparison(args.real, out / "real", models=models, fs=args.fs, fit_fraction=args.fit_fraction,
                        method=args.method, command_range=args.command_range, progress=progress,
                        validate=args.validate, lag_all=args.lag_all)
        print((out / "real" / "comparison_all.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
