"""Virtual damper test rig: drive any damper model with a prescribed stroke and command.

Sinusoidal tests (the review's section 4 sinusoidal tester), band-limited random tests, and a user's own
displacement/command record. Several records (e.g. one per command level) run as one vectorised batch
through the shared stepping routine :func:`mrd_env.stepping.run`. Every test returns damper records
(:class:`~mrd_env.records.DamperRecord`, the container of a measured record too) with the rig's extras: the
effective command ``u`` after the coil lag and the damper's ``model`` name.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .command_lag import effective_command
from .dampers import DamperModel, make_damper
from .records import DamperRecord
from .stepping import SystemMatrices, run
from .resources import check as check_memory, samples_text
from .validation import MIN_RECORD_SAMPLES, as_generator, check_array, check_n_samples, check_scalar


#: Bytes per sample and record while a test runs (stroke, velocity, acceleration, command, the integrator's inputs
#: and forces, the records; measured: 165–181).
SAMPLE_BYTES = 200


def _check_test_memory(n_samples: float, n_records: int, dt: float, cause: str) -> None:
    """``ValueError`` naming ``cause`` if a test of ``n_records`` records of ``n_samples`` exceeds the memory limit
    (:mod:`mrd_env.resources`)."""
    check_memory({f"{n_records} record{'s' if n_records > 1 else ''} of {samples_text(n_samples, dt)}":
                  n_records * n_samples * SAMPLE_BYTES}, cause)


def _as_damper(damper: DamperModel | str) -> DamperModel:
    if isinstance(damper, str):
        return make_damper(damper)
    if not isinstance(damper, DamperModel):
        raise ValueError(f"damper must be a model name or a DamperModel, got {type(damper).__name__}")
    return damper


def check_test_step(dt, damper: DamperModel, f_max: float, what: str) -> float:
    """``dt`` (s) if it resolves a test: finite, > 0, at least 10 samples per period of the highest excitation
    frequency ``f_max`` (Hz) and no longer than the command lag's time constant 1/η."""
    dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    if f_max * dt > 0.1:
        raise ValueError(f"dt = {dt:g} s cannot resolve {what} ({f_max:g} Hz): need at least 10 samples per cycle, "
                         f"dt <= {0.1 / f_max:g} s")
    c = damper.command
    lag = 1.0 / max(c.eta, c.eta_down)
    if dt > lag:
        raise ValueError(f"dt = {dt:g} s cannot resolve the damper's command lag: must be <= 1/eta = {lag:g} s "
                         "(the faster of the rise and fall rates)")
    return dt


def simulate(damper: DamperModel | str, x: np.ndarray, command: np.ndarray, dt: float = 1e-3,
             v: np.ndarray | None = None, a: np.ndarray | None = None, *, labels=None,
             **integrator_options) -> list[DamperRecord]:
    """Drive ``damper`` with strokes ``x`` (m) and commands ``command`` sampled every ``dt`` seconds.

    ``x`` and ``command`` are 1-D (one record) or 2-D (records × samples, run as one batch). Velocity ``v``
    and acceleration ``a`` default to second-order finite differences of ``x`` (``numpy.gradient``); give
    them when known exactly. The command at sample k is held until sample k+1; all states start at rest.
    """
    damper = _as_damper(damper)
    dt = check_scalar("dt", dt, 0.0, lo_open=True, unit="s")
    x2 = check_array("x", x)
    if x2.ndim > 2:
        raise ValueError(f"x must be 1-D (one record) or 2-D (records × samples), got shape {x2.shape}")
    x2 = np.atleast_2d(x2)
    n_rec, n = x2.shape
    if n < MIN_RECORD_SAMPLES or n_rec < 1:
        raise ValueError(f"x must hold at least one record of at least {MIN_RECORD_SAMPLES} samples, got shape "
                         f"{x2.shape}")
    c2 = np.atleast_2d(check_array("command", command))
    if c2.ndim == 2 and c2.shape[1] == 1:
        c2 = np.repeat(c2, n, axis=1)
    if c2.ndim == 2 and c2.shape == (1, n):
        c2 = np.repeat(c2, n_rec, axis=0)
    if c2.shape != (n_rec, n):
        raise ValueError(f"command must have shape {(n_rec, n)} (or be one value per record), got {c2.shape}")
    damper.command.check_command(c2)
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is reported below, by name
        v2 = np.gradient(x2, dt, axis=1) if v is None else np.atleast_2d(check_array("v", v, shape=None))
        a2 = np.gradient(v2, dt, axis=1) if a is None else np.atleast_2d(check_array("a", a))
    for name, arr in (("v", v2), ("a", a2)):
        if arr.shape != (n_rec, n):
            raise ValueError(f"{name} must have the shape of x {(n_rec, n)}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"the finite-difference {name} of x overflows float64 with dt = {dt:g} s: "
                             f"check x (peak {np.abs(x2).max():g} m) and dt, or give {name}")
    W = np.ascontiguousarray(np.stack([x2, v2, a2], axis=2))
    Y = np.tile(damper.initial_state(), (n_rec, 1))
    U = c2[:, :1].copy()  # the effective command starts at the first command (the rig was settled)
    V = np.ascontiguousarray(c2[:, :-1, None])
    F, _, _ = run(damper, SystemMatrices.displacement_driven(), Y, U, V, W, dt, **integrator_options)
    # force at t0 from the rest state (switched to the initial motion), then the integrator's end-of-step forces
    F0 = damper.force(x2[:, 0], v2[:, 0], c2[:, 0], a=a2[:, 0])
    force = np.concatenate([F0[:, None], F[:, :, 0]], axis=1)
    u = np.array([effective_command(damper.command, c, dt) for c in c2])
    t = np.arange(n) * dt
    labels = labels or [""] * n_rec
    return [DamperRecord(t, x2[i], c2[i], force[i], v2[i], damper.command.unit, labels[i], u=u[i],
                         model=damper.name) for i in range(n_rec)]


def sinusoidal_test(damper: DamperModel | str, amplitude: float, frequency: float, commands=(0.0,), *,
                    cycles: float = 3.0, dt: float = 1e-3, **integrator_options) -> list[DamperRecord]:
    """x = X sin(2π f t) at constant command levels, one record per level (review section 4)."""
    damper = _as_damper(damper)
    X = check_scalar("amplitude", amplitude, 0.0, lo_open=True, unit="m")
    f = check_scalar("frequency", frequency, 0.0, lo_open=True, unit="Hz")
    cycles = check_scalar("cycles", cycles, 0.0, lo_open=True)
    dt = check_test_step(dt, damper, f, "the excitation frequency")
    cmds = np.atleast_1d(check_array("commands", commands))
    if cmds.ndim != 1 or cmds.size == 0:
        raise ValueError(f"commands must be one command level or a 1-D list of them, got shape {cmds.shape}")
    # divided in turn: f·dt may underflow to 0
    steps = check_n_samples(cycles / f / dt, f"cycles / (frequency · dt) = {cycles:g} / ({f:g} Hz · {dt:g} s)")
    if steps < 1.5:
        raise ValueError(f"cycles = {cycles:g} at {f:g} Hz lasts less than two steps dt = {dt:g} s: "
                         "give more cycles or a smaller dt")
    n = int(round(steps)) + 1
    _check_test_memory(n, len(cmds), dt, f"cycles={cycles:g} at frequency={f:g} Hz, dt={dt:g} s and "
                                         f"{len(cmds)} command level{'s' if len(cmds) > 1 else ''}")
    t = np.arange(n) * dt
    w = 2.0 * np.pi * f
    x = np.tile(X * np.sin(w * t), (len(cmds), 1))
    v = np.tile(X * w * np.cos(w * t), (len(cmds), 1))
    a = np.tile(-X * w * w * np.sin(w * t), (len(cmds), 1))
    labels = [f"{c:g} {damper.command.unit}" for c in cmds]
    return simulate(damper, x, cmds[:, None] * np.ones((1, n)), dt, v, a, labels=labels, **integrator_options)


def random_test(damper: DamperModel | str, rms: float, bandwidth: float, duration: float, *, command=None,
                switch_rate: float = 0.0, dt: float = 1e-3, rng=None, **integrator_options) -> DamperRecord:
    """Band-limited random stroke (Gaussian, flat spectrum up to ``bandwidth`` Hz, scaled to ``rms`` m).

    ``command``: a constant level, or None with ``switch_rate`` > 0 for a command switched at random
    between the preset's minimum and maximum (Poisson switching, mean rate in Hz) — the random tests of
    the Spencer/Dyke characterisation. ``rng``: a ``numpy.random.Generator`` or a seed.
    """
    damper = _as_damper(damper)
    rng = as_generator(rng)
    rms = check_scalar("rms", rms, 0.0, lo_open=True, unit="m")
    bw = check_scalar("bandwidth", bandwidth, 0.0, lo_open=True, unit="Hz")
    dt = check_test_step(dt, damper, bw, "the stroke's bandwidth")
    duration = check_scalar("duration", duration, 2 * dt, unit="s")
    n = int(round(check_n_samples(duration / dt, f"duration / dt = {duration:g} s / {dt:g} s"))) + 1
    if bw * n * dt < 1.0:  # the lowest non-zero frequency of the record is 1 / (n dt)
        raise ValueError(f"bandwidth = {bw:g} Hz is below the record's frequency resolution 1/duration = "
                         f"{1 / (n * dt):g} Hz, so the stroke would be empty: raise bandwidth or duration")
    _check_test_memory(n, 1, dt, f"duration={duration:g} s at dt={dt:g} s")
    spec = np.fft.rfft(rng.standard_normal(n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[(freqs > bw) | (freqs == 0.0)] = 0.0
    spec *= rms / np.sqrt(np.mean(np.fft.irfft(spec, n) ** 2))
    x = np.fft.irfft(spec, n)
    v = np.fft.irfft(spec * 2j * np.pi * freqs, n)  # exact derivative of the band-limited signal
    a = np.fft.irfft(spec * (2j * np.pi * freqs) ** 2, n)
    c = damper.command
    if command is not None:
        cmd = np.full(n, check_scalar("command", command, c.v_min, c.v_max, unit=c.unit))
    else:
        rate = check_scalar("switch_rate", switch_rate, 0.0, 0.1 / dt, lo_open=True, unit="Hz")
        flips = rng.random(n) < rate * dt
        cmd = np.where(np.cumsum(flips) % 2 == 0, c.v_min, c.v_max)
    return simulate(damper, x, cmd, dt, v, a, labels=["random"], **integrator_options)[0]


def plot_loops(results: list[DamperRecord], path: str | Path, *, last_cycles: slice | None = None,
               title: str = "") -> Path:
    """Force–displacement and force–velocity loops of several records on one figure (review Figs. 2, 5)."""
    from .report import figure, save_figure

    fig, (ax1, ax2) = figure(1, 2, figsize=(10, 4.2))
    for r in results:
        sl = last_cycles or slice(None)
        ax1.plot(r.x[sl] * 1e3, r.force[sl] / 1e3, label=r.label or r.model)
        ax2.plot(r.velocity()[sl], r.force[sl] / 1e3, label=r.label or r.model)
    ax1.set_xlabel("displacement x (mm)")
    ax2.set_xlabel("velocity ẋ (m/s)")
    for ax in (ax1, ax2):
        ax.set_ylabel("force F (kN)")
        ax.grid(True, alpha=0.3)
    ax2.legend(title="command", fontsize=8)
    fig.suptitle(title or f"{results[0].model}: force–displacement and force–velocity loops")
    return save_figure(fig, path, dpi=130)
