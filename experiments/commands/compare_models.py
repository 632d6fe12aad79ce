"""``mrd-env compare-models``: fit several damper models (and the neural forward model) to measured records and
compare them on the held-back part — or, with --validate FILE, on another record — (E_t, E_x, E_v, J2, wall
time), with overlay figures and one fitted preset per model."""
from __future__ import annotations

import argparse
from pathlib import Path

from mrd_env.dampers import available_dampers
from mrd_env.identification.compare import compare_models, split_records
from mrd_env.identification.neural import NAME as NEURAL

from ..common import sweep
from ..common.fitting import (add_data_arguments, free_with_command, grid_dt, load_data, neural_data, number,
                              options, reported_warnings)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_data_arguments(p)
    p.add_argument("--models", nargs="+", default=None,
                   help=f"models to compare (default: all registered: {available_dampers()}); add neural for the "
                        "neural forward model")
    p.add_argument("--plot-window", type=number(lo=0.0, lo_open=True, unit="s"), default=1.0,
                   help="seconds of the held-back part shown over time in the figures (default 1)")
    p.add_argument("--out", type=Path, default=Path("results/compare"), help="output folder")
    sweep.add_arguments(p)


def check_models(models: list[str]) -> None:
    """--models: known names, each once."""
    known = available_dampers() + [NEURAL]
    bad = sorted({m for m in models if m not in known})
    if bad:
        raise ValueError(f"--models: unknown model(s) {bad}; available: {known}")
    twice = sorted({m for m in models if models.count(m) > 1})
    if twice:
        raise ValueError(f"--models: {', '.join(twice)} given more than once")


def run(args: argparse.Namespace) -> int:
    if args.models:
        check_models(args.models)
    executor = sweep.options(args)
    recs = load_data(args)
    others = load_data(args, args.validate) if args.validate else None
    search, data = options(args, grid_dt(args, recs[0]))
    models = args.models or available_dampers()
    model_options = {m: {"free": free_with_command(args, m, None)} for m in models
                     if m != NEURAL and (args.fit_eta or args.fit_lag)}
    with reported_warnings():
        if NEURAL in models and data.align:  # the network is given the offset a reference fit finds
            fits = recs if others else split_records(recs, args.fit_fraction, data.dt, data.faults)[1]
            model_options[NEURAL] = {"data": neural_data(args, fits, data)}
        res = compare_models(recs, models, search=search, data=data, fit_fraction=args.fit_fraction,
                             validation_records=others, out=args.out, plot_window=args.plot_window,
                             model_options=model_options, progress=not args.no_progress,
                             **executor)
    failed = [m.model for m in res.models if m.fit is None]
    if len(failed) == len(res.models):  # nothing to compare: an error, whatever the table says
        raise ValueError(f"no model could be fitted (table in {args.out}); {res.models[0].model}: "
                         f"{res.models[0].error}")
    print(res.files["table_md"].read_text())
    print(f"wrote {len(res.files)} files in {args.out}")
    if failed:
        print(f"failed: {', '.join(failed)} (see the table)")
    return 0
