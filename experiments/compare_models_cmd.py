"""``mrd-env compare-models``: fit several damper models to one measured record and compare them on the
held-back part (E_t, E_x, E_v, J2, wall time), with overlay figures and one fitted preset per model."""
from __future__ import annotations

import argparse
from pathlib import Path

from mrd_env.dampers import available_dampers
from mrd_env.identification.compare import compare_models

from .identify_cmd import add_data_arguments, fit_options, grid_dt, load_data


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_data_arguments(p)
    p.add_argument("--models", nargs="+", default=None,
                   help=f"models to compare (default: all registered: {available_dampers()})")
    p.add_argument("--plot-window", type=float, default=1.0,
                   help="seconds of the held-back part shown over time in the figures (default 1)")
    p.add_argument("--out", type=Path, default=Path("results/compare"), help="output folder")


def run(args: argparse.Namespace) -> int:
    rec = load_data(args)
    opts = fit_options(args)
    model_options = None
    if args.fit_eta:
        from mrd_env.identification.fit import COMMAND_ETA, fixed_by_default
        from mrd_env.dampers import make_damper
        model_options = {}
        for m in args.models or available_dampers():
            d = make_damper(m)
            fixed = fixed_by_default(d, d.params)
            model_options[m] = {"free": [k for k in d.params.names() if k not in fixed] + [COMMAND_ETA]}
    res = compare_models([rec], args.models, method=args.method, fit_fraction=args.fit_fraction, out=args.out,
                         seed=args.seed, dt=grid_dt(args, rec), progress=not args.no_progress,
                         plot_window=args.plot_window, fit_options=opts, model_options=model_options)
    failed = [m.model for m in res.models if m.fit is None]
    if len(failed) == len(res.models):  # nothing to compare: an error, whatever the table says
        raise ValueError(f"no model could be fitted (table in {args.out}); {res.models[0].model}: "
                         f"{res.models[0].error}")
    print(res.files["table_md"].read_text())
    print(f"wrote {len(res.files)} files in {args.out}")
    if failed:
        print(f"failed: {', '.join(failed)} (see the table)")
    return 0
