"""Virtual-rig records for inverse models: random commands, and the forces a damper actually produces under them
("achievable" desired forces: a perfect inverse tracks them with zero error).

The stroke is the rig's band-limited random motion (:func:`mrd_env.rig.random_test`); the command is held at
random levels for random times — uniform levels in the command range, mixed with on–off switching between its
ends, as semi-active controllers command — so that every effective command, and every switching rate a
controller uses, appears.
"""
from __future__ import annotations

import numpy as np

from ..records import DamperRecord
from ..rig import random_test, simulate
from ..validation import as_generator, check_scalar
from .base import as_damper


def random_command(n: int, dt: float, command, rng, *, mean_hold: float = 0.03,
                   on_off_fraction: float = 0.3) -> np.ndarray:
    """n samples of a command held at random levels: hold times exponential with mean ``mean_hold`` (s); each
    new level is an end of [v_min, v_max] with probability ``on_off_fraction``, else uniform in the range.
    ``command`` is the damper's :class:`~mrd_env.dampers.CommandSpec`."""
    rng = as_generator(rng)
    mean_hold = check_scalar("mean_hold", mean_hold, dt, unit="s")
    on_off_fraction = check_scalar("on_off_fraction", on_off_fraction, 0.0, 1.0)
    out = np.empty(n)
    k = 0
    while k < n:
        hold = max(1, int(round(rng.exponential(mean_hold) / dt)))
        if rng.random() < on_off_fraction:
            level = command.v_max if rng.random() < 0.5 else command.v_min
        else:
            level = rng.uniform(command.v_min, command.v_max)
        out[k:k + hold] = level
        k += hold
    return out


def achievable_forces(damper, *, duration: float = 4.0, dt: float = 1e-3, rms: float = 0.004,
                      bandwidth: float = 8.0, mean_hold: float = 0.03, on_off_fraction: float = 0.3,
                      rng=None) -> DamperRecord:
    """The damper on the rig under a random stroke (``rms`` m, flat spectrum up to ``bandwidth`` Hz) and a
    :func:`random_command` (its first step at v_min), as a rig :class:`~mrd_env.records.DamperRecord`: its
    force is a desired force the damper can produce exactly."""
    damper = as_damper(damper)
    rng = as_generator(rng)
    motion = random_test(damper, rms, bandwidth, duration, command=damper.command.v_min, dt=dt, rng=rng)
    cmd = random_command(motion.t.size, dt, damper.command, rng, mean_hold=mean_hold,
                         on_off_fraction=on_off_fraction)
    cmd[0] = damper.command.v_min  # the rig starts at rest, switched off, as :func:`~mrd_env.inverse.track` does
    return simulate(damper, motion.x, cmd, dt, v=motion.v, labels=["achievable"])[0]
