"""Force tracking, measured: an inverse in closed loop with a damper along a motion record.

At each sample t_k the inverse gets the desired force of the next sample f_d(t_{k+1}), the measured motion
x(t_k), ẋ(t_k) and the damper's force f(t_k); its command is held over [t_k, t_{k+1}] while the damper — any
:class:`~mrd_env.dampers.DamperModel`, the "plant", stepped by the project's stepping routine
(:class:`~mrd_env.stepping.Stepper`) on the rig — follows the motion. The tracking error is scored from the
second sample on (the first cannot be commanded):

* NRMSE = sqrt(mean (f − f_d)²) / sqrt(mean f_d²) (the project's normalised RMS error), and
* E_t, the review's eq. (3) with the desired force in the place of the measured one
  (:func:`mrd_env.identification.measures.error_time`: the RMS error over the RMS deviation of f_d from its
  mean).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..identification.measures import error_measures, error_time
from ..stepping import Stepper, SystemMatrices
from ..validation import check_array, check_scalar
from .base import Inverse, as_damper

_RIG = SystemMatrices.displacement_driven()


def nrmse(f, f_ref) -> float:
    """sqrt(mean (f − f_ref)²) / sqrt(mean f_ref²)."""
    f, f_ref = np.asarray(f, dtype=np.float64), np.asarray(f_ref, dtype=np.float64)
    return float(np.sqrt(np.mean((f - f_ref) ** 2)) / np.sqrt(np.mean(f_ref ** 2)))


@dataclass(frozen=True)
class TrackingResult:
    """Closed-loop tracking of N records (arrays (N, n), SI): the desired and achieved forces (N), the commands
    (held from each sample to the next; the last repeats the one before), the errors per record from the second
    sample on, and the mean wall time of one ``command`` call (s, for the whole batch); ``command_unit`` is the
    plant's (V or A)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    f_desired: np.ndarray
    force: np.ndarray
    command: np.ndarray
    nrmse: np.ndarray
    E_t: np.ndarray
    command_time: float
    inverse: str
    plant: str
    command_unit: str = ""


def _records(name: str, value, shape: tuple[int, int] | None = None) -> np.ndarray:
    a = check_array(name, value)
    if a.ndim not in (1, 2):
        raise ValueError(f"{name} must be 1-D (one record) or 2-D (records × samples), got shape {a.shape}")
    a = np.atleast_2d(a)
    if shape is not None and a.shape != shape:
        raise ValueError(f"{name} must have the shape of x {shape}, got {a.shape}")
    return a


def track(inverse: Inverse, damper, x, v, f_desired, dt: float, *, u0: float | None = None, scored=None,
          **integrator_options) -> TrackingResult:
    """Run ``inverse`` in closed loop with the plant ``damper`` along the motion ``x`` (m), ``v`` (m/s) sampled
    every ``dt`` (s), asking for ``f_desired`` (N); 1-D arrays (one record) or 2-D (records × samples, one batch
    of the inverse). The plant starts at rest with the effective command ``u0`` (default v_min); the inverse is
    reset first. ``scored`` (a bool per sample, like ``x``): the samples the errors are computed on (default: every
    one from the second; a measured record's faults, say, left out). ``integrator_options`` (``max_substeps``,
    ``rtol``, ``atol``) go to the plant's stepping."""
    if not isinstance(inverse, Inverse):
        raise ValueError(f"inverse must be an Inverse (see make_inverse), got {type(inverse).__name__}")
    damper = as_damper(damper)
    dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    if abs(dt - inverse.dt) > 1e-9 * dt:
        raise ValueError(f"dt = {dt:g} s differs from the inverse's control step {inverse.dt:g} s")
    if damper.command.unit != inverse.damper.command.unit:
        raise ValueError(f"the plant's command is in {damper.command.unit} but the inverse's in "
                         f"{inverse.damper.command.unit}")
    X = _records("x", x)
    N, n = X.shape
    if n < 3:
        raise ValueError(f"x must hold at least 3 samples per record, got {n}")
    V = _records("v", v, (N, n))
    Fd = _records("f_desired", f_desired, (N, n))
    c = damper.command
    u0 = c.v_min if u0 is None else check_scalar("u0", u0, c.v_min, c.v_max, unit=c.unit)
    A = np.gradient(V, dt, axis=1)
    W = np.ascontiguousarray(np.stack([X, V, A], axis=2))
    plant = Stepper(damper, _RIG, N, 1, dt, **integrator_options)
    plant.U = np.full((N, 1), u0)
    F = np.empty((N, n))
    F[:, 0] = damper.force(X[:, 0], V[:, 0], u0, a=A[:, 0])
    cmd = np.empty((N, n))
    inverse.reset()
    spent = 0.0
    for k in range(n - 1):
        t0 = time.perf_counter()
        cmd[:, k] = inverse.command(Fd[:, k + 1], X[:, k], V[:, k], f_measured=F[:, k])
        spent += time.perf_counter() - t0
        Fk, _ = plant.step(cmd[:, k, None, None], W[:, k:k + 2])
        F[:, k + 1] = Fk[:, 0, 0]
    cmd[:, -1] = cmd[:, -2]
    t = np.arange(n) * dt
    if scored is None:
        e_nrmse = np.array([nrmse(F[i, 1:], Fd[i, 1:]) for i in range(N)])
        e_t = np.array([error_time(Fd[i, 1:], F[i, 1:], t[1:]) for i in range(N)])
    else:
        M = np.broadcast_to(np.asarray(scored, dtype=bool), (N, n)) if np.ndim(scored) == 1 else \
            _records("scored", scored, (N, n)).astype(bool)
        e_nrmse = np.array([nrmse(F[i, 1:][M[i, 1:]], Fd[i, 1:][M[i, 1:]]) for i in range(N)])
        e_t = np.array([error_measures(Fd[i, 1:], F[i, 1:], t[1:], v=V[i, 1:], mask=M[i, 1:])["E_t"]
                        for i in range(N)])
    return TrackingResult(t, X, V, Fd, F, cmd, e_nrmse, e_t, spent / (n - 1), inverse.name, damper.name, c.unit)


def plot_tracking(results: dict[str, TrackingResult], path: str | Path, *, record: int = 0,
                  window: tuple[float, float] | None = None, title: str = "") -> Path:
    """Desired and achieved force over time, the commands, and the force–velocity loops of one record for
    several inverses (``{label: result}``) on one PNG figure (:func:`tracking_figure`); ``window`` (s) restricts
    the time span shown."""
    from ..report import save_figure

    return save_figure(tracking_figure(results, record=record, window=window, title=title), path, dpi=110)


def tracking_figure(results: dict[str, TrackingResult], *, record: int = 0,
                    window: tuple[float, float] | None = None, title: str = ""):
    """The matplotlib Figure of :func:`plot_tracking`; the command axis in the plant's command unit."""
    from ..report import figure

    fig, axes = figure(3, 1, figsize=(10, 9))
    first = next(iter(results.values()))
    t = first.t
    sl = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    axes[0].plot(t[sl], first.f_desired[record, sl] / 1e3, "k", lw=1.6, label="desired")
    axes[2].plot(first.v[record, sl], first.f_desired[record, sl] / 1e3, "k", lw=1.6, label="desired")
    for label, r in results.items():
        axes[0].plot(t[sl], r.force[record, sl] / 1e3, lw=0.8, label=f"{label} (NRMSE {100 * r.nrmse[record]:.1f} %)")
        axes[1].step(t[sl], r.command[record, sl], where="post", lw=0.8, label=label)
        axes[2].plot(r.v[record, sl], r.force[record, sl] / 1e3, lw=0.6, label=label)
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("force (kN)")
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel(f"command ({first.command_unit})" if first.command_unit else "command")
    axes[2].set_xlabel("velocity (m/s)")
    axes[2].set_ylabel("force (kN)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    axes[0].set_title(title or f"force tracking, plant {first.plant}")
    return fig
