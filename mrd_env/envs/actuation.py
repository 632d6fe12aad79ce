"""Force actuation: desired damper forces → commands, through an inverse model (:mod:`mrd_env.inverse`).

The piece an environment or a controller plugs in to act in forces rather than commands (an agent whose action
is a desired force, clipped-optimal control with any inverse): built from the environment, it knows the damper
model, the control step, the static preload and which sensors measure the damper's stroke, velocity and force
(``env.roles``), and keeps one inverse over the N environments × nd dampers of a batch::

    act = ForceActuation(env, inverse="model")        # or "heaviside", "sid", "neural", or an Inverse
    act.reset()                                       # at the start of an episode
    v = act.from_observation(f_desired, obs)          # (N, nd) commands for observations (N, n_obs)

``f_desired`` is the force wanted beyond the damper's static preload F_static (the force the plant's linear model
and the control laws see, e.g. clipped-optimal's f_c); measured forces are the sensor's, preload included.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..inverse import Inverse, make_inverse
from .sensors import newest_layout


class ForceActuation:
    """Desired forces (N, nd) → commands (N, nd) for the environment ``env`` (scalar or vector), with
    ``inverse`` a name of :func:`mrd_env.inverse.make_inverse` (``options`` go to it), a dict
    ``{"kind": name, **options}`` or an :class:`~mrd_env.inverse.Inverse` built for the env's damper and control
    step."""

    def __init__(self, env, inverse: str | Mapping | Inverse = "model", **options):
        if isinstance(inverse, Mapping):
            options = {**{k: v for k, v in inverse.items() if k != "kind"}, **options}
            inverse = inverse.get("kind", "model")
        base = getattr(env, "unwrapped", env)
        self.damper = base.damper
        self.dt = float(base.control_dt)
        self.n_dampers = int(base.n_dampers)
        self.f_static = float(getattr(base, "F_static", 0.0))
        if isinstance(inverse, Inverse):
            if options:
                raise ValueError(f"options {sorted(options)} apply to an inverse built by name, not to an instance")
            if abs(inverse.dt - self.dt) > 1e-9 * self.dt:
                raise ValueError(f"the inverse's control step dt = {inverse.dt:g} s differs from the environment's "
                                 f"control_dt = {self.dt:g} s")
            if inverse.damper.command != self.damper.command:
                raise ValueError("the inverse's command channel differs from the environment damper's "
                                 f"({inverse.damper.command} vs {self.damper.command})")
            self.inverse = inverse
        else:
            if inverse == "heaviside":  # the on–off law acts on the force beyond the preload, as clipped-optimal
                options = {"f_static": self.f_static, **options}
            self.inverse = make_inverse(inverse, self.damper, dt=self.dt, **options)
        roles = dict(getattr(base, "roles", {}))
        self.needs_motion = not (self.inverse.name == "heaviside")
        wanted = ["damper_force"] + (["damper_stroke", "damper_velocity"] if self.needs_motion else [])
        missing = [r for r in wanted if r not in roles]
        if missing:
            raise ValueError(f"the {self.inverse.name!r} inverse needs the damper's {missing}, which the environment "
                             f"does not declare (its roles: {roles})")
        self.sensors = {r: roles[r] for r in wanted}
        layout = newest_layout(base)
        absent = [s for s in self.sensors.values() if s not in layout]
        if absent:
            raise ValueError(f"the {self.inverse.name!r} inverse needs the sensor(s) {absent}, but the environment "
                             f"measures {list(layout)}; create it with sensors=(..., "
                             f"{', '.join(map(repr, absent))})")
        self._index = {r: np.arange(layout[s].start, layout[s].stop)[-self.n_dampers:] for r, s in self.sensors.items()}

    def reset(self, mask=None) -> None:
        """Forget the past: of every environment (the next call starts new episodes, of any batch size), or of
        the environments where ``mask`` (N,) is true."""
        self.inverse.reset(None if mask is None else np.repeat(np.asarray(mask, dtype=bool), self.n_dampers))

    def command(self, f_desired, force, stroke=None, velocity=None) -> np.ndarray:
        """Commands (N, nd) for desired forces beyond the preload ``f_desired`` (N) and the measured damper
        ``force`` (N, preload included), ``stroke`` (m) and ``velocity`` (m/s); arrays (N, nd), (N·nd,) or
        scalars."""
        fd = np.asarray(f_desired, dtype=np.float64)
        shape = np.broadcast_shapes(fd.shape, np.shape(force))
        n = max(int(np.prod(shape)), 1)
        x = np.zeros(n) if stroke is None else np.broadcast_to(np.asarray(stroke, float), shape).reshape(-1)
        v = np.zeros(n) if velocity is None else np.broadcast_to(np.asarray(velocity, float), shape).reshape(-1)
        if self.needs_motion and (stroke is None or velocity is None):
            raise ValueError(f"the {self.inverse.name!r} inverse needs the damper's stroke and velocity")
        f = np.broadcast_to(np.asarray(force, dtype=np.float64), shape).reshape(-1)
        c = self.inverse.command(np.broadcast_to(fd, shape).reshape(-1) + self.f_static, x, v, f_measured=f)
        return c.reshape(-1, self.n_dampers)

    def from_observation(self, f_desired, obs) -> np.ndarray:
        """Commands (N, nd) for desired forces (N, nd) beyond the preload and observations (N, n_obs) (or one
        observation), reading the damper's force, stroke and velocity from the sensors."""
        O = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        fd = np.broadcast_to(np.asarray(f_desired, dtype=np.float64), (O.shape[0], self.n_dampers)).reshape(-1)
        return self._from_rows(fd, O).reshape(-1, self.n_dampers)

    def step_commands(self, action: np.ndarray, obs: np.ndarray, force_range: float) -> np.ndarray:
        """The commands (N·nd,) of an environment step in ``action_mode="force"``: ``action`` (N·nd,) float64 the
        desired forces beyond the preload (N), clipped to ±``force_range`` as the action Box; ``obs`` (N, n_obs) or
        (n_obs,) the observations the action answers."""
        if not np.isfinite(action).all():
            raise ValueError("action must be finite (no NaN or infinity)")
        return self._from_rows(np.clip(action, -force_range, force_range), obs if obs.ndim == 2 else obs[None])

    def _from_rows(self, fd: np.ndarray, O: np.ndarray) -> np.ndarray:
        """The inverse's commands (N·nd,) for desired forces beyond the preload fd (N·nd,) and observations O
        (N, n_obs): the hot path of a force-mode step (no broadcasting, one copy per measured signal)."""
        m = {r: O[:, i].reshape(-1).astype(np.float64) for r, i in self._index.items()}
        f = m["damper_force"]
        zeros = None if self.needs_motion else np.zeros(f.size)
        return self.inverse.command(fd + self.f_static, m.get("damper_stroke", zeros),
                                    m.get("damper_velocity", zeros), f_measured=f)
