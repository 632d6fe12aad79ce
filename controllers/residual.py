"""Residual policies: an agent's action is a correction added to a classical law's command.

Residual policy learning (Silver et al. 2018, arXiv:1812.06298; Johannink et al., ICRA 2019): the command is

    u = u_law(y) + scale · (u_max − u_min) · a,  reflected at u_min and u_max,     a ∈ [−1, 1]^nd,

with ``u_law`` the command of a law (skyhook, clipped-optimal, any :class:`~controllers.base.Controller`) on the
same observation y; the agent sees y and u_law (:meth:`Residual.observe`). An agent whose output is zero is the law exactly; ``mrd-env train --residual LAW`` zeroes the
last layer of the policy (:func:`zero_policy_output`), so that training starts at the law and learns only the
correction, and exploration starts from a good policy. With ``scale = 1`` any command is reachable from any law
command. ``boundary="clip"`` clips at the range's ends instead of reflecting: where the law sits at an end, the
outward half of the corrections does nothing and the inward half moves the command (see :meth:`Residual.combine`).

The law may run faster than the agent: with ``hold = k`` the environment steps at the law's rate (e.g. 1 ms) and
the agent's correction is held for k steps while the law's command follows every observation, so that a residual
agent deciding every 10 ms competes with the law at its own best rate (docs/rl-agents.md, "A correction held over
the law at 1 ms").

One rule (:class:`Residual`) in two places: :class:`controllers.training_wrappers.ResidualVecEnv` (an SB3
``VecEnvWrapper`` whose actions are the corrections a: training, any algorithm) and :class:`ResidualController`
(a trained residual agent behind the controllers' interface: what :meth:`controllers.agents.TrainedAgent.bind`
returns for an agent trained with a residual).
"""
from __future__ import annotations

import numpy as np

from .base import AgentController, Controller


class Residual:
    """The rule above for the environment ``env`` (scalar or vector; commands or normalised actions, not force
    mode): ``actions(obs, a, episode_start)`` → the environment's actions. ``law``: a controller's name (with
    ``law_options``) or a :class:`~controllers.base.Controller` built for ``env``. ``boundary``: "reflect"
    (default) or "clip", what a command beyond the range's ends becomes (:meth:`combine`)."""

    BOUNDARIES = ("reflect", "clip")

    def __init__(self, env, law: str | Controller, scale: float = 1.0, boundary: str = "reflect", **law_options):
        from .registry import make_controller
        from mrd_env.validation import check_scalar

        base = getattr(env, "unwrapped", env)
        if getattr(base, "action_mode", "physical") == "force":
            raise ValueError("a residual policy adds to a law's command: build the environment with action_mode "
                             "'physical' or 'normalized', not 'force'")
        self.scale = check_scalar("residual scale", scale, 0.0, lo_open=True)
        if boundary not in self.BOUNDARIES:
            raise ValueError(f"residual boundary must be one of {list(self.BOUNDARIES)}, got {boundary!r}")
        self.boundary = boundary
        if isinstance(law, Controller):
            if law_options:
                raise ValueError(f"options {sorted(law_options)} apply to a law given by name")
            self.law = law
        else:
            self.law = make_controller(law, base, **law_options)
        if self.law.acts_in_env_space:
            raise ValueError(f"the residual's base must be a classical law, not the agent {self.law.name!r}")
        self.name = self.law.name
        self.n_dampers = self.law.n_dampers
        self.v_min, self.v_max = self.law.v_min, self.law.v_max
        self.normalized = self.law.normalized

    def reset(self, mask=None) -> None:
        self.law.reset(mask)

    def law_command(self, obs, episode_start=None) -> np.ndarray:
        """The law's physical command u_law for observations ``obs`` (n_obs,) or (N, n_obs); ``episode_start``:
        rows whose episode has just begun (the law forgets them)."""
        law_a = np.asarray(self.law.predict(obs, episode_start=episode_start)[0], dtype=np.float64)
        return self.v_min + (law_a + 1.0) * 0.5 * (self.v_max - self.v_min) if self.normalized else law_a

    def observe(self, obs, u_law) -> np.ndarray:
        """What the agent sees: the observation with the law's command appended, mapped to [−1, 1] — the agent
        can then tell where the law saturates (a correction beyond the range does nothing there), from the same
        sensors, so no information is added."""
        v = 2.0 * (np.asarray(u_law) - self.v_min) / (self.v_max - self.v_min) - 1.0
        return np.concatenate([np.asarray(obs, dtype=np.float32), v.astype(np.float32)], axis=-1)

    def combine(self, u_law, a) -> np.ndarray:
        """The environment's actions for the law's commands ``u_law`` and corrections ``a`` in [−1, 1].

        With ``boundary="clip"`` a command beyond an end is that end. Where a bang-bang law (clipped-optimal) sits
        at an end, reflection makes the command depend on |a| only, so the return is even in the policy's mean
        there and its gradient at the law (mean 0) vanishes: clipping keeps a first-order signal (the inward half
        of the noise moves the command, the outward half does nothing) and a mean pushed outwards leaves the
        command at the law's."""
        u_law = np.asarray(u_law, dtype=np.float64)
        a = np.clip(np.asarray(a, dtype=np.float64).reshape(u_law.shape), -1.0, 1.0)
        u = u_law + self.scale * (self.v_max - self.v_min) * a
        if self.boundary == "clip":
            return self.law._to_action(u)  # clipped to [u_min, u_max] there
        # reflected at the range's ends rather than clipped: where the law saturates, a correction beyond the end
        # acts like the same correction inwards, so the exploration noise of a stochastic policy costs alike on
        # both sides and does not pull its mean outwards (clipping does: the outward half of the noise is free)
        u = np.where(u < self.v_min, 2.0 * self.v_min - u, u)
        u = np.where(u > self.v_max, 2.0 * self.v_max - u, u)
        return self.law._to_action(u)

    def actions(self, obs, a, episode_start=None) -> np.ndarray:
        """The environment's actions for observations ``obs`` and corrections ``a`` (see :meth:`combine`)."""
        return self.combine(self.law_command(obs, episode_start), a)


def check_hold(hold) -> int:
    """The number of the environment's steps a correction is held for: an int >= 1 (``ValueError`` otherwise)."""
    if isinstance(hold, bool) or not isinstance(hold, (int, np.integer)) or hold < 1:
        raise ValueError(f"the residual's hold must be an int >= 1 (environment steps per correction), got {hold!r}")
    return int(hold)


class ResidualController(AgentController):
    """A trained residual agent (``agent``: anything with SB3's ``predict`` whose actions are corrections in
    [−1, 1]) on the law ``law`` with ``scale`` (and ``boundary`` among ``law_options``, see :class:`Residual`),
    behind the controllers' interface. ``hold``: the agent decides at every ``hold``-th step of each episode and its
    correction is held in between, while the law's command follows every step (see the module docstring)."""

    name = "residual"

    def __init__(self, env, agent, law: str, scale: float = 1.0, name: str | None = None,
                 env_kwargs: dict | None = None, hold: int = 1, **law_options):
        self.hold = check_hold(hold)
        if self.hold > 1 and (getattr(agent, "meta", None) or {}).get("recurrent"):
            raise ValueError("a held residual (hold > 1) needs a policy without memory, not a recurrent one")
        self.residual = Residual(env, law, scale, **law_options)
        super().__init__(env, agent, name=name or f"residual {law}", env_kwargs=env_kwargs)
        self._k = None  # each row's steps since its episode began (hold > 1)
        self._a = None  # each row's held correction

    def reset(self, mask=None) -> None:
        self.residual.reset(mask)
        super().reset(mask)
        if mask is None:
            self._k = None

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        episode_start = self.episode_starts(episode_start)
        u_law = self.residual.law_command(observation, episode_start)
        if self.hold == 1:
            a, self._state = self.model.predict(self.residual.observe(observation, u_law),
                                                state=state if state is not None else self._state,
                                                episode_start=episode_start, deterministic=deterministic)
            return self.residual.combine(u_law, a), self._state
        rows = 1 if np.ndim(observation) == 1 else np.shape(observation)[0]
        if self._k is None or self._k.shape[0] != rows:
            self._k = np.zeros(rows, dtype=np.int64)
        if episode_start is not None:
            self._k[np.broadcast_to(np.asarray(episode_start, dtype=bool), (rows,))] = 0
        due = self._k % self.hold == 0
        if due.any():
            a = np.asarray(self.model.predict(self.residual.observe(observation, u_law),
                                              deterministic=deterministic)[0], dtype=np.float64).reshape(rows, -1)
            self._a = a if self._a is None or self._a.shape != a.shape else np.where(due[:, None], a, self._a)
        self._k += 1
        return self.residual.combine(u_law, self._a.reshape(np.shape(u_law))), None


def zero_policy_output(model) -> None:
    """Zero the last layer of an SB3 (or sb3-contrib) policy, so that its deterministic action is 0 — a residual
    agent that is exactly its law (PPO, A2C, RecurrentPPO, ARS: ``action_net``; SAC, TQC: ``actor.mu``; TD3, DDPG:
    the actor's last linear layer, and the target actor's)."""
    import torch

    policy = model.policy
    layers = []
    net = getattr(policy, "action_net", None)
    if isinstance(net, torch.nn.Sequential):  # ARS's MLP policy
        net = [m for m in net if isinstance(m, torch.nn.Linear)][-1]
    if net is not None:
        layers.append(net)
    for actor in (getattr(policy, "actor", None), getattr(policy, "actor_target", None)):
        if actor is None:
            continue
        mu = getattr(actor, "mu", None)
        if isinstance(mu, torch.nn.Sequential):
            mu = [m for m in mu if isinstance(m, torch.nn.Linear)][-1]
        if mu is not None:
            layers.append(mu)
    if not layers:
        raise ValueError(f"cannot find the output layer of the {type(policy).__name__} policy to start it at zero")
    with torch.no_grad():
        for layer in layers:
            layer.weight.zero_()
            if layer.bias is not None:  # ARS's linear policy has none
                layer.bias.zero_()
