"""Identification benchmark (a script, not a test): synthetic recovery for every registered model, and the
real-data comparison when a measured record is given.

    python -m experiments.bench_identification                       # synthetic recovery, all models
    python -m experiments.bench_identification --real /path/to/ranran_50_converted.csv --fs 3004.8
    python -m experiments.bench_identification --skip-synthetic --propagate 20   # sensor-error propagation

Synthetic recovery: each model's default preset is driven on the virtual rig (an 8 s random stroke with the
command switched at random, and sinusoids at four command levels), white force noise of 1 % of the force
standard deviation is added, the fit starts from the preset's free parameters multiplied by random factors in
[0.8, 1.25] (seeded) and runs bounded least squares on the pooled samples (``weighting="sample"``: one noise
level on every record, so this is the maximum-likelihood fit). Per parameter: the recovery error and the Cramér–Rao
bound of its relative standard deviation (:func:`mrd_env.identification.fit.sensitivity`); a parameter with a
bound ≤ 0.5 % is counted as well identifiable.

Real data: :func:`mrd_env.identification.compare.compare_models` on the record (fit on the first
--fit-fraction, errors on the rest), plus Spencer–Dyke with the command lag η fitted as well. The default
column mapping is the NEES export's (t, D cm, Y V, F N, V cm/s).
"""
from __future__ import annotations

import argparse
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


def real_comparison(path: Path, out: Path, *, models, fs: float | None, fit_fraction: float, method: str,
                    command_range: str, progress: bool, validate: Path | None = None) -> list[dict]:
    """Every model (and the neural forward model) fitted on the first ``fit_fraction`` of the record (or on all
    of it, scored on ``validate``); then Spencer–Dyke with the command dynamics fitted (asymmetric lag and delay)
    and the force aligned with the motion. Faults are excluded (the default). Returns the table's rows."""
    columns = {"t": "t", "x": "D", "command": "Y", "force": "F", "v": "V"}
    units = {"t": "s", "x": "cm", "command": "V", "force": "N", "v": "cm/s"}
    rec = load_record_csv(path, columns, units)
    other = None if validate is None else load_record_csv(validate, columns, units)
    dt = None if fs is None else 1.0 / fs
    # models whose command channel is a current (A) are driven by the record's voltage: the driver's V → A gain
    # is absorbed into their per-command coefficients (same numbers, channel relabelled, range covering 0-2.25 V)
    entries = []
    for m in (models or available_dampers()):
        if m == "neural":
            entries.append(m)
            continue
        d = make_damper(m)
        if d.command.unit != rec.command_unit:
            c = d.command
            try:
                d = type(d)(d.params, CommandSpec(rec.command_unit, min(c.v_min, 0.0), max(c.v_max, 2.25), c.eta))
            except ValueError:  # the preset is not valid over the wider range: keep its own (commands clipped)
                d = type(d)(d.params, CommandSpec(rec.command_unit, c.v_min, c.v_max, c.eta))
            entries.append(d)
        else:
            entries.append(m)
    search = {"method": method, "progress": progress}
    data = {"dt": dt, "command_range": command_range}
    res = compare_models([rec], entries, search=search, data=data, fit_fraction=fit_fraction, out=out,
                         validation_records=None if other is None else [other],
                         model_options={"neural": {"search": {"method": "adam", "progress": progress}}})
    rows = res.rows
    if "spencer_dyke" in (models or available_dampers()):
        # the command dynamics fitted (η_rise, η_fall, delay) and the force aligned with the motion
        d = make_damper("spencer_dyke", command={"eta_fall": 190.0})
        free = [k for k in d.params.names() if k not in fixed_by_default(d, d.params)]
        free += ["command_eta", "command_eta_fall", "command_delay"]
        sd = compare_models([rec], [d], search=search, data={**data, "align": True}, fit_fraction=fit_fraction,
                            out=out / "spencer_dyke_lag", validation_records=None if other is None else [other],
                            model_options={"spencer_dyke": {"free": free,
                                                            "initial": {"command_eta": 300.0,
                                                                        "command_eta_fall": 125.0}}})
        row = dict(sd.rows[0])
        c = sd.models[0].fit.damper.command if sd.models[0].fit is not None else None
        row["model"] = ("spencer_dyke + lag + align" + ("" if c is None else
                        f" (η_rise {c.eta:.0f}/s, η_fall {c.eta_down:.0f}/s, τ {1e3 * c.delay:.2f} ms)"))
        rows.append(row)
    how = "clipped to" if command_range == "clip" else "widening"
    where = (f"fit on all of {path.name}, errors on {validate.name}" if validate is not None
             else f"fit on the first {100 * fit_fraction:g} %, errors on the rest")
    write_table(rows, out / "comparison_all", title=f"{path.name}: {where} ({method}, commands {how} the preset "
                "range; faults excluded)", floatfmt=".4g")
    return rows


def main(argv=None) -> int:
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
                                     out=out / "propagation")
        print(pr.files["table_md"].read_text())
    if args.real is not None:
        real_comparison(args.real, out / "real", models=models, fs=args.fs, fit_fraction=args.fit_fraction,
                        method=args.method, command_range=args.command_range, progress=progress,
                        validate=args.validate)
        print((out / "real" / "comparison_all.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
