"""``mrd-env rig``: sinusoidal (or user-record) tests of any damper model with loops, CSV and a table."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mrd_env.dampers import available_dampers, make_damper
from mrd_env.rig import plot_loops, simulate, sinusoidal_test

from mrd_env.report import write_table

from ..common.records import add_column_arguments, read_record_columns


def replay(damper, args: argparse.Namespace):
    """The damper driven by the stroke (and velocity, if given) and command of ``--record``."""
    data, unit = read_record_columns(args, args.record, ("t", "x", "command"))
    if unit != damper.command.unit:
        raise ValueError(f"--record {args.record}: its command is in {unit} but the damper's is in "
                         f"{damper.command.unit}")
    t = data["t"]
    dt = (t[-1] - t[0]) / (len(t) - 1)
    if np.abs(t - (t[0] + dt * np.arange(len(t)))).max() > 0.5 * dt:
        raise ValueError(f"--record {args.record}: the time column is not uniformly sampled (resample it first)")
    return simulate(damper, data["x"], data["command"], dt, data.get("v"), labels=["record"])[0]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--damper", "--model", dest="model", default="spencer_dyke",
                   help=f"damper model, one of {available_dampers()}, or a preset file (fitted.json); --model is "
                        "the same option under its former name")
    p.add_argument("--preset", default=None,
                   help="parameter preset of the model (default: the model's default), or a preset file written by "
                        "mrd-env identify --save-preset")
    p.add_argument("--amplitude", type=float, default=0.015, help="stroke amplitude X in m (default 0.015)")
    p.add_argument("--frequency", type=float, default=2.5, help="frequency in Hz (default 2.5)")
    p.add_argument("--commands", type=float, nargs="+", default=None,
                   help="command levels in V or A (default: 4 levels across the preset's range)")
    p.add_argument("--cycles", type=float, default=3.0, help="cycles simulated (the last one is plotted)")
    p.add_argument("--dt", type=float, default=1e-3, help="time step in s (default 1e-3)")
    p.add_argument("--record", type=Path, default=None,
                   help="CSV to replay instead of a sinusoid: stroke and command over time (e.g. a file written by "
                        "mrd-env rig, or any CSV with --columns t=...,x=...,command=...[,v=...] and --units)")
    add_column_arguments(p)
    p.add_argument("--out", type=Path, default=Path("results/rig"), help="output folder")


def run(args: argparse.Namespace) -> int:
    from mrd_env.dampers import is_preset_file

    damper = make_damper(args.preset) if is_preset_file(args.preset) else make_damper(args.model, args.preset)
    c = damper.command
    if args.record is not None:
        results = [replay(damper, args)]
        last = None
    else:
        levels = args.commands if args.commands is not None else list(np.linspace(c.v_min, c.v_max, 4))
        results = sinusoidal_test(damper, args.amplitude, args.frequency, levels, cycles=args.cycles, dt=args.dt)
        last = results[0].steady_cycles(args.frequency)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    # a record's files are named after it, so that replaying a record never replaces the sinusoidal test's
    stem = damper.name if args.record is None else f"{damper.name}_{args.record.stem}"
    earlier = [p for p in out.glob(f"{stem}_*") if p.suffix in (".csv", ".md", ".png")]
    rows = []
    for r in results:
        sl = last or slice(None)
        name = (r.label or "record").replace(" ", "")
        r.to_csv(out / f"{stem}_{name}.csv")
        row = {"command": r.label, "F_max (N)": float(r.force[sl].max()), "F_min (N)": float(r.force[sl].min())}
        if last:
            row["energy per cycle (J)"] = r.dissipated_energy(sl)
        else:  # a record has no cycles: the energy it dissipated in all
            row["energy dissipated (J)"] = r.dissipated_energy(sl)
        rows.append(row)
    title = (f"{damper.name}: X = {args.amplitude * 1e3:g} mm, f = {args.frequency:g} Hz"
             if args.record is None else f"{damper.name}: record {args.record.name}")
    md, csv_path = write_table(rows, out / f"{stem}_summary", title=title, floatfmt=".1f")
    fig = plot_loops(results, out / f"{stem}_loops.png", last_cycles=last, title=title)
    print(md.read_text())
    if earlier:
        print(f"note: replaced {len(earlier)} file(s) of an earlier run in {out} (use --out to keep both)",
              file=sys.stderr)
    print(f"wrote {md}, {csv_path}, {fig} and {len(results)} record CSV(s) in {out}")
    return 0
