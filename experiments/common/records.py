"""Command-line options for reading a user's record: ``--columns`` and ``--units`` (shared by ``rig``,
``identify`` and ``compare-models``), read through :func:`mrd_env.records.read_columns`."""
from __future__ import annotations

import argparse
from pathlib import Path

from mrd_env.records import own_columns, read_columns

ACCEPTED_UNITS = "t s|ms, x m|cm|mm, v m/s|cm/s|mm/s, force N|kN, command V|mV|A|mA"


def parse_pairs(text: str, what: str) -> dict[str, str]:
    """``"a=b,c=d"`` → {"a": "b", "c": "d"}; ``ValueError`` naming the option otherwise."""
    out = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        if "=" not in item:
            raise ValueError(f"{what}: expected role=value pairs separated by commas, got {item!r}")
        k, v = (s.strip() for s in item.split("=", 1))
        out[k] = v
    return out


def add_column_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--columns", default=None,
                   help="roles to header names, e.g. t=t,x=D,command=Y,force=F,v=V (v optional; default: the "
                        "SI header of files written by mrd-env: t_s, x_m, v_m_per_s, command_V/A, force_N)")
    p.add_argument("--units", default=None,
                   help=f"unit of each chosen column, e.g. t=s,x=cm,command=V,force=N,v=cm/s (required with "
                        f"--columns; accepted: {ACCEPTED_UNITS})")


def columns_and_units(args: argparse.Namespace, path: Path, required: tuple[str, ...]):
    """The column mapping and units from ``--columns``/``--units``, or the file's own SI header."""
    if args.columns is None:
        if args.units is not None:
            raise ValueError("--units needs --columns")
        return own_columns(path, required)
    if args.units is None:
        raise ValueError("--columns needs --units (every column's unit must be declared)")
    return parse_pairs(args.columns, "--columns"), parse_pairs(args.units, "--units")


def read_record_columns(args: argparse.Namespace, path: Path, required: tuple[str, ...]) -> tuple[dict, str]:
    """({role: SI array}, command unit) of the file at ``path``."""
    columns, units = columns_and_units(args, path, required)
    data = read_columns(path, columns, units, required=required)
    return data, {"mV": "V", "mA": "A"}.get(units["command"], units["command"])
