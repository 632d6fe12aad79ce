"""Training of the neural inverse (:mod:`mrd_env.inverse.neural`) with torch, on virtual-rig data generated from
any damper model or on a user's measured records.

Each sample k of a record gives the network's input at t_k (the desired force is the force measured at
t_{k+1}; the histories end at t_k; û_k is the effective command, the command record passed through the lag) and
its target, the effective command at t_{k+1}. Rig data: ``n_records`` records of
:func:`~mrd_env.inverse.data.achievable_forces` whose stroke r.m.s., bandwidth and command hold time are drawn
log-uniformly from the given ranges, so that the network sees slow and fast strokes, small and large, and
commands switched often and seldom; and, from the state at every sample, three one-step :func:`branches` (other
commands tried for one step, the two ends with desired forces pushed past the reachable band). Without the
branches a network only ever sees desired forces one natural step away from the measured one; in closed loop a
tracking error takes it outside that set, where it has learnt nothing (in a trial without branches, H = 4,
an error ran away for 60 ms after a velocity reversal: NRMSE 14 % on a record where the same settings with
branches gave 1.7 %). Measured records have no model to branch from:
a network trained on them sees their own samples only.

The loss is the mean squared error of the scaled target; Adam with a cosine learning-rate decay; float64; one
torch thread; everything seeded (same seed, same network, bit for bit).
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Sequence

import numpy as np

from ..command_lag import effective_command
from ..validation import shown
from ..validation import as_generator, check_scalar
from .base import as_damper, lag_decay, writable_c
from .data import achievable_forces
from .neural import SCALES, Network, feature_matrix, n_inputs
from .observer import OneStep


def rig_records(damper, *, n_records: int = 40, duration: float = 5.0, dt: float = 1e-3,
                rms: tuple[float, float] = (0.001, 0.006), bandwidth: tuple[float, float] = (2.0, 15.0),
                mean_hold: tuple[float, float] = (0.005, 0.1), rng=None) -> list:
    """Virtual-rig training records (see the module docstring); ranges are (low, high), drawn log-uniformly."""
    damper = as_damper(damper)
    rng = as_generator(rng)

    def draw(name, lohi):
        lo, hi = (check_scalar(name, v, 0.0, lo_open=True) for v in lohi)
        if hi < lo:
            raise ValueError(f"{name} must be a range (low, high) with low <= high, got {lohi}")
        return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))

    out = []
    for _ in range(int(check_scalar("n_records", n_records, 1, 1e6))):
        bw = min(draw("bandwidth", bandwidth), 0.1 / dt)
        out.append(achievable_forces(damper, duration=duration, dt=dt, rms=draw("rms", rms), bandwidth=bw,
                                     mean_hold=max(draw("mean_hold", mean_hold), dt), rng=rng))
    return out


def branches(damper, records: Sequence, dt: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """One-step branches of rig records (all of one length n): (desired forces, effective commands at the end
    of the step), each (R, n − 1, 3), for three commands tried from the state at every sample k — one drawn
    uniformly from the range, v_min and v_max — along the record's true next motion. The two ends' desired
    forces are pushed beyond the force they reach, outwards, by a random fraction (exponential, mean 1/4) of
    the reachable band |F(v_max) − F(v_min)|: past either end of the band, the answer is that end (the clipped
    inverse). The states come from the damper model run along the record with its own commands
    (:class:`~mrd_env.inverse.observer.OneStep`)."""
    c = damper.command
    R, n = len(records), records[0].t.size
    x = np.array([r.x for r in records])
    v = np.array([r.v for r in records])
    u = np.array([r.u for r in records])
    cmd = np.array([r.command for r in records])
    obs = OneStep(damper, R, dt)
    obs.start(np.stack([x[:, 0], v[:, 0], np.zeros(R)], axis=1), u[:, 0])
    decay = lag_decay(c, dt)
    fd = np.empty((R, n - 1, 3))
    u_next = np.empty((R, n - 1, 3))
    V = np.empty((R, 3))
    V[:, 1], V[:, 2] = c.v_min, c.v_max
    for k in range(n - 1):
        V[:, 0] = rng.uniform(c.v_min, c.v_max, R)
        Fb = obs.step_forces(V, x[:, k + 1], v[:, k + 1])
        band = Fb[:, 2] - Fb[:, 1]
        push = rng.exponential(0.25, (R, 2)) * band[:, None]
        fd[:, k] = Fb
        fd[:, k, 1] -= push[:, 0]
        fd[:, k, 2] += push[:, 1]
        u_next[:, k] = V + (u[:, k, None] - V) * np.where(V > u[:, k, None], decay[0], decay[1])
        obs.advance(cmd[:, k], x[:, k + 1], v[:, k + 1])
    return fd, u_next


def features(records: Sequence, damper, history: int, dt: float, *, rng=None) -> tuple[np.ndarray, np.ndarray,
                                                                                             tuple]:
    """(inputs (M, 3H+2), scaled targets (M,), scales :data:`~mrd_env.inverse.neural.SCALES`) of the records
    (objects with t, x, v, command, force; a measured record's effective command is rebuilt through the damper's
    lag from its commands, starting at its first command). With ``rng`` (rig records of one length) the
    :func:`branches` are added to each record's own samples."""
    c = damper.command
    rows = []
    for i, r in enumerate(records):
        t = np.asarray(r.t, dtype=np.float64)
        step = np.diff(t)
        if t.size < history + 2 or np.abs(step - dt).max() > 1e-6 * dt:
            raise ValueError(f"records[{i}] must be sampled uniformly at dt = {dt:g} s with more than "
                             f"history + 1 = {history + 1} samples (resample it first)")
        v = np.asarray(r.v if getattr(r, "v", None) is not None else np.gradient(r.x, t), dtype=np.float64)
        cmd = np.clip(np.asarray(r.command, dtype=np.float64), c.v_min, c.v_max)
        # the effective command as the inverse models it: the lag without the pure delay
        u = (np.asarray(r.u, dtype=np.float64) if getattr(r, "u", None) is not None
             else effective_command(dataclasses.replace(c, delay=0.0), cmd, dt))
        # writable C arrays whatever the record (read-only, strided): one compiled variant of feature_matrix
        rows.append(tuple(writable_c(a) for a in (r.force, r.x, v, u)))

    def std(fn):
        return float(np.std(np.concatenate([fn(q) for q in rows])))

    scales = (std(lambda q: q[0]), std(lambda q: np.diff(q[0])), std(lambda q: q[1]), std(lambda q: q[2]),
              std(lambda q: np.diff(q[2])), std(lambda q: np.diff(q[3])))
    if not all(s > 0 for s in scales):
        raise ValueError("the records' force, stroke, velocity and effective command must vary (a zero standard "
                         f"deviation among {dict(zip(SCALES, scales))})")
    sc = np.array(scales)
    extra = branches(damper, records, dt, rng) if rng is not None else None
    Xs, ys = [], []
    for i, (F, x, v, u) in enumerate(rows):
        targets = [(F[1:], u[1:])]
        if extra is not None:
            targets += [(extra[0][i, :, j], extra[1][i, :, j]) for j in range(extra[0].shape[2])]
        for fd, u_next in targets:
            m = F.size - history
            X, y = np.empty((m, n_inputs(history))), np.empty(m)
            feature_matrix(F, x, v, u, writable_c(fd), writable_c(u_next),
                           history, sc, c.v_min, c.v_max, dt, X, y)
            Xs.append(X)
            ys.append(y)
    return np.vstack(Xs), np.concatenate(ys), scales


def train_neural_inverse(damper, records: Sequence | None = None, *, dt: float = 1e-3, history: int = 8,
                         hidden: Sequence[int] = (64, 64), epochs: int = 30, batch_size: int = 256,
                         learning_rate: float = 3e-3, seed: int = 0, n_records: int = 40, duration: float = 5.0,
                         rms: tuple[float, float] = (0.001, 0.006), bandwidth: tuple[float, float] = (2.0, 15.0),
                         mean_hold: tuple[float, float] = (0.005, 0.1), reproduce: str = "",
                         progress: bool = True) -> Network:
    """Train a neural inverse for ``damper`` (its model, parameters and command channel) at the control step
    ``dt``: on virtual-rig data from the damper itself (``records=None``; ``n_records``, ``duration``, ``rms``,
    ``bandwidth``, ``mean_hold`` as in :func:`rig_records`) or on the given measured records (DamperRecord or
    rig records sampled at ``dt``). ``reproduce``: the command that reproduces this network, kept in its
    metadata. Needs torch."""
    try:
        import torch
    except ImportError as exc:  # an optional dependency
        raise ImportError("training a neural inverse needs torch (pip install 'mrd-env[rl]')") from exc
    damper = as_damper(damper)
    dt = check_scalar("dt", dt, 0.0, 1.0, lo_open=True, unit="s")
    history = int(check_scalar("history", history, 1, 1000))
    hidden = [int(check_scalar("hidden", h, 1, 4096)) for h in hidden]
    epochs = int(check_scalar("epochs", epochs, 1, 1e6))
    batch_size = int(check_scalar("batch_size", batch_size, 1, 1e7))
    learning_rate = check_scalar("learning_rate", learning_rate, 0.0, 1.0, lo_open=True)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {shown(seed)}")
    rng = np.random.default_rng(seed)
    source = "virtual rig"
    if records is None:
        records = rig_records(damper, n_records=n_records, duration=duration, dt=dt, rms=rms, bandwidth=bandwidth,
                              mean_hold=mean_hold, rng=rng)
    else:
        source = ", ".join(getattr(r, "label", "") or f"record {i}" for i, r in enumerate(records))
    X, y, scales = features(records, damper, history, dt, rng=rng if source == "virtual rig" else None)
    perm = rng.permutation(X.shape[0])
    n_val = max(1, X.shape[0] // 10)
    val, tr = perm[:n_val], perm[n_val:]

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        torch.manual_seed(seed)
        sizes = [X.shape[1], *hidden, 1]
        layers = []
        for i in range(len(sizes) - 1):
            layers.append(torch.nn.Linear(sizes[i], sizes[i + 1]))
            if i < len(sizes) - 2:
                layers.append(torch.nn.Tanh())
        net = torch.nn.Sequential(*layers).double()
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
        steps = epochs * math.ceil(tr.size / batch_size)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=steps)
        Xt, yt = torch.from_numpy(X), torch.from_numpy(y)
        from tqdm.auto import tqdm

        t0 = time.perf_counter()
        bar = tqdm(range(epochs), desc=f"train neural inverse ({damper.name})", disable=not progress)
        for _ in bar:
            order = tr[rng.permutation(tr.size)]
            for s in range(0, order.size, batch_size):
                idx = torch.from_numpy(order[s:s + batch_size])
                loss = torch.mean((net(Xt[idx])[:, 0] - yt[idx]) ** 2)
                opt.zero_grad()
                loss.backward()
                opt.step()
                sched.step()
            with torch.no_grad():
                v_loss = float(torch.mean((net(Xt[val])[:, 0] - yt[val]) ** 2))
            bar.set_postfix_str(f"validation RMS {math.sqrt(v_loss):.4f}")
        with torch.no_grad():
            t_loss = float(torch.mean((net(Xt[tr])[:, 0] - yt[tr]) ** 2))
        linear = [m for m in net if isinstance(m, torch.nn.Linear)]
        weights = tuple(m.weight.detach().numpy().astype(np.float64).copy() for m in linear)
        biases = tuple(m.bias.detach().numpy().astype(np.float64).copy() for m in linear)
        wall = time.perf_counter() - t0
    finally:
        torch.set_num_threads(threads)
    c = damper.command
    meta = {"model": damper.name, "parameters": damper.params.to_dict(),
            "command": {"unit": c.unit, "v_min": c.v_min, "v_max": c.v_max, "eta": c.eta, "eta_fall": c.eta_down,
                         "delay": c.delay}, "dt": dt,
            "hidden": hidden, "source": source, "n_samples": int(X.shape[0]), "epochs": epochs,
            "batch_size": batch_size, "learning_rate": learning_rate, "seed": int(seed),
            "train_rms_u": math.sqrt(t_loss), "validation_rms_u": math.sqrt(v_loss), "wall_time_s": wall,
            "torch": torch.__version__, "reproduce": reproduce,
            "rig_data": None if source != "virtual rig" else {"n_records": n_records, "duration": duration,
                                                                "rms": list(rms), "bandwidth": list(bandwidth),
                                                                "mean_hold": list(mean_hold)}}
    return Network(weights, biases, history, scales, meta)
