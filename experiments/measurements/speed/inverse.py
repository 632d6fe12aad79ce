"""Speed of the inverse models (a script, not a test): µs per ``command`` call.

    python -m experiments.measurements.speed.inverse [--model spencer_dyke] [--repeats 5] [--out results/inverse]

Each inverse is built for the model's ``spencer1997`` preset and called along a 2 s achievable-force record
(virtual rig, random stroke and commands), one call per 1 ms step as in a control loop, for a batch of N = 1 and
N = 64 dampers; the figure is the median over ``--repeats`` passes of the mean time per call (whole batch), the
passes of all inverses interleaved (the machine is shared). For the neural inverse the same network's forward pass
in torch (float64, ``torch.no_grad``, one thread) on one input row is timed too: the cost that exporting the
weights to compiled numpy code avoids.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from mrd_env import make_damper
from mrd_env.inverse import achievable_forces, make_inverse
from mrd_env.report import write_table
from mrd_env.stepping.first_use import set_mode

INVERSES = {"heaviside (on–off)": ("heaviside", {}), "heaviside (continuous)": ("heaviside", {"gain": 2e-3}),
            "sid": ("sid", {}), "model": ("model", {}), "neural": ("neural", {})}


def time_calls(inv, rec, N: int) -> float:
    """Mean seconds per ``command`` call along the record for a batch of N identical dampers."""
    inv.reset()
    fd, x, v, f = (np.ascontiguousarray(np.repeat(a[:, None], N, axis=1)) for a in
                   (rec.force[1:], rec.x[:-1], rec.v[:-1], rec.force[:-1]))
    t0 = time.perf_counter()
    for k in range(fd.shape[0]):
        inv.command(fd[k], x[k], v[k], f[k])
    return (time.perf_counter() - t0) / fd.shape[0]


def torch_forward_time(net, calls: int = 2000) -> float:
    """Seconds per torch forward pass of ``net`` on one input row (the torch-inference alternative)."""
    import torch

    torch.set_num_threads(1)
    model = net.to_torch()
    row = np.random.default_rng(0).normal(size=net.n_inputs)
    with torch.no_grad():
        for _ in range(100):
            model(torch.from_numpy(row)[None])
        t0 = time.perf_counter()
        for _ in range(calls):
            float(model(torch.from_numpy(row)[None])[0, 0])
    return (time.perf_counter() - t0) / calls


def main(argv=None) -> int:
    set_mode("wait")  # time the compiled kernel, never the interpreted one of a first use
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default="spencer_dyke", choices=("spencer_dyke", "bouc_wen"))
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=Path("results/inverse"))
    args = p.parse_args(argv)
    d = make_damper(args.model, "spencer1997")
    rec = achievable_forces(d, duration=2.0, rng=2)
    invs = {label: make_inverse(name, d, **opts) for label, (name, opts) in INVERSES.items()}
    for inv in invs.values():  # compile / load every kernel before timing
        time_calls(inv, rec, 1)
        time_calls(inv, rec, 64)
    times = {(label, N): [] for label in invs for N in (1, 64)}
    for _ in range(args.repeats):
        for label, inv in invs.items():
            for N in (1, 64):
                times[label, N].append(time_calls(inv, rec, N))
    rows = [{"inverse": label, "µs per call, N = 1": 1e6 * float(np.median(times[label, 1])),
             "µs per call, N = 64": 1e6 * float(np.median(times[label, 64])),
             "µs per damper, N = 64": 1e6 * float(np.median(times[label, 64])) / 64} for label in invs]
    try:
        t_torch = torch_forward_time(invs["neural"].network)
        rows.append({"inverse": "neural: torch forward pass only (1 row)", "µs per call, N = 1": 1e6 * t_torch,
                     "µs per call, N = 64": float("nan"), "µs per damper, N = 64": float("nan")})
    except ImportError:
        pass
    md, _ = write_table(rows, args.out / f"bench_inverse_{args.model}", floatfmt=".3g",
                        title=f"µs per command call ({args.model}, spencer1997; median of {args.repeats} passes "
                              "of 2 s at 1 kHz)")
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
