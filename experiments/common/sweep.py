"""The sweep options every long command shares (``--backend``, ``--jobs``, ``--address``): see
:mod:`mrd_env.executor`."""
from __future__ import annotations

import argparse

from mrd_env.executor import BACKENDS


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("sweep (mrd_env.executor)")
    g.add_argument("--backend", choices=BACKENDS, default="auto",
                   help="serial, a local process pool, or Ray (default auto: the pool when it helps)")
    g.add_argument("--jobs", type=int, default=None, help="workers (default: the cores of this machine)")
    g.add_argument("--address", default=None,
                   help="Ray cluster address (e.g. ray://head:10001 or auto); default: a local Ray instance")


def options(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`mrd_env.executor.run_tasks`, checked."""
    if args.jobs is not None and args.jobs < 1:
        raise ValueError(f"--jobs must be >= 1, got {args.jobs}")
    if args.address is not None and args.backend != "ray":
        raise ValueError("--address is the address of a Ray cluster: add --backend ray")
    return {"backend": args.backend, "jobs": args.jobs, "address": args.address}
