"""Buildings with several dampers: the decentralised bang-bang law (its rule on hand-made observations, bang-bang,
energy out of the building), every law designed for all dampers at once on the six-storey building with four
dampers (one command per damper, each decided on its own storey), and the criteria counting every device."""
import gymnasium as gym
import numpy as np
import pytest

from controllers import DecentralizedBangBang, MaximumEnergyDissipation, make_controller
from mrd_env.constants import GRAVITY
from mrd_env.plants import ShearBuildingEnv

SENSORS = ("abs_acc", "drift", "floor_vel", "damper_force", "damper_stroke", "damper_velocity", "ground_acc",
           "command")
SIX = dict(plant_preset="six_storey", ground_motion="el_centro", episode_seconds=1.0)


def obs(env, **values):
    o = np.zeros(env.observation_space.shape[0])
    layout = {n: sl for n, sl, _ in env.sensor_layout}
    for k, v in values.items():
        o[layout[k]] = v
    return o


@pytest.mark.parametrize("floor,on", [(1, False), (2, True)])
def test_decentralized_bang_bang_uses_the_ground_velocity_for_a_damper_on_the_ground(floor, on):
    """Hand-checked: the ground at rest, then accelerating at −2 m/s² over one 1 ms control step, so ẋ_g = −1 mm/s
    (trapezoid); the stroke rate is +0.5 mm/s and the force 100 N beyond the preload. On the ground (storey 1) the
    stroke rate seen from the ground-fixed frame is 0.5 − 1 = −0.5 mm/s: (S ẋ_a)·f < 0, off. Between floors 1 and
    2 it is the stroke rate itself: on, as maximum energy dissipation."""
    env = ShearBuildingEnv(damper_floors=(floor,), sensors=SENSORS)
    law, med = DecentralizedBangBang(env), MaximumEnergyDissipation(env)
    f = env.F_static + 100.0
    law.predict(obs(env, ground_acc=0.0, damper_velocity=5e-4, damper_force=f))
    o = obs(env, ground_acc=-2.0, damper_velocity=5e-4, damper_force=f)
    assert law.predict(o)[0][0] == (2.25 if on else 0.0)
    assert med.predict(o)[0][0] == 2.25
    law.reset()  # a new episode starts from rest: the ground velocity is forgotten
    assert law.predict(o)[0][0] == 2.25


def run(law, steps=None, **options):
    env = gym.make("mrd_env/ShearBuildingPhysical-v0", sensors=SENSORS, **{**SIX, **options})
    ctrl = make_controller(law, env)
    o, _ = env.reset(seed=0)
    layout = {n: sl for n, sl, _ in env.unwrapped.sensor_layout}
    rows, actions, done = [o], [], False
    while not done:
        a, _ = ctrl.predict(o)
        o, _, term, trunc, info = env.step(a)
        rows.append(o)
        actions.append(a)
        done = term or trunc
    O = np.array(rows, dtype=float)
    return {k: O[:, sl] for k, sl in layout.items()}, np.array(actions), info["episode_metrics"], env.unwrapped


def test_decentralized_bang_bang_is_bang_bang_and_takes_energy_out_of_the_six_storey_building():
    sig, u, m, env = run("decentralized_bang_bang")
    assert u.shape[1] == 4
    assert set(np.unique(u)) <= {0.0, 2.25} and len(np.unique(u)) == 2
    # the dampers' work on the building: Σ_j ∫ f_j·ẋ_j dt > 0 (f beyond the preload, resisting extension)
    work = np.sum((sig["damper_force"][1:] - env.F_static) * sig["damper_velocity"][1:]) * env.control_dt
    assert work > 0.0
    assert m["J4"] < 1.0 and m["J1"] < 1.0  # less drift than the building without dampers


@pytest.mark.parametrize("law", ["clipped_optimal", "lyapunov", "max_energy_dissipation", "modulated_friction",
                                 "decentralized_bang_bang"])
def test_every_law_commands_each_of_the_four_dampers_on_its_own(law):
    """One command per damper, and the dampers of storey 1 and those of storey 2 are not commanded alike."""
    _, u, m, _ = run(law)
    assert u.shape == (1000, 4)
    assert np.any(u[:, 0] != u[:, 2]) and np.any(u[:, 1] != u[:, 3])
    assert m["J4"] < 1.0


def test_the_criteria_count_every_device():
    """Peak force and stroke: the largest over the four dampers (then over weight); control power: summed over
    them (the structural benchmark's peak and total control power), from the sensors recorded every 1 ms."""
    sig, _, m, env = run("decentralized_bang_bang")
    f, x, v = sig["damper_force"], sig["damper_stroke"], sig["damper_velocity"]
    by_device = np.max(np.abs(f), axis=0)
    assert np.ptp(by_device) > 0.0  # the devices differ: which one is counted matters
    assert m["damper_force_peak"] == pytest.approx(by_device.max(), rel=1e-6)
    assert m["force_over_weight"] == pytest.approx(by_device.max() / (6 * 200.0 * GRAVITY), rel=1e-6)
    assert m["stroke_peak"] == pytest.approx(np.max(np.abs(x)), rel=1e-6)
    power = np.sum(np.abs(f * v), axis=1)
    assert m["control_power_peak"] == pytest.approx(power.max(), rel=1e-5)
    assert m["control_power_total"] == pytest.approx(power[1:].sum() * env.control_dt, rel=1e-5)
