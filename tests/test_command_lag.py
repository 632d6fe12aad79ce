"""The command dynamics (asymmetric lag, pure delay) against their closed form, through the compiled kernel.

At a constant velocity the Bingham force is affine in the effective command u, F = F(0) + (f_cb tanh(ẋ/v_s) +
c0b ẋ)·u, so the rig's force shows u exactly: after a step from v0 to v1 issued at t_s, u(t) = v0 for
t < t_s + τ and v1 + (v0 − v1) exp(−η (t − t_s − τ)) after, with η = η_rise on a rise and η_fall on a fall.
"""
import math

import numpy as np
import pytest

from mrd_env.command_lag import effective_command
from mrd_env.dampers import CommandSpec, make_damper
from mrd_env.rig import simulate

DT = 2.5e-4
VEL = 0.05  # m/s


def _u_exact(t, t_up, t_down, delay, v1=2.0, eta_rise=300.0, eta_fall=125.0):
    """u after a rise 0 → v1 issued at t_up and a fall back to 0 issued at t_down."""
    tr, tf = t - t_up - delay, t - t_down - delay
    rise = np.where(tr < 0, 0.0, v1 * (1 - np.exp(-eta_rise * np.clip(tr, 0, None))))
    u_fall0 = v1 * (1 - math.exp(-eta_rise * (t_down - t_up)))
    return np.where(tf < 0, rise, u_fall0 * np.exp(-eta_fall * np.clip(tf, 0, None)))


@pytest.mark.parametrize("delay", [0.0, 3 * DT, 2.6 * DT])
def test_asymmetric_lag_and_delay_closed_form(delay):
    spec = CommandSpec("V", 0.0, 2.25, eta=300.0, eta_fall=125.0, delay=delay)
    d = make_damper("bingham", command=spec)
    n = 400
    t = np.arange(n) * DT
    k_up, k_down = 40, 220
    cmd = np.where((np.arange(n) >= k_up) & (np.arange(n) < k_down), 2.0, 0.0)
    x = VEL * t
    r = simulate(d, x, cmd, DT, v=np.full(n, VEL), a=np.zeros(n))[0]
    p = d.params
    gain = p.fc_b * math.tanh(VEL / p.v_s) + p.c0b * VEL
    F0 = p.fc_a * math.tanh(VEL / p.v_s) + p.c0a * VEL + p.f0
    u_ref = _u_exact(t, t[k_up], t[k_down], delay)
    np.testing.assert_allclose(r.u, u_ref, atol=1e-12)
    np.testing.assert_allclose(r.force, F0 + gain * u_ref, rtol=1e-9, atol=1e-6)


def test_lag_times_63_percent():
    """1/η_rise and 1/η_fall are the 63.2 % times of a rise and of a fall."""
    spec = CommandSpec("V", 0.0, 1.0, eta=1 / 3.3e-3, eta_fall=1 / 8e-3)
    dt = 1e-5
    v = np.r_[np.zeros(10), np.ones(3000), np.zeros(3000)]
    u = effective_command(spec, v, dt)
    k63 = int(np.argmax(u >= 1 - math.exp(-1))) - 10
    assert abs(k63 * dt - 3.3e-3) <= 1.5 * dt  # the first sample past the crossing
    u_end = u[3010]
    k63f = int(np.argmax(u[3010:] <= u_end * math.exp(-1)))
    assert abs(k63f * dt - 8e-3) <= 1.5 * dt


def test_symmetric_spec_is_unchanged_default():
    spec = CommandSpec("V", 0.0, 1.0, 190.0)
    assert spec.eta_down == 190.0 and spec.delay == 0.0
    with pytest.raises(ValueError, match="CommandSpec.eta_fall"):
        CommandSpec("V", 0.0, 1.0, 190.0, eta_fall=0.0)
    with pytest.raises(ValueError, match="CommandSpec.delay"):
        CommandSpec("V", 0.0, 1.0, 190.0, delay=-1e-3)


def test_environments_use_the_same_command_dynamics():
    """The environments step the same compiled driver: a delay longer than the run leaves the damper at its
    initial command, an explicit symmetric spec is bit-identical to the default one."""
    import gymnasium as gym

    import mrd_env  # noqa: F401  (registers the environments)

    def run(command):
        env = gym.make("mrd_env/QuarterCarPhysical-v0", damper=make_damper("bingham", command=command))
        obs, _ = env.reset(seed=3)
        out = [obs]
        for _ in range(5):
            obs, *_ = env.step(env.action_space.high)
            out.append(obs)
        return np.array(out)

    base = run(None)
    assert np.array_equal(run({"eta": 190.0, "eta_fall": None, "delay": 0.0}), base)
    held = run({"delay": 1.0})  # the command never arrives within the run: the damper stays at v_min
    passive = run({"eta": 190.0})
    assert not np.array_equal(held, base)
    env = gym.make("mrd_env/QuarterCarPhysical-v0", damper=make_damper("bingham"))
    env.reset(seed=3)
    ref = [env.step(env.action_space.low)[0] for _ in range(5)]
    # the physics of the held run is that of a run at v_min; only the applied command (the last column) differs
    np.testing.assert_array_equal(held[1:, :-1], np.array(ref)[:, :-1])
    assert np.all(held[1:, -1] == 2.25)
    assert np.array_equal(passive, base)
