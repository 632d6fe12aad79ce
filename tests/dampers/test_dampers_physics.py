"""Physics of the default damper models: dissipation, monotonicity in command, saturation, command lag,
and clear errors on bad input."""
import math

import numpy as np
import pytest

from mrd_env import SimulationDivergedError, available_dampers, make_damper
from mrd_env.dampers import CommandSpec, damper_class
from mrd_env.dampers.bouc_wen import BoucWenParams
from mrd_env.dampers.spencer_dyke import SpencerDykeParams
from mrd_env.stepping import SystemMatrices, run
from mrd_env.rig import random_test, simulate, sinusoidal_test

DEFAULT_MODELS = ["spencer_dyke", "bouc_wen", "bingham"]


def test_models_are_selectable_by_name():
    assert set(DEFAULT_MODELS) <= set(available_dampers())
    with pytest.raises(ValueError, match="unknown damper model 'nope'.*available"):
        make_damper("nope")
    with pytest.raises(ValueError, match="unknown preset 'nope'"):
        make_damper("spencer_dyke", "nope")


@pytest.mark.parametrize("model", DEFAULT_MODELS)
def test_energy_dissipated_per_steady_cycle_is_positive_and_grows_with_command(model):
    d = make_damper(model)
    levels = np.linspace(d.command.v_min, d.command.v_max, 4)
    results = sinusoidal_test(d, 0.01, 2.0, levels, cycles=3)
    energies = [r.dissipated_energy(r.steady_cycles(2.0)) for r in results]
    peaks = [r.force[r.steady_cycles(2.0)].max() for r in results]
    assert all(e > 0 for e in energies)
    assert np.all(np.diff(energies) > 0)
    assert np.all(np.diff(peaks) > 0)


# strokes and frequencies from a fine stroke at low frequency to the full stroke and to a road's wheel hop
RIG_TESTS = [(0.015, 2.5), (0.002, 1.0), (0.03, 0.5), (0.005, 8.0)]


@pytest.mark.parametrize("model,preset", [(m, p) for m in available_dampers() for p in damper_class(m).presets])
def test_every_preset_dissipates_more_per_cycle_with_more_command(model, preset):
    """Ten command levels over the range at four strokes and frequencies: the energy dissipated per steady cycle
    of every model's every preset is positive and grows with the command (the hysteretic bi-viscous preset's
    fitted laws turned over at 1.85 V and failed this until 2026-11-25)."""
    d = make_damper(model, preset=preset)
    levels = np.linspace(d.command.v_min, d.command.v_max, 10)
    for X, f in RIG_TESTS:
        rs = sinusoidal_test(d, X, f, levels, cycles=3, dt=min(2e-4, 1 / (50 * f)))
        energies = np.array([r.dissipated_energy(r.steady_cycles(f)) for r in rs])
        assert np.all(energies > 0), (X, f, energies)
        assert np.all(np.diff(energies) > 0), (X, f, levels[np.argmin(np.diff(energies))], energies)


@pytest.mark.parametrize("preset", ["spencer1997", "automotive"])
@pytest.mark.parametrize("model", ["spencer_dyke", "bouc_wen"])
def test_bouc_wen_z_never_exceeds_saturation(model, preset):
    d = make_damper(model, preset)
    p = d.params
    zs = (p.A / (p.beta + p.gamma)) ** (1 / p.n)
    r = random_test(d, rms=0.01, bandwidth=30.0, duration=2.0, switch_rate=5.0, rng=3)
    # re-run through the stepping routine to read the state history
    n = len(r.t)
    W = np.stack([r.x, r.v, np.gradient(r.v, r.dt)], axis=1)[None]
    _, Yh, _ = run(d, SystemMatrices.displacement_driven(), d.initial_state()[None].copy(),
                   r.command[:1][None].copy(), r.command[:-1][None, :, None].copy(), W, r.dt)
    z = Yh[0, :, d.state_names.index("z")]
    assert np.max(np.abs(z)) <= zs * (1 + 1e-12)
    assert np.max(np.abs(z)) > 0.99 * zs  # and the random test does reach it
    assert z.shape[0] == n - 1  # the states after every step of the record


def test_saturation_value_is_the_closed_form():
    d = make_damper("spencer_dyke")
    assert d.saturation() == pytest.approx(math.sqrt(301 / (2 * 3.63e6)))
    assert d.saturation() == pytest.approx(0.644e-2, rel=2e-3)  # reference page: 0.644 cm


def test_command_lag_reaches_63_percent_after_one_over_eta():
    """u̇ = −η(u − v): seen in the force of a Bingham damper at constant velocity (F affine in u)."""
    d = make_damper("bingham")
    eta = d.command.eta
    dt = 1e-4
    n = 400
    t = np.arange(n) * dt
    cmd = np.full(n, d.command.v_max)
    cmd[0] = d.command.v_min
    r = simulate(d, 0.1 * t, cmd, dt, v=np.full(n, 0.1), a=np.zeros(n))[0]
    # the command at sample k is held over [t_k, t_k+1): the step starts at t = dt
    F_start, F_end = r.force[0], (d.params.fc_a + d.params.fc_b * d.command.v_max) * np.tanh(0.1 / d.params.v_s) \
        + (d.params.c0a + d.params.c0b * d.command.v_max) * 0.1 + d.params.f0
    frac = (np.interp(dt + 1 / eta, r.t, r.force) - F_start) / (F_end - F_start)
    assert frac == pytest.approx(1 - math.exp(-1), abs=2e-3)
    assert np.interp(dt + 1 / eta, r.t, (r.u - d.command.v_min) / (d.command.v_max - d.command.v_min)) == \
        pytest.approx(1 - math.exp(-1), abs=2e-3)


def test_bingham_jump_at_zero_velocity_is_two_fc():
    d = make_damper("bingham", v_s=0.0)
    p = d.params.as_array()
    force = type(d).force_law
    u = 1.0
    jump = force(p, np.zeros(0), 0.0, 1e-9, 0.0, u) - force(p, np.zeros(0), 0.0, -1e-9, 0.0, u)
    assert jump == pytest.approx(2 * (d.params.fc_a + d.params.fc_b * u), rel=1e-6)


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize("field,value", [("c0a", -1.0), ("alpha_b", float("nan")), ("n", 0.5),
                                         ("A", 0.0), ("c1a", float("inf"))])
def test_bad_parameters_name_the_field(field, value):
    with pytest.raises(ValueError, match=f"SpencerDykeParams.{field}"):
        make_damper("spencer_dyke", **{field: value})


def test_cross_field_constraint():
    with pytest.raises(ValueError, match="beta \\+ gamma"):
        make_damper("bouc_wen", beta=-2e6, gamma=1e6)


def test_wrong_params_type_and_unknown_override():
    with pytest.raises(ValueError, match="unknown parameter"):
        make_damper("bouc_wen", c1a=3.0)
    with pytest.raises(ValueError, match="must be a BoucWenParams"):
        type(make_damper("bouc_wen"))(params=make_damper("spencer_dyke").params)


def test_command_outside_range_and_dt():
    d = make_damper("spencer_dyke")
    with pytest.raises(ValueError, match=r"command must stay within \[0, 2.25\] V"):
        sinusoidal_test(d, 0.01, 1.0, [3.0])
    with pytest.raises(ValueError, match="command contains a non-finite"):
        simulate(d, np.zeros(10), np.full(10, np.nan))
    with pytest.raises(ValueError, match="dt = 0.0 is invalid: must be finite and > 0 s"):
        simulate(d, np.zeros(10), np.zeros(10), dt=0.0)
    with pytest.raises(ValueError, match="dt = -0.001 is invalid"):
        simulate(d, np.zeros(10), np.zeros(10), dt=-1e-3)
    with pytest.raises(ValueError, match="amplitude"):
        sinusoidal_test(d, -0.01, 1.0)
    with pytest.raises(ValueError, match="x contains a non-finite"):
        simulate(d, np.array([0.0, np.nan, 0.0]), np.zeros(3))
    with pytest.raises(ValueError, match="CommandSpec.eta"):
        CommandSpec("V", 0.0, 1.0, eta=-5.0)
    with pytest.raises(ValueError, match="CommandSpec.unit"):
        CommandSpec("W", 0.0, 1.0)


def test_non_finite_state_stops_with_model_and_time():
    d = make_damper("spencer_dyke")
    n = 50
    t = np.arange(n + 1) * 1e-3
    W = np.stack([0.01 * np.sin(20 * t), 0.2 * np.cos(20 * t), 0 * t], axis=1)[None]
    P = d.params.as_array()[None, None].copy()
    P[0, 0, 0] = np.nan  # a corrupted parameter vector, bypassing validation
    with pytest.raises(SimulationDivergedError, match=r"'spencer_dyke'.*t = 0.001 s") as info:
        run(d, SystemMatrices.displacement_driven(), np.zeros((1, 2)), np.zeros((1, 1)), np.zeros((1, n, 1)),
            W, 1e-3, P=P)
    assert info.value.model == "spencer_dyke"
    assert info.value.time == pytest.approx(1e-3)


def test_params_round_trip_and_units_are_si():
    p = make_damper("spencer_dyke").params
    assert isinstance(p, SpencerDykeParams)
    assert p.c0a == 2100.0 and p.x0 == 0.143 and p.gamma == 3.63e6  # 21.0 N·s/cm, 14.3 cm, 363 cm⁻²
    assert SpencerDykeParams(**p.to_dict()) == p
    assert BoucWenParams.units()["c0a"] == "N·s/m"


# ---------------------------------------------------------------- the force of a configured damper


def test_force_called_on_an_instance():
    """``d.force(x, v, u)`` evaluates the force law with the damper's own parameters (issue: it raised TypeError)."""
    d = make_damper("bingham")
    p = d.params
    u = 1.0
    expected = (p.fc_a + p.fc_b * u) * np.tanh(0.1 / p.v_s) + (p.c0a + p.c0b * u) * 0.1 + p.f0
    assert d.force(0.0, 0.1, u) == pytest.approx(expected, rel=1e-12)
    F = d.force(np.zeros(3), np.array([-0.1, 0.0, 0.1]), u)
    assert F.shape == (3,) and F[0] < p.f0 < F[2]
    sd = make_damper("spencer_dyke")
    assert sd.force(0.0, 0.0, 0.0) == pytest.approx(-sd.params.k1 * sd.params.x0)  # at rest: the preload
    with pytest.raises(ValueError, match="u must stay within"):
        sd.force(0.0, 0.1, 5.0)
    with pytest.raises(ValueError, match="v contains a non-finite"):
        sd.force(0.0, float("nan"), 1.0)


def test_command_channel_overrides_by_dict_or_spec():
    d = make_damper("spencer_dyke", command={"v_max": 3.0})
    assert d.command.v_max == 3.0 and d.command.eta == 190.0 and d.command.unit == "V"
    from mrd_env.dampers import CommandSpec
    assert make_damper("spencer_dyke", command=CommandSpec("A", 0.0, 1.0, 50.0)).command.unit == "A"
    with pytest.raises(ValueError, match=r"command has unknown key\(s\) \['vmax'\]"):
        make_damper("spencer_dyke", command={"vmax": 3.0})
    with pytest.raises(ValueError, match="CommandSpec.v_max"):
        make_damper("spencer_dyke", command={"v_max": -1.0})
    with pytest.raises(ValueError, match="command must be a CommandSpec"):
        make_damper("spencer_dyke", command=3.0)
