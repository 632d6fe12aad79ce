"""``mrd-env inverse``: inverse models of the damper — force-tracking tables and figures, and neural training.

    mrd-env inverse achievable                          # desired forces the damper can produce (random commands)
    mrd-env inverse record --data FILE --columns ... --units ... --fs 3004.8     # a measured record
    mrd-env inverse train --damper spencer_dyke --preset spencer1997 --out net.npz

``achievable``: for each plant model, a virtual-rig record under a random stroke and random commands
(:func:`mrd_env.inverse.achievable_forces`) gives the desired force; every inverse built on the plant's own
model tracks it in closed loop with the plant (a perfect inverse has zero error), and so does every inverse built
on another model (``--mismatch inverse_model:plant_model``, default Bouc–Wen inverses on the Spencer–Dyke plant).

``record``: the desired force is a measured force; the plant is the model fitted to the first ``--fit-fraction``
of the record (or ``--plant-preset``), the inverses are built on that model (the neural one is trained on the
fit part of the record itself, and/or on virtual-rig data of the fitted model), and E_t (review eq. 3) is
measured on the held-back rest. The row "measured command" is the plant driven by the command the test sent.

Tables are written as Markdown and CSV, figures as PNG (desired vs achieved force, commands, force–velocity loops).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mrd_env.dampers import DamperModel, available_dampers, is_preset_file, load_damper_preset, make_damper
from mrd_env.dampers.preset_file import NEURAL_MODEL, preset_model
from mrd_env.inverse import INVERSES, make_inverse, plot_tracking, track
from mrd_env.inverse.base import Inverse
from mrd_env.report import write_table

from ..common.fitting import add_data_arguments, number

DT = 1e-3


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    a = sub.add_parser("achievable", help="track desired forces the damper can produce (tables, figures)",
                       description="track desired forces the damper can produce (tables, figures)")
    a.add_argument("--plants", nargs="+", default=["spencer_dyke", "bouc_wen"],
                   help="plant dampers: model names, or preset files (fitted.json, mrd-env identify --save-preset)")
    a.add_argument("--preset", default="spencer1997",
                   help="preset of every damper given by model name (default spencer1997)")
    a.add_argument("--inverses", nargs="+", default=list(INVERSES), help=f"inverses, among {list(INVERSES)}")
    a.add_argument("--mismatch", nargs="*", default=["bouc_wen:spencer_dyke"],
                   help="extra pairs inverse_damper:plant_damper, each a model name or a preset file (default "
                        "bouc_wen:spencer_dyke)")
    a.add_argument("--duration", type=float, default=10.0, help="record length in s (default 10)")
    a.add_argument("--rms", type=float, default=0.004, help="stroke r.m.s. in m (default 0.004)")
    a.add_argument("--bandwidth", type=float, default=8.0, help="stroke bandwidth in Hz (default 8)")
    a.add_argument("--seed", type=number(int, lo=0), default=1, help="seed of the record (default 1)")
    a.add_argument("--network", type=Path, action="append", default=[],
                   help="a neural-inverse network file to use for its model (default: the shipped ones)")
    a.add_argument("--out", type=Path, default=Path("results/inverse/achievable"), help="output folder")


    r = sub.add_parser("record", help="track a measured force with a plant fitted to the record",
                       description="track a measured force with a plant fitted to the record")
    add_data_arguments(r)
    r.add_argument("--model", default="spencer_dyke",
                   help="the plant's damper model, fitted to the record: a model name (starting from its preset) or "
                        "a preset file (starting from its parameters)")
    r.add_argument("--plant-preset", type=Path, default=None,
                   help="use this fitted preset (JSON, mrd-env identify --save-preset) as the plant, without fitting")
    r.add_argument("--inverses", nargs="+", default=list(INVERSES), help=f"inverses, among {list(INVERSES)}")
    r.add_argument("--neural", nargs="+", default=["record", "rig"], choices=("record", "rig"),
                   help="neural inverses: trained on the record's fit part and/or on rig data of the fitted model")
    r.add_argument("--epochs", type=number(int, lo=1), default=30, help="neural training epochs (default 30)")
    r.add_argument("--plot-window", type=float, default=1.0, help="seconds shown over time (default 1)")
    r.add_argument("--out", type=Path, default=Path("results/inverse/record"), help="output folder")

    t = sub.add_parser("train", help="train a neural inverse and save it (.npz)",
                       description="train a neural inverse on virtual-rig data of a damper (or on measured records) "
                                   "and save it")
    t.add_argument("--damper", "--model", dest="model", default="spencer_dyke",
                   help=f"damper model, one of {available_dampers()}, or a preset file (fitted.json); --model: the "
                        "same option under its former name")
    t.add_argument("--preset", default=None, help="preset of a model given by name (default: the model's)")
    t.add_argument("--out", type=Path, required=True, help="network file to write (.npz)")
    t.add_argument("--dt", type=number(lo=0.0, hi=1.0, lo_open=True, unit="s"), default=DT,
                   help="control step in s (default 1e-3)")
    t.add_argument("--history", type=number(int, lo=1, hi=1000), default=8,
                   help="measurements in the input history (default 8)")
    t.add_argument("--hidden", type=number(int, lo=1, hi=4096), nargs="+", default=[64, 64],
                   help="hidden layer widths (default 64 64)")
    t.add_argument("--epochs", type=number(int, lo=1), default=30, help="training epochs (default 30)")
    t.add_argument("--records", type=number(int, lo=1), default=40, help="virtual-rig records (default 40)")
    t.add_argument("--duration", type=number(lo=0.0, lo_open=True, unit="s"), default=5.0,
                   help="seconds per record (default 5)")
    t.add_argument("--rms", type=float, nargs=2, default=[0.001, 0.006], metavar=("LO", "HI"),
                   help="stroke r.m.s. range in m (default 0.001 0.006)")
    t.add_argument("--bandwidth", type=float, nargs=2, default=[2.0, 15.0], metavar=("LO", "HI"),
                   help="stroke bandwidth range in Hz (default 2 15)")
    t.add_argument("--hold", type=float, nargs=2, default=[0.005, 0.1], metavar=("LO", "HI"),
                   help="mean command hold time range in s (default 0.005 0.1)")
    t.add_argument("--seed", type=number(int, lo=0), default=0, help="seed (default 0)")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    return {"achievable": run_achievable, "record": run_record, "train": run_train}[args.action](args)


# --- achievable forces ----------------------------------------------------------------------------------------

def _check_inverses(inverses) -> None:
    bad = sorted({i for i in inverses if i not in INVERSES})
    if bad:
        raise ValueError(f"--inverses: unknown inverse(s) {bad}; available: {list(INVERSES)}")


def _check_dampers(option: str, specs) -> None:
    """Every spec of ``option`` a model name or a preset file; the unknown names listed once."""
    bad = sorted({m for m in specs if not is_preset_file(m) and m not in available_dampers()})
    if bad:
        raise ValueError(f"{option}: unknown damper model(s) {bad}; available: {available_dampers()}, or a preset "
                         "file (fitted.json, mrd-env identify --save-preset)")


def preset_damper(path) -> DamperModel:
    """The parametric damper of a preset file; a neural forward model is refused: the inverses step the plant's
    model and (sid, model) invert it, which a network over a motion history does not offer."""
    if preset_model(path) == NEURAL_MODEL:
        raise ValueError(f"{path} holds a neural forward model; the inverses need a parametric damper model to "
                         "step as the plant and to invert (fit one: mrd-env identify --model spencer_dyke "
                         "--save-preset fitted.json)")
    return load_damper_preset(path)


def damper_of(spec: str, preset: str | None = None) -> DamperModel:
    """The damper that a model name (with ``preset``) or a preset file names."""
    return preset_damper(spec) if is_preset_file(spec) else make_damper(spec, preset)


def label_of(spec: str) -> str:
    """A damper spec as tables and file names show it: a model name, or a preset file's stem."""
    return Path(spec).stem if is_preset_file(spec) else spec


def _pairs(args) -> list[tuple[str, str]]:
    """(inverse damper, plant damper) of every block of the table, each a model name or a preset file."""
    pairs = [(m, m) for m in args.plants]
    for item in args.mismatch:
        parts = item.split(":")
        if len(parts) != 2 or not all(parts):
            raise ValueError(f"--mismatch: expected inverse_damper:plant_damper, got {item!r}")
        pairs.append((parts[0], parts[1]))
    _check_dampers("--plants", args.plants)
    _check_dampers("--mismatch", [m for pair in pairs[len(args.plants):] for m in pair])
    return pairs


def build_inverse(name: str, damper, dt: float, networks: dict):
    """``make_inverse(name, damper, dt=dt)``; the neural one with the network given for the model, if any; None
    for an inverse that does not apply to the damper (SID outside the Bouc–Wen family; the neural inverse when no
    network is given and none ships for the damper's parameters: a fitted damper needs one trained for it)."""
    from mrd_env.inverse.neural import shipped_network
    from mrd_env.inverse.sid import SID_MODELS

    if name == "sid" and damper.name not in SID_MODELS:
        return None
    options = {}
    if name == "neural":
        if damper.name in networks:
            options = {"network": networks[damper.name]}
        else:
            try:
                shipped_network(damper)
            except ValueError:
                print(f"note: no neural inverse for this {damper.name} damper (none ships for its parameters): train "
                      "one with mrd-env inverse train --damper <its preset file> and pass it with --network")
                return None
    return make_inverse(name, damper, dt=dt, **options)


def achievable_rows(pairs, inverses, *, preset: str, duration: float, rms: float, bandwidth: float, seed: int,
                    networks: dict | None = None, out: Path | None = None) -> list[dict]:
    """The tracking table of the ``achievable`` action (one row per inverse damper, plant and inverse; dampers are
    model names with ``preset``, or preset files), with one figure per pair when ``out`` is given."""
    from mrd_env.inverse import achievable_forces

    networks = networks or {}
    rows = []
    for inv_spec, plant_spec in pairs:
        plant = damper_of(plant_spec, preset)
        rec = achievable_forces(plant, duration=duration, dt=DT, rms=rms, bandwidth=bandwidth, rng=seed)
        inv_damper = damper_of(inv_spec, preset)
        results = {}
        for name in inverses:
            inv = build_inverse(name, inv_damper, DT, networks)
            if inv is None:
                continue
            r = track(inv, plant, rec.x, rec.v, rec.force, DT)
            results[name] = r
            rows.append({"plant": label_of(plant_spec), "inverse model": label_of(inv_spec), "inverse": name,
                         "NRMSE %": 100 * float(r.nrmse[0]), "E_t %": 100 * float(r.E_t[0]),
                         "µs per call": 1e6 * r.command_time})
        if out is not None and results:
            plot_tracking(results, out / f"achievable_{label_of(inv_spec)}_on_{label_of(plant_spec)}.png",
                          window=(1.0, 2.0), title=f"achievable forces: inverses on {label_of(inv_spec)}, plant "
                                                   f"{label_of(plant_spec)}")
    return rows


def run_achievable(args: argparse.Namespace) -> int:
    from mrd_env.inverse.neural import load_network
    from mrd_env.validation import check_scalar

    _check_inverses(args.inverses)
    pairs = _pairs(args)
    for m in dict.fromkeys(m for pair in pairs for m in pair):
        damper_of(m, args.preset)  # an unknown preset or a bad preset file fails here, before any run
    check_scalar("--duration", args.duration, 0.1, 3600.0, unit="s")
    check_scalar("--rms", args.rms, 0.0, 0.1, lo_open=True, unit="m")
    check_scalar("--bandwidth", args.bandwidth, 0.0, 100.0, lo_open=True, unit="Hz")
    networks = {}
    for path in args.network:
        net = load_network(path)
        networks[net.meta["model"]] = net
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    rows = achievable_rows(pairs, args.inverses, preset=args.preset, duration=args.duration, rms=args.rms,
                           bandwidth=args.bandwidth, seed=args.seed, networks=networks, out=out)
    md, _ = write_table(rows, out / "achievable", floatfmt=".3g",
                        title=f"achievable forces ({args.preset}, {args.duration:g} s, stroke {1e3 * args.rms:g} mm "
                              f"r.m.s. up to {args.bandwidth:g} Hz, seed {args.seed}): tracking errors")
    print(md.read_text())
    print(f"wrote {out}")
    return 0


# --- a measured record ----------------------------------------------------------------------------------------

def run_record(args: argparse.Namespace) -> int:
    from mrd_env.identification import fit_model, save_preset
    from mrd_env.identification.compare import split_records
    from mrd_env.identification.prepare import prepare_record
    from mrd_env.inverse.training import train_neural_inverse

    from ..common.fitting import free_with_command, grid_dt, load_data, options

    _check_inverses(args.inverses)
    _check_dampers("--model", [args.model])
    plant = preset_damper(args.plant_preset) if args.plant_preset is not None else None
    if getattr(args, "validate", None):
        raise ValueError("--validate: inverse record tracks the held-back part of its one record; cross-record "
                         "validation belongs to identify and compare-models")
    recs = load_data(args)
    if len(recs) != 1:
        raise ValueError(f"--data: inverse record takes one record, got {len(recs)}")
    rec = recs[0]
    dt = grid_dt(args, rec)
    whole, fits, idx = split_records([rec], args.fit_fraction, dt, args.faults)
    r, k = whole[0], idx[0]
    dt = r.dt if dt is None else dt
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    search, data = options(args, dt)
    offset = data.offset or 0  # a given plant: the force offset given (auto finds none without a fit)
    if plant is None:
        start = damper_of(args.model) if is_preset_file(args.model) else args.model  # a file: from its values
        fr = fit_model(start, fits, search=search, data=data, free=free_with_command(args, args.model, None))
        plant = fr.damper
        offset = fr.settings["offsets"][0]
        save_preset(fr, out / f"plant_{label_of(args.model)}.json")
    # the target as the plant was fitted to it: the force moved by the offset, its faults left out of the scores
    prep = prepare_record(r, plant.command, dt=dt, command_range="clip", faults=args.faults, offset=offset)
    x, v, f = r.x[k:], r.velocity()[k:], prep.series.force[k:]
    scored = prep.mask[k:]
    cmd = np.clip(r.command[k:], plant.command.v_min, plant.command.v_max)
    t = r.t[k:] - r.t[k]  # the held-back part, from 0
    results, rows = {}, []

    def add(label, res):
        results[label] = res
        rows.append({"inverse": label, "E_t %": 100 * float(res.E_t[0]), "NRMSE %": 100 * float(res.nrmse[0]),
                     "µs per call": 1e6 * res.command_time})

    add("measured command", track(RecordedCommand(plant, cmd, dt=dt), plant, x, v, f, dt, scored=scored))
    for name in args.inverses:
        if name == "neural":
            for source in args.neural:
                net = train_neural_inverse(plant, fits if source == "record" else None, dt=dt, epochs=args.epochs,
                                           seed=args.seed, progress=not args.no_progress,
                                           **rig_like(fits[0], dt))
                net.save(out / f"neural_{source}.npz")
                add(f"neural ({source} data)", track(make_inverse("neural", plant, dt=dt, network=net), plant, x, v,
                                                     f, dt, scored=scored))
            continue
        inv = build_inverse(name, plant, dt, {})
        if inv is not None:
            add(name, track(inv, plant, x, v, f, dt, scored=scored))
    title = (f"{r.label}: plant {plant.name} fitted on the first {100 * args.fit_fraction:g} %, tracking of the "
             f"measured force on the held-back {t[-1]:.2f} s")
    md, _ = write_table(rows, out / "record_tracking", title=title, floatfmt=".4g")
    window = (0.0, min(args.plot_window, float(t[-1])))  # time from the start of the held-back part
    plot_tracking(results, out / "record_tracking.png", window=window, title=title)
    print(md.read_text())
    print(f"wrote {out}")
    return 0


def rig_like(record, dt: float) -> dict:
    """Virtual-rig settings resembling a measured record, for a neural inverse trained on its fitted model: 15
    records of 4 s, stroke r.m.s. from half to 1.5 times the record's, bandwidth from half to all of the frequency
    below which 99 % of its stroke's power lies, command hold times from 5 ms to twice the record's mean."""
    from scipy.signal import welch

    f, P = welch(record.x - np.mean(record.x), fs=1.0 / dt, nperseg=min(8192, record.n))
    f99 = float(f[np.searchsorted(np.cumsum(P) / np.sum(P), 0.99)])
    sx = float(np.std(record.x))
    cmd = record.command
    # a switch: a step of more than a tenth of the span (a measured command is noisy from sample to sample)
    switches = max(int(np.count_nonzero(np.abs(np.diff(cmd)) > 0.1 * (cmd.max() - cmd.min()))), 1)
    hold = record.duration / switches
    return {"n_records": 15, "duration": 4.0, "rms": (0.5 * sx, 1.5 * sx), "bandwidth": (0.5 * f99, f99),
            "mean_hold": (0.005, max(0.005, 2.0 * hold))}


class RecordedCommand(Inverse):
    """Not an inverse: the commands a test sent, replayed one per call (the plant's own error as a baseline)."""

    name = "measured command"

    def __init__(self, damper, commands, *, dt: float):
        super().__init__(damper, dt=dt)
        self.commands = np.asarray(commands, dtype=np.float64)

    def _start(self, rows, x, v, f_measured):
        self.k = 0

    def _command(self, f_desired, x, v, f_measured):
        self.k += 1
        return self.commands[self.k - 1:self.k]


# --- training -----------------------------------------------------------------------------------------------------

def run_train(args: argparse.Namespace) -> int:
    from mrd_env.inverse.training import train_neural_inverse

    _check_dampers("--damper", [args.model])
    damper = damper_of(args.model, args.preset)
    for name, lohi in (("--rms", args.rms), ("--bandwidth", args.bandwidth), ("--hold", args.hold)):
        if not (np.all(np.isfinite(lohi)) and 0 < lohi[0] <= lohi[1]):
            raise ValueError(f"{name} must be a range LO HI with 0 < LO <= HI, got {lohi}")
    if args.out.is_dir():
        raise ValueError(f"--out {args.out} is a folder; give a file name (.npz)")
    model = [f"--model {args.model}"] + ([] if is_preset_file(args.model)
                                         else [f"--preset {args.preset or type(damper).default_preset}"])
    reproduce = ("mrd-env inverse train " + " ".join([
        *model, f"--dt {args.dt:g}", f"--history {args.history}",
        "--hidden " + " ".join(map(str, args.hidden)), f"--epochs {args.epochs}", f"--records {args.records}",
        f"--duration {args.duration:g}", f"--rms {args.rms[0]:g} {args.rms[1]:g}",
        f"--bandwidth {args.bandwidth[0]:g} {args.bandwidth[1]:g}", f"--hold {args.hold[0]:g} {args.hold[1]:g}",
        f"--seed {args.seed}", f"--out {args.out}"]))
    net = train_neural_inverse(damper, dt=args.dt, history=args.history, hidden=args.hidden, epochs=args.epochs,
                               seed=args.seed, n_records=args.records, duration=args.duration,
                               rms=tuple(args.rms), bandwidth=tuple(args.bandwidth), mean_hold=tuple(args.hold),
                               reproduce=reproduce, progress=not args.no_progress)
    path = net.save(args.out)
    print(f"validation RMS of the scaled target {net.meta['validation_rms_u']:.4f}, {net.meta['n_samples']} "
          f"samples, {net.meta['wall_time_s']:.1f} s; wrote {path}")
    print(f"reproduce: {reproduce}")
    return 0
