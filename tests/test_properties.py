"""Property-based checks of the public entry points (hypothesis): every input either works, with finite
outputs, or raises a ``ValueError`` whose message names the offending argument — never a silent NaN and never
an unrelated exception. Physically extreme but valid inputs may raise :class:`mrd_env.SimulationDivergedError`.
"""
from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st
from hypothesis.extra.numpy import arrays

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env import SimulationDivergedError, available_dampers, make_damper
from mrd_env.dampers import damper_class
from mrd_env.disturbances import Record, bump, iso8608_road, kanai_tajimi, scale_record, sine_sweep
from mrd_env.disturbances.record import n_samples_for
from mrd_env.identification import DamperRecord, load_record_csv
from mrd_env.records import UNITS, read_columns
from mrd_env.rig import random_test, simulate, sinusoidal_test
from mrd_env.validation import as_real

DAMPERS = available_dampers()
QC, SB = "mrd_env/QuarterCarPhysical-v0", "mrd_env/ShearBuildingPhysical-v0"

# Kernels are compiled once per damper model and cached on disk; the examples themselves take milliseconds.
FEW = settings(max_examples=25, deadline=None)
SOME = settings(max_examples=50, deadline=None)
MANY = settings(max_examples=100, deadline=None)

# --- values ----------------------------------------------------------------------------------------------------

NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])
HUGE = st.sampled_from([1e300, -1e300, 1.7e308, 10 ** 400, -(10 ** 400)])
JUNK = st.one_of(
    st.none(), st.text(max_size=4), st.builds(complex, st.floats(-1e3, 1e3), st.floats(1e-3, 1e3)),
    st.just(np.complex128(1 + 2j)), st.lists(st.floats(-1, 1), min_size=2, max_size=3),
    st.just([1.0, [2.0]]), st.dictionaries(st.text(max_size=2), st.integers(), max_size=1), st.just(object()),
    st.just(np.datetime64("2020-01-01")))
#: Anything a user might pass where a real number is expected.
ANY_SCALAR = st.one_of(st.floats(), st.integers(-10 ** 6, 10 ** 6), HUGE, NON_FINITE, JUNK)
#: Values that are never a valid positive quantity.
NOT_POSITIVE = st.one_of(st.floats(max_value=0.0), NON_FINITE, JUNK, st.just(-(10 ** 400)))


def sized(valid: st.SearchStrategy) -> st.SearchStrategy:
    """For an argument that sets a record's length (duration, dt, cycles): mostly valid values, or values that
    must be refused — non-positive, non-finite, junk, or so extreme that the record could not be held (a
    moderately large valid value would only make the test slow)."""
    return st.one_of(valid, valid, NOT_POSITIVE, HUGE, st.just(1e-300))


def assert_names(err: BaseException, *names: str) -> None:
    """The message names at least one of ``names`` as a word (not as part of a longer identifier), or, for an
    indexed coefficient, its family: as a range ("fz01..fz04" names fz03) or a function ("alpha(I)" names
    alpha1)."""
    msg = str(err)

    def named(n: str) -> bool:
        if re.search(rf"(?<![A-Za-z0-9_]){re.escape(n)}(?![A-Za-z0-9_])", msg):
            return True
        family = re.sub(r"_?[0-9]+$", "", n)
        return family != n and bool(re.search(rf"(?<![A-Za-z0-9_]){re.escape(family)}(_?[0-9]+\.\.|\()", msg))

    assert any(named(str(n)) for n in names), f"message {msg!r} names none of {names}"


def all_finite(*arrays_) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=np.float64))) for a in arrays_)


# --- dampers: parameters, presets, command channel, force ---------------------------------------------------------

def _in_bounds(lo: float, hi: float) -> st.SearchStrategy:
    lo_f = lo if math.isfinite(lo) else -1e6
    hi_f = hi if math.isfinite(hi) else 1e6
    return st.floats(lo_f, max(lo_f, hi_f), allow_nan=False)


def _check_force(d) -> None:
    c = d.command
    try:
        F = d.force([0.0, 0.01, -0.02], [0.1, -0.3, 0.0], [c.v_min, c.v_max, 0.5 * (c.v_min + c.v_max)])
    except ValueError as e:  # huge but valid parameters: the force overflows float64, and says so
        assert "not finite" in str(e), str(e)
        return
    assert F.shape == (3,) and all_finite(F)


@SOME
@given(name=st.sampled_from(DAMPERS), data=st.data())
def test_make_damper_parameter_overrides(name, data):
    cls = damper_class(name)
    bounds = cls.Params.bounds()
    keys = data.draw(st.lists(st.sampled_from(list(bounds) + ["not_a_parameter"]), unique=True, max_size=3))
    overrides = {k: data.draw(st.one_of(ANY_SCALAR, _in_bounds(*bounds[k])) if k in bounds else ANY_SCALAR)
                 for k in keys}
    try:
        d = make_damper(name, **overrides)
    except ValueError as e:
        # a constraint across fields may name the coefficient family: "the v0 polynomial (v0_0..v0_4)" for v0_2
        assert_names(e, *overrides)
        return
    assert set(overrides) <= set(bounds)
    p = d.params.to_dict()
    assert all_finite(list(p.values()))
    for k, v in overrides.items():
        assert p[k] == float(v)
    _check_force(d)


def _presets() -> list[str]:
    return sorted({p for n in DAMPERS for p in damper_class(n).presets})


COMMAND_KEYS = ["unit", "v_min", "v_max", "eta", "eta_fall", "delay", "gain"]


@SOME
@given(name=st.sampled_from(DAMPERS), preset=st.one_of(st.none(), st.sampled_from(_presets()), ANY_SCALAR),
       command=st.one_of(
           st.none(),
           st.dictionaries(st.sampled_from(COMMAND_KEYS),
                           st.one_of(st.sampled_from(["V", "A", "mA"]), st.floats(-5.0, 500.0), ANY_SCALAR),
                           max_size=3),
           JUNK))
def test_make_damper_preset_and_command(name, preset, command):
    cls = damper_class(name)
    try:
        d = make_damper(name, preset=preset, command=command)
    except ValueError as e:
        assert_names(e, "preset", "command", *(command if isinstance(command, dict) else ()))
        return
    assert preset is None or preset in cls.presets
    for k, v in (command or {}).items():
        assert getattr(d.command, k) == (v if k == "unit" else float(v))
    assert all_finite([d.command.v_min, d.command.v_max, d.command.eta, d.command.eta_down, d.command.delay])
    _check_force(d)


@st.composite
def _array_like(draw, finite_only: bool = False):
    elements = st.floats(-1.0, 1.0) if finite_only else st.floats()
    return draw(st.one_of(
        st.floats(-0.05, 0.05), arrays(np.float64, st.sampled_from([(), (1,), (3,), (2, 3), (1, 3), (0,)]),
                                       elements=elements),
        st.lists(elements, max_size=4), *(() if finite_only else (ANY_SCALAR,))))


@SOME
@given(name=st.sampled_from(DAMPERS), x=_array_like(), v=_array_like(), u=_array_like(True), a=_array_like(True),
       state=st.one_of(st.none(), ANY_SCALAR, arrays(np.float64, st.integers(0, 4))))
def test_damper_force_any_input(name, x, v, u, a, state):
    d = make_damper(name)
    c = d.command
    u = np.clip(u, c.v_min, c.v_max) if isinstance(u, np.ndarray) and u.size and np.all(np.isfinite(u)) else u
    try:
        F = d.force(x, v, u, a=a, state=state)
    except ValueError as e:
        msg = str(e)
        assert re.match(r"(x|v|u|a|state)\b", msg) or ("not finite" in msg and "x =" in msg), msg
        return
    shape = np.broadcast_shapes(*(np.shape(np.asarray(z, dtype=float)) for z in (x, v, a, u)))
    assert np.shape(F) == shape and all_finite(F)
    assert isinstance(F, float) == (shape == ())


# --- the virtual rig ---------------------------------------------------------------------------------------------

def _rig_damper(data):
    return make_damper(data.draw(st.sampled_from(DAMPERS)))


@st.composite
def _valid_sinusoid(draw):
    d = make_damper(draw(st.sampled_from(DAMPERS)))
    c = d.command
    f = draw(st.floats(0.5, 20.0))
    dt = draw(st.floats(1e-4, 0.999 * min(0.1 / f, 1.0 / c.eta)))  # 0.999: no rounding onto the limit
    cycles = draw(st.floats(max(0.05, 2 * f * dt), 0.5 * f))  # at most 0.5 s simulated
    commands = draw(st.lists(st.floats(c.v_min, c.v_max), min_size=1, max_size=3))
    return d, {"amplitude": draw(st.floats(1e-4, 0.05)), "frequency": f, "commands": commands, "cycles": cycles,
               "dt": dt}


@SOME
@given(case=_valid_sinusoid())
def test_sinusoidal_test_valid_gives_finite_forces(case):
    d, kw = case
    try:
        rs = sinusoidal_test(d, **kw)
    except SimulationDivergedError as e:  # physically extreme (e.g. 3 m/s at a 4 ms step) but valid
        assert d.name in str(e) and "t =" in str(e)
        return
    assert len(rs) == len(kw["commands"])
    for r in rs:
        assert len(r.t) >= 2 and all_finite(r.x, r.v, r.u, r.force)


BAD_SINUSOID = {
    "amplitude": NOT_POSITIVE, "frequency": NOT_POSITIVE, "cycles": st.one_of(NOT_POSITIVE, st.just(1e-9), HUGE),
    "dt": st.one_of(NOT_POSITIVE, st.just(1.0), st.just(1e-300)),
    "commands": st.one_of(st.sampled_from([None, "x", 1 + 2j, [1.0, [2.0]], {}, [], [99.0], [-1.0],
                                           [[0.0, 1.0], [0.5, 0.5]], [math.nan]]), NON_FINITE),
}


@SOME
@given(case=_valid_sinusoid(), arg=st.sampled_from(sorted(BAD_SINUSOID)), data=st.data())
def test_sinusoidal_test_bad_argument_is_named(case, arg, data):
    d, kw = case
    kw[arg] = data.draw(BAD_SINUSOID[arg], label=arg)
    with pytest.raises(ValueError) as info:
        sinusoidal_test(d, **kw)
    assert_names(info.value, arg, *(["command"] if arg == "commands" else []))  # "command must stay within ..."


@SOME
@given(data=st.data())
def test_sinusoidal_test_any_arguments(data):
    d = _rig_damper(data)
    kw = {k: data.draw(st.one_of(st.floats(1e-4, 10.0), ANY_SCALAR), label=k) for k in ("amplitude", "frequency")}
    kw["cycles"] = data.draw(sized(st.floats(0.01, 2.0)), label="cycles")
    kw["dt"] = data.draw(sized(st.floats(1e-4, 1e-2)), label="dt")
    kw["commands"] = data.draw(st.one_of(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=2), ANY_SCALAR))
    try:
        f, dt, cycles = (as_real(k, kw[k]) for k in ("frequency", "dt", "cycles"))
        if 0 < dt and 0 < f and cycles / f / dt > 5e4:
            kw["cycles"] = 1e9  # a valid but huge request: must be refused by name, not by a memory error
    except ValueError:
        pass
    try:
        rs = sinusoidal_test(d, **kw)
    except ValueError as e:
        assert_names(e, *kw, "command")
        return
    except SimulationDivergedError:
        return
    for r in rs:
        assert all_finite(r.force, r.x, r.v)


@st.composite
def _valid_random(draw):
    d = make_damper(draw(st.sampled_from(DAMPERS)))
    c = d.command
    bw = draw(st.floats(5.0, 50.0))
    dt = draw(st.floats(1e-4, 0.999 * min(0.1 / bw, 1.0 / c.eta)))
    duration = draw(st.floats(max(2.0 / bw, 2 * dt), 0.5))
    kw = {"rms": draw(st.floats(1e-4, 0.02)), "bandwidth": bw, "duration": duration, "dt": dt,
          "rng": draw(st.one_of(st.none(), st.integers(0, 2 ** 32), st.builds(np.random.default_rng)))}
    if draw(st.booleans()):
        kw["command"] = draw(st.floats(c.v_min, c.v_max))
    else:
        kw["switch_rate"] = draw(st.floats(0.1, 0.1 / dt))
    return d, kw


@SOME
@given(case=_valid_random())
def test_random_test_valid_gives_finite_forces(case):
    d, kw = case
    try:
        r = random_test(d, **kw)
    except SimulationDivergedError as e:
        assert d.name in str(e) and "t =" in str(e)
        return
    assert all_finite(r.x, r.v, r.force, r.command)
    assert np.sqrt(np.mean(r.x ** 2)) == pytest.approx(kw["rms"], rel=1e-9)


BAD_RANDOM = {
    "rms": NOT_POSITIVE, "bandwidth": st.one_of(NOT_POSITIVE, st.just(1e-3)),
    "duration": st.one_of(NOT_POSITIVE, st.just(1e-9), st.just(1e300)), "dt": st.one_of(NOT_POSITIVE, st.just(1.0)),
    "command": st.one_of(NON_FINITE, st.just(99.0), st.just(-1.0), st.text(min_size=1, max_size=3), JUNK.filter(
        lambda v: v is not None)),
    "switch_rate": st.one_of(NOT_POSITIVE, st.just(1e9)),
    "rng": st.one_of(st.integers(max_value=-1), st.floats(), st.text(max_size=3), st.just([1.5]), st.just(object())),
}


@SOME
@given(case=_valid_random(), arg=st.sampled_from(sorted(BAD_RANDOM)), data=st.data())
def test_random_test_bad_argument_is_named(case, arg, data):
    d, kw = case
    kw[arg] = data.draw(BAD_RANDOM[arg], label=arg)
    if arg == "switch_rate":
        kw.pop("command", None)
    if arg == "command" and kw[arg] is None:
        return
    with pytest.raises(ValueError) as info:
        random_test(d, **kw)
    assert_names(info.value, arg)


@SOME
@given(data=st.data())
def test_simulate_any_record(data):
    d = _rig_damper(data)
    c = d.command
    n = data.draw(st.integers(0, 60))
    x = data.draw(st.one_of(
        arrays(np.float64, st.sampled_from([(n,), (2, n), (1, n)]), elements=st.floats(-0.05, 0.05)),
        arrays(np.float64, st.sampled_from([(n,), (2, 2, n)]), elements=st.floats()), ANY_SCALAR), label="x")
    command = data.draw(st.one_of(st.floats(c.v_min, c.v_max), st.lists(st.floats(c.v_min, c.v_max), min_size=1,
                                                                        max_size=2), ANY_SCALAR,
                                  arrays(np.float64, st.sampled_from([(n,), (2, n)]), elements=st.floats())),
                        label="command")
    dt = data.draw(st.one_of(st.floats(1e-4, 1e-2), ANY_SCALAR), label="dt")
    v = data.draw(st.one_of(st.none(), arrays(np.float64, st.sampled_from([(n,), (3,)]), elements=st.floats()), JUNK),
                  label="v")
    try:
        rs = simulate(d, x, command, dt, v)
    except ValueError as e:
        assert_names(e, "x", "command", "dt", "v", "a")
        return
    except SimulationDivergedError:
        return
    for r in rs:
        assert len(r.t) == np.shape(x)[-1] and all_finite(r.force, r.u, r.v)


def test_rig_damper_argument_is_named():
    for bad in ("nope", 3, None, ["spencer_dyke"]):
        with pytest.raises(ValueError) as info:
            sinusoidal_test(bad, 0.01, 2.0, [0.0])
        assert_names(info.value, "damper", "damper model")


# --- environments: options and actions -----------------------------------------------------------------------------

STEP_LIMIT = 40


def _run_env(env_id: str, options: dict, seed: int = 0) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make(env_id, **options)
        try:
            obs, _ = env.reset(seed=seed)
            assert all_finite(obs) and env.observation_space.contains(obs)
            u = env.unwrapped
            lo, hi = u.command_spec.v_min, u.command_spec.v_max
            rng = np.random.default_rng(seed)
            for _ in range(STEP_LIMIT):
                a = rng.uniform(-2.0, 2.0, env.action_space.shape) * max(abs(hi), 1.0)
                obs, r, term, trunc, info = env.step(a)
                assert all_finite(obs, r) and obs.shape == env.observation_space.shape
                assert np.all(u.command >= lo) and np.all(u.command <= hi)
                if term or trunc:
                    if "episode_metrics" in info:
                        assert all_finite(list(info["episode_metrics"].values()))
                    break
        finally:
            env.close()


def _common_good(draw, sensor_names) -> dict:
    opts = {}
    dt, control_dt = draw(st.sampled_from([(1e-3, 1e-3), (1e-3, 2e-3), (5e-4, 1e-3), (1e-3, 1e-2), (2e-3, 4e-3)]))
    if draw(st.booleans()):
        opts.update(dt=dt, control_dt=control_dt)
    opts["episode_seconds"] = draw(st.floats(0.05, 0.2))
    if draw(st.booleans()):
        sensors = draw(st.lists(st.sampled_from(sensor_names), unique=True, min_size=1, max_size=4))
        opts["sensors"] = sensors
        if draw(st.booleans()):
            opts["sensor_noise"] = {s: draw(st.floats(0.0, 0.1)) for s in sensors[:2]}
    for key, strat in (("sensor_delay", st.integers(0, 3)),
                       ("action_mode", st.sampled_from(["physical", "normalized"])),
                       ("stroke_limit", st.one_of(st.none(), st.floats(0.02, 1.0))),
                       ("render_mode", st.sampled_from([None, "rgb_array"]))):
        if draw(st.booleans()):
            opts[key] = draw(strat)
    if draw(st.booleans()):
        name = draw(st.sampled_from(DAMPERS))
        opts["damper"] = name
        opts["damper_preset"] = draw(st.one_of(st.none(), st.sampled_from(sorted(damper_class(name).presets))))
    return opts


QC_SENSORS = ["sprung_acc", "unsprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel", "damper_force",
              "command", "road", "damper_states"]
SB_SENSORS = ["abs_acc", "drift", "floor_vel", "floor_disp", "damper_force", "damper_stroke", "damper_velocity",
              "ground_acc", "command", "damper_states"]


@st.composite
def _qc_good(draw):
    opts = _common_good(draw, QC_SENSORS)
    if draw(st.booleans()):
        opts["reward_weights"] = draw(st.dictionaries(st.sampled_from(["comfort", "travel", "tyre", "termination"]),
                                                      st.floats(0.0, 10.0)))
    opts["plant_preset"] = draw(st.sampled_from(["set_a", "set_b", "set_c"]))
    if draw(st.booleans()):
        opts["plant_params"] = {"m_s": draw(st.floats(150.0, 500.0))}
    road = draw(st.sampled_from(["iso8608", "bump", "sine_sweep"]))
    opts["road"] = road
    opts["road_params"] = draw({
        "iso8608": st.fixed_dictionaries({}, optional={"road_class": st.sampled_from(list("ABCDEFGH")),
                                                       "speed": st.floats(5.0, 30.0)}),
        "bump": st.fixed_dictionaries({}, optional={"height": st.floats(-0.05, 0.1), "length": st.floats(0.3, 2.0),
                                                    "speed": st.floats(2.0, 20.0), "t_start": st.floats(0.0, 0.1)}),
        "sine_sweep": st.fixed_dictionaries({}, optional={"amplitude": st.floats(1e-3, 0.02),
                                                          "f_start": st.floats(0.5, 2.0), "f_end": st.floats(2.0, 20.0)}),
    }[road])
    return opts


@st.composite
def _sb_good(draw):
    opts = _common_good(draw, SB_SENSORS)
    if draw(st.booleans()):
        opts["reward_weights"] = draw(st.dictionaries(st.sampled_from(["drift", "acc", "termination"]),
                                                      st.floats(0.0, 10.0)))
    if draw(st.booleans()):
        opts["damper_floors"] = draw(st.sampled_from([1, 2, 3, (1, 2), [1, 2, 3]]))
    gm = draw(st.sampled_from(["el_centro", "kanai_tajimi", "peer:el_centro_1940_270"]))
    opts["ground_motion"] = gm
    scales = {"time_scale": st.floats(0.1, 1.0), "amplitude_scale": st.floats(0.1, 2.0)}
    opts["ground_motion_params"] = draw({
        "el_centro": st.fixed_dictionaries({}, optional={"component": st.sampled_from(["NS", "EW", "UP"]), **scales}),
        "kanai_tajimi": st.fixed_dictionaries({}, optional={"pga": st.floats(0.5, 5.0), "zeta_g": st.floats(0.1, 1.0),
                                                            **scales}),
        "peer:el_centro_1940_270": st.fixed_dictionaries({}, optional=scales),
    }[gm])
    return opts


@FEW
@given(options=_qc_good())
def test_quarter_car_valid_options_run_finite(options):
    _run_env(QC, options)


@FEW
@given(options=_sb_good())
def test_building_valid_options_run_finite(options):
    _run_env(SB, options)


_OVERFLOW_INT = 10 ** 400
COMMON_BAD = {
    "dt": [0.0, -1e-3, math.nan, math.inf, "x", None, 0.5, 1 + 1j, [1e-3], _OVERFLOW_INT, 1e-300],
    "control_dt": [0.0, -1.0, math.nan, 1.5e-3, "x", None, _OVERFLOW_INT, 1e300],
    "episode_seconds": [0.0, -1.0, math.nan, math.inf, "x", 1e-4, _OVERFLOW_INT],
    "sensors": [[], ["nope"], 3, [1], ["command", "command"], "nope", [None]],
    "sensor_noise": [{"nope": 0.1}, {"command": -1.0}, {"command": math.nan}, {"command": "x"}, 5, [0.1],
                     {"command": None}, {"command": [0.1] * 4}, {"command": 1j}, {"command": {"a": 1}},
                     {"command": [1.0, [2.0]]}, {"command": _OVERFLOW_INT}],
    "sensor_delay": [-1, 1.5, "1", True, None, _OVERFLOW_INT],
    "action_mode": ["x", None, 1, "Physical", ["physical"]],
    "inverse": ["nope", 3, {"kind": "nope"}, {"kind": "model", "n_grids": 3}, ["model"]],   # in force mode
    "force_range": [0.0, -1.0, math.nan, math.inf, "x", _OVERFLOW_INT, 1j],
    "stroke_limit": [0.0, -1.0, math.nan, math.inf, "x", _OVERFLOW_INT, 1j],
    "damper": ["nope", 3, None, ["spencer_dyke"]],
    "damper_preset": ["nope", 3, ["spencer1997"]],
    "damper_params": [{"nope": 1.0}, {"c0a": -1.0}, {"c0a": math.nan}, 5, {"c0a": "x"}, {"c0a": _OVERFLOW_INT},
                      {1: 2.0}],
    "render_mode": ["x", 3, "HUMAN", ["human"]],
}
QC_BAD = {
    **COMMON_BAD,
    "reward_weights": [{"nope": 1.0}, {"comfort": -1.0}, {"travel": math.nan}, {"tyre": "x"}, 3, [1.0],
                       {"comfort": _OVERFLOW_INT}, {1: 1.0, "a": 1.0}],
    "plant_preset": ["nope", 3, None, ["set_a"]],
    "plant_params": [{"nope": 1.0}, {"m_s": -1.0}, {"m_s": math.nan}, 5, {"m_s": "x"}, {"m_s": _OVERFLOW_INT},
                     {1: 2.0}],
    "road": ["nope", 3, ["bump"]],  # None is the default road
    "road_params": [{"nope": 1.0}, {"speed": -1.0}, {"road_class": "Z"}, 5, {"speed": math.nan}, {"speed": "x"},
                    {"road_class": 3}, {"method": "x"}, {"road_class": "C", "speed": 1e6}],
}
SB_BAD = {
    **COMMON_BAD,
    "reward_weights": [{"nope": 1.0}, {"drift": -1.0}, {"acc": math.nan}, 3],
    "plant_preset": ["nope", 3, ["three_storey"]],
    "plant_params": [{"nope": 1.0}, {"masses": (98.3, -1.0, 98.3)}, {"damper_floors": (9,)}, 5],
    "damper_floors": [0, 4, (1.5,), "a", [], 1.5, [None], (0, 1), True, "12", {"a": 1}],
    "ground_motion": ["nope", "peer:nope", 3, ["el_centro"]],  # None is the default record
    "ground_motion_params": [{"nope": 1.0}, {"time_scale": -1.0}, {"component": "XX"}, {"amplitude_scale": math.nan},
                             5, {"time_scale": "x"}, {"source": "nope"}, {"component": ["NS"]}],
}


def _names_for(option: str, value) -> tuple[str, ...]:
    """What a message about ``option=value`` may name: the option, or the key of a dict option it is about."""
    inner = tuple(str(k) for k in value) if isinstance(value, dict) else ()
    alias = {"plant_preset": ("preset",), "damper": ("damper model",), "damper_preset": ("preset",),
             "sensors": ("sensor",), "road": (), "ground_motion_params": ("component", "source"),
             "plant_params": ("QuarterCarParams", "ShearBuildingParams")}.get(option, ())
    return (option, *alias, *inner)


def _check_bad_option(env_id: str, base: dict, option: str, value) -> None:
    options = {**base, option: value}
    if option == "damper_params":
        options.pop("damper", None)
        options.pop("damper_preset", None)
    if option == "damper_preset":
        options.pop("damper", None)
    if option == "sensor_noise":
        options.pop("sensors", None)
    if option in ("dt", "control_dt"):
        options.pop("dt" if option == "control_dt" else "control_dt", None)
    if option in ("inverse", "force_range"):
        options["action_mode"] = "force"
    with pytest.raises(ValueError) as info:
        if option == "render_mode" and not isinstance(value, str):
            # gymnasium.make itself calls render_mode.endswith() before the environment sees it
            from mrd_env.plants import QuarterCarEnv, ShearBuildingEnv
            (QuarterCarEnv if env_id == QC else ShearBuildingEnv)(**options)
        else:
            _run_env(env_id, options)
    assert_names(info.value, *_names_for(option, value))


def _case_id(option: str, value) -> str:
    return f"{option}={value!r}".replace(repr(_OVERFLOW_INT), "10**400")


def _bad_cases(table: dict) -> list:
    return [pytest.param(k, v, id=_case_id(k, v)) for k, vs in table.items() for v in vs]


QC_OK = _bad_cases(QC_BAD)
SB_OK = _bad_cases(SB_BAD)


@pytest.mark.parametrize("env_id, options", [(QC, {"road": "iso8608"}), (SB, {"ground_motion": "kanai_tajimi"})])
def test_huge_episode_of_a_generated_disturbance_is_named(env_id, options):
    with pytest.raises(ValueError) as info:
        _run_env(env_id, {**options, "episode_seconds": 1e300})
    assert_names(info.value, "episode_seconds")


@pytest.mark.parametrize("ground_motion, params", [
    ("el_centro", {"time_scale": 1e-300}),
    ("kanai_tajimi", {"time_scale": 1e-300}),
    ("el_centro", {"amplitude_scale": 1e300}),
])
def test_building_extreme_ground_motion_scale_is_named(ground_motion, params):
    with pytest.raises(ValueError) as info:
        _run_env(SB, {"ground_motion": ground_motion, "ground_motion_params": params, "episode_seconds": 0.1})
    assert_names(info.value, *params)


@pytest.mark.parametrize("option, value", QC_OK)
@settings(max_examples=3, deadline=None)
@given(base=_qc_good())
def test_quarter_car_bad_option_is_named(option, value, base):
    _check_bad_option(QC, base, option, value)


@pytest.mark.parametrize("option, value", SB_OK)
@settings(max_examples=3, deadline=None)
@given(base=_sb_good())
def test_building_bad_option_is_named(option, value, base):
    _check_bad_option(SB, base, option, value)


_ACTION_SHAPES = st.sampled_from([(), (1,), (2,), (3,), (1, 1), (0,)])
ACTIONS = st.one_of(
    st.floats(), st.integers(-10, 10), HUGE, JUNK, st.booleans(),
    arrays(st.sampled_from([np.float64, np.float32, np.complex128]), _ACTION_SHAPES,
           elements=st.floats(-5, 5, width=32) | NON_FINITE),
    arrays(st.sampled_from([np.int64, np.uint8, np.bool_]), _ACTION_SHAPES),
    st.lists(st.floats(-5, 5), min_size=1, max_size=3))


def _expected_command(env, action) -> np.ndarray | None:
    """The physical command an accepted action must give (in force mode: the range it must lie in, (lo, hi)),
    or None if it must be refused."""
    u = env.unwrapped
    nd = u.n_dampers
    try:
        a = np.asarray(action)
    except Exception:
        return None
    if a.dtype.kind not in "fiu":
        return None
    a = a.astype(np.float64)
    if nd == 1 and a.ndim == 0:
        a = a.reshape(1)
    if a.shape != (nd,) or not np.all(np.isfinite(a)):
        return None
    lo, hi = u.command_spec.v_min, u.command_spec.v_max
    if u.action_mode == "force":  # the inverse's command: any in the range
        return np.array([lo, hi])
    if u.action_mode == "normalized":
        return np.clip(lo + (np.clip(a, -1.0, 1.0) + 1.0) * 0.5 * (hi - lo), lo, hi)
    return np.clip(a, lo, hi)


_ENVS: dict = {}


def _env(env_id, mode, floors):
    key = (env_id, mode, floors)
    if key not in _ENVS:
        opts = {"action_mode": mode, "episode_seconds": 0.5}
        if env_id == SB:
            opts["damper_floors"] = floors
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _ENVS[key] = gym.make(env_id, **opts)
    return _ENVS[key]


def _ragged(action) -> bool:
    try:
        np.asarray(action)
        return False
    except ValueError:
        return True


def _check_action(env_id, mode, floors, action) -> None:
    env = _env(env_id, mode, floors if env_id == SB else (1,))
    env.reset(seed=0)
    expected = _expected_command(env, action)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            obs, r, term, trunc, info = env.step(action)
        except ValueError as e:
            assert expected is None, f"a valid action {action!r} was refused: {e}"
            assert_names(e, "action")
            return
    assert expected is not None, f"the invalid action {action!r} was accepted"
    if mode == "force":
        assert np.all((env.unwrapped.command >= expected[0]) & (env.unwrapped.command <= expected[1]))
    else:
        np.testing.assert_allclose(env.unwrapped.command, expected, rtol=0, atol=1e-12)
    assert all_finite(obs, r)


@MANY
@given(env_id=st.sampled_from([QC, SB]), mode=st.sampled_from(["physical", "normalized", "force"]),
       floors=st.sampled_from([(1,), (1, 2)]), action=ACTIONS)
def test_step_any_action(env_id, mode, floors, action):
    assume(not _ragged(action))  # an environment defect, pinned below
    _check_action(env_id, mode, floors, action)


@pytest.mark.parametrize("env_id", [QC, SB])
def test_step_ragged_action_is_named(env_id):
    _check_action(env_id, "physical", (1,), [1.0, [2.0]])


# --- record loaders --------------------------------------------------------------------------------------------------

_COUNTER = iter(range(10 ** 9))


@pytest.fixture(scope="module")
def tmp_dir(tmp_path_factory) -> Path:
    """One folder for all examples (hypothesis runs many examples per call of a function-scoped fixture)."""
    return tmp_path_factory.mktemp("records")
HEADER_NAME = st.text(alphabet="abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_", min_size=1, max_size=6)


def _write(folder: Path, content: bytes | str, suffix: str = ".csv") -> Path:
    path = folder / f"f{next(_COUNTER)}{suffix}"
    if isinstance(content, str):
        path.write_text(content, encoding="utf-8")
    else:
        path.write_bytes(content)
    return path


@st.composite
def _tables(draw):
    """A valid table: (header names per role, units per role, values per role, separator, extra columns)."""
    n = draw(st.integers(3, 12))
    roles = ["t", "x", "command", "force"] + (["v"] if draw(st.booleans()) else [])
    names = draw(st.lists(HEADER_NAME, unique=True, min_size=len(roles) + 1, max_size=len(roles) + 2))
    columns = dict(zip(roles, names))
    extra = names[len(roles):]
    units = {r: draw(st.sampled_from(sorted(UNITS[r]))) for r in roles}
    steps = draw(arrays(np.float64, n - 1, elements=st.floats(1e-3, 1.0)))
    t0 = draw(st.floats(-10.0, 10.0))
    values = {"t": np.concatenate([[t0], t0 + np.cumsum(steps)])}
    for r in roles[1:]:
        values[r] = draw(arrays(np.float64, n, elements=st.floats(-1e6, 1e6)))
    for e in extra:  # columns that are not chosen are never parsed
        values["extra:" + e] = draw(st.lists(st.sampled_from(["", "n/a", "1.5"]), min_size=n, max_size=n))
    sep = draw(st.sampled_from([",", ";", "\t"]))
    return columns, units, values, sep, extra


def _render(columns, values, sep, extra, mutate=None) -> str:
    head = list(columns.values()) + extra
    keys = list(columns) + ["extra:" + e for e in extra]
    rows = [[repr(float(values[k][i])) if k in columns else values[k][i] for k in keys]
            for i in range(len(values["t"]))]
    if mutate is not None:
        mutate(head, rows)
    return "\n".join(sep.join(r) for r in [head] + rows) + "\n"


@SOME
@given(table=_tables())
def test_load_record_csv_valid_tables_round_trip(table, tmp_dir):
    columns, units, values, sep, extra = table
    path = _write(tmp_dir, _render(columns, values, sep, extra))
    rec = load_record_csv(path, columns, units)
    for role in columns:
        got = rec.v if role == "v" else getattr(rec, role)
        np.testing.assert_array_equal(got, np.asarray(values[role]) * UNITS[role][units[role]])
    assert rec.command_unit == {"mV": "V", "mA": "A"}.get(units["command"], units["command"])


def _cell_mutation(kind, role_index, row, text):
    def mutate(head, rows):
        r = rows[min(row, len(rows) - 1)]
        r[role_index] = {"missing": "", "text": text, "nonfinite": "nan", "inf": "-inf"}[kind]
    return mutate


FILE_DEFECTS = st.sampled_from(["missing", "text", "nonfinite", "inf", "one_row", "header_only", "empty", "binary",
                                "nul", "ragged", "duplicate_header", "time_not_increasing", "comma_decimal",
                                "folder", "missing_file", "single_column"])


@SOME
@given(table=_tables(), defect=FILE_DEFECTS, data=st.data())
def test_load_record_csv_bad_files_name_the_file(table, defect, data, tmp_dir):
    columns, units, values, sep, extra = table
    roles = list(columns)
    j = data.draw(st.integers(0, len(roles) - 1), label="column")
    row = data.draw(st.integers(0, 20), label="row")
    if defect in ("missing", "text", "nonfinite", "inf"):
        text = data.draw(st.text(alphabet="abcxyz-+/ ", min_size=1, max_size=5).filter(
            lambda s: s.strip() and s.strip().lower() not in ("nan", "inf", "-inf", "+inf")))
        content = _render(columns, values, sep, extra, _cell_mutation(defect, j, row, text))
    elif defect == "one_row":
        content = _render(columns, {k: v[:1] for k, v in values.items()}, sep, extra)
    elif defect == "header_only":
        content = sep.join(list(columns.values()) + extra) + "\n"
    elif defect == "empty":
        content = data.draw(st.sampled_from(["", "\n\n", "  \n"]))
    elif defect == "binary":
        # 0xFF never occurs in UTF-8 text
        content = data.draw(st.tuples(st.binary(max_size=32), st.binary(max_size=32)).map(
            lambda ab: ab[0] + b"\xff" + ab[1]))
    elif defect == "nul":
        content = _render(columns, values, sep, extra).replace(sep, "\x00" + sep, 1)
    elif defect == "ragged":
        content = _render(columns, values, sep, extra, lambda h, rows: rows[min(row, len(rows) - 1)].extend(["1", "2"]))
    elif defect == "duplicate_header":
        content = _render(columns, values, sep, extra, lambda h, rows: (h.append(h[j]), [r.append("0") for r in rows]))
    elif defect == "time_not_increasing":
        def swap(h, rows):
            k = min(row, len(rows) - 2)
            rows[k][0], rows[k + 1][0] = rows[k + 1][0], rows[k][0]
        content = _render(columns, values, sep, extra, swap)
    elif defect == "comma_decimal":
        content = _render(columns, values, ";", extra).replace(".", ",")
    elif defect == "single_column":
        content = _render(columns, values, " ", extra)
    else:
        content = None
    if defect == "folder":
        path = tmp_dir / f"folder{next(_COUNTER)}"
        path.mkdir()
    elif defect == "missing_file":
        path = tmp_dir / f"missing{next(_COUNTER)}.csv"
    else:
        path = _write(tmp_dir, content)
    with pytest.raises(ValueError) as info:
        load_record_csv(path, columns, units)
    assert str(path) in str(info.value), str(info.value)
    with pytest.raises(ValueError) as info:
        DamperRecord.read_csv(path)
    assert str(path) in str(info.value), str(info.value)


MAP_DEFECTS = st.sampled_from(["unknown_role", "missing_role", "absent_column", "not_a_dict", "bad_unit",
                               "missing_unit", "extra_unit", "unit_not_text", "units_not_a_dict", "column_not_text"])


@SOME
@given(table=_tables(), defect=MAP_DEFECTS, data=st.data())
def test_read_columns_bad_column_maps_are_named(table, defect, data, tmp_dir):
    columns, units, values, sep, extra = table
    path = _write(tmp_dir, _render(columns, values, sep, extra))
    role = data.draw(st.sampled_from(["t", "x", "command", "force"]), label="role")
    cols, us = dict(columns), dict(units)
    junk = data.draw(st.one_of(JUNK, st.integers(), st.just(("a", "b"))), label="junk")
    if defect == "unknown_role":
        cols["speed"] = extra[0]
        names = ("columns", "speed")
    elif defect == "missing_role":
        del cols[role]
        us.pop(role)
        names = ("columns", role)
    elif defect == "absent_column":
        cols[role] = "zz" + cols[role]
        names = (cols[role],)
    elif defect == "not_a_dict":
        cols = junk if not isinstance(junk, dict) else list(cols.items())
        names = ("columns",)
    elif defect == "bad_unit":
        us[role] = data.draw(st.text(max_size=4).filter(lambda s: s not in UNITS[role]))
        names = ("units",)
    elif defect == "missing_unit":
        del us[role]
        names = ("units",)
    elif defect == "extra_unit":
        if "v" in cols:
            del cols["v"]
        us["v"] = "m/s"
        names = ("units",)
    elif defect == "unit_not_text":
        us[role] = junk if not isinstance(junk, str) else ["m"]
        names = ("units",)
    elif defect == "units_not_a_dict":
        us = junk if not isinstance(junk, dict) else list(us.items())
        names = ("units",)
    else:
        cols[role] = junk if not isinstance(junk, str) else 3
        names = ("columns", role)
    with pytest.raises(ValueError) as info:
        read_columns(path, cols, us)
    assert_names(info.value, *names)
    with pytest.raises(ValueError) as info:
        load_record_csv(path, cols, us)
    assert_names(info.value, *names)


@SOME
@given(path=st.one_of(st.none(), st.integers(), st.floats(), st.just(["a.csv"]), st.just(b"\x00"), st.just("")))
def test_record_loaders_reject_a_path_that_is_not_a_file(path):
    cols = {"t": "t", "x": "x", "command": "c", "force": "F"}
    units = {"t": "s", "x": "m", "command": "V", "force": "N"}
    for call in (lambda: load_record_csv(path, cols, units), lambda: read_columns(path, cols, units),
                 lambda: DamperRecord.read_csv(path)):
        with pytest.raises(ValueError) as info:
            call()
        assert_names(info.value, "path", str(path))


COLUMN = st.one_of(arrays(np.float64, st.integers(0, 8), elements=st.floats()),
                   arrays(np.float64, st.integers(3, 8), elements=st.floats(-10, 10)),
                   st.lists(st.floats(), max_size=6), ANY_SCALAR)


@SOME
@given(data=st.data())
def test_damper_record_any_columns(data):
    n = data.draw(st.integers(3, 8), label="n")
    t_good = np.cumsum(data.draw(arrays(np.float64, n, elements=st.floats(1e-3, 1.0)), label="steps"))
    good = st.just(np.zeros(n))
    kw = {"t": data.draw(st.one_of(st.just(t_good), COLUMN), label="t")}
    for k in ("x", "command", "force"):
        kw[k] = data.draw(st.one_of(good, COLUMN), label=k)
    kw["v"] = data.draw(st.one_of(st.none(), good, COLUMN), label="v")
    kw["command_unit"] = data.draw(st.one_of(st.sampled_from(["V", "A"]), ANY_SCALAR), label="command_unit")
    try:
        rec = DamperRecord(**kw)
    except ValueError as e:
        assert_names(e, *(f"column '{k}'" for k in ("t", "x", "command", "force", "v")), "command_unit")
        return
    assert rec.command_unit in ("V", "A")
    assert all_finite(rec.t, rec.x, rec.command, rec.force, rec.velocity())
    assert np.all(np.diff(rec.t) > 0)


# --- disturbance generators ------------------------------------------------------------------------------------------

def _maybe(valid: st.SearchStrategy) -> st.SearchStrategy:
    """Mostly valid values, sometimes anything."""
    return st.one_of(valid, valid, ANY_SCALAR)


def _check_record(rec: Record, duration=None, dt=None) -> None:
    assert isinstance(rec, Record) and all_finite(rec.data) and rec.n_samples >= 2
    if duration is not None:
        assert rec.n_samples == n_samples_for(float(duration), float(dt))


@SOME
@given(data=st.data())
def test_iso8608_road_any_arguments(data):
    kw = {
        "road_class": data.draw(st.one_of(st.sampled_from(list("ABCDEFGHabc")), ANY_SCALAR), label="road_class"),
        "speed": data.draw(_maybe(st.floats(1.0, 40.0)), label="speed"),
        "duration": data.draw(sized(st.floats(0.01, 0.5)), label="duration"),
        "dt": data.draw(sized(st.floats(2e-4, 4e-3)), label="dt"),
        "rng": data.draw(st.one_of(st.none(), st.integers(0, 2 ** 32), st.integers(max_value=-1), JUNK), label="rng"),
    }
    for k, strat in (("n_min", st.floats(1e-3, 0.1)), ("n_max", st.floats(0.5, 3.0)), ("waviness", st.floats(1.0, 3.5)),
                     ("method", st.sampled_from(["sinusoids", "fft", "nope"])),
                     ("n_waves", st.one_of(st.none(), st.integers(1, 300)))):
        if k == "n_waves":  # a size: junk or out of range, never a valid but slow count
            kw[k] = data.draw(st.one_of(strat, strat, st.sampled_from([0, -1, 1.5, "x", True, 10 ** 7, 10 ** 400])),
                              label=k) if data.draw(st.booleans(), label=f"give {k}") else None
            continue
        if data.draw(st.booleans(), label=f"give {k}"):
            kw[k] = data.draw(_maybe(strat), label=k)
    if kw.get("method") == "fft":
        kw.pop("n_waves", None)
    try:
        rec = iso8608_road(**kw)
    except ValueError as e:
        assert_names(e, *kw)
        return
    _check_record(rec, kw["duration"], kw["dt"])


@SOME
@given(data=st.data())
def test_bump_any_arguments(data):
    kw = {"height": data.draw(_maybe(st.floats(-0.1, 0.1)), label="height"),
          "length": data.draw(_maybe(st.floats(0.1, 2.0)), label="length"),
          "speed": data.draw(_maybe(st.floats(1.0, 30.0)), label="speed"),
          "t_start": data.draw(sized(st.floats(0.0, 0.2)), label="t_start"),
          "duration": data.draw(st.one_of(st.none(), sized(st.floats(0.1, 0.5))), label="duration"),
          "dt": data.draw(sized(st.floats(1e-4, 1e-2)), label="dt")}
    try:
        rec = bump(**kw)
    except ValueError as e:
        assert_names(e, *kw)
        return
    _check_record(rec)


@SOME
@given(data=st.data())
def test_sine_sweep_any_arguments(data):
    kw = {"amplitude": data.draw(_maybe(st.floats(1e-4, 0.05)), label="amplitude"),
          "f_start": data.draw(_maybe(st.floats(0.1, 50.0)), label="f_start"),
          "f_end": data.draw(_maybe(st.floats(0.1, 50.0)), label="f_end"),
          "duration": data.draw(sized(st.floats(0.01, 0.5)), label="duration"),
          "dt": data.draw(sized(st.floats(1e-4, 5e-3)), label="dt"),
          "kind": data.draw(st.one_of(st.sampled_from(["log", "linear"]), ANY_SCALAR), label="kind")}
    try:
        rec = sine_sweep(**kw)
    except ValueError as e:
        assert_names(e, *kw)
        return
    _check_record(rec, kw["duration"], kw["dt"])


@SOME
@given(data=st.data())
def test_kanai_tajimi_any_arguments(data):
    kw = {"duration": data.draw(sized(st.floats(0.05, 0.5)), label="duration"),
          "dt": data.draw(sized(st.floats(1e-4, 5e-3)), label="dt"),
          "omega_g": data.draw(_maybe(st.floats(1.0, 60.0)), label="omega_g"),
          "zeta_g": data.draw(_maybe(st.floats(0.05, 2.0)), label="zeta_g"),
          "rng": data.draw(st.one_of(st.integers(0, 2 ** 32), st.integers(max_value=-1), JUNK), label="rng")}
    intensity = data.draw(st.sampled_from(["pga", "S0", "both", "neither"]), label="intensity")
    if intensity in ("pga", "both"):
        kw["pga"] = data.draw(_maybe(st.floats(0.1, 10.0)), label="pga")
    if intensity in ("S0", "both"):
        kw["S0"] = data.draw(_maybe(st.floats(1e-4, 1.0)), label="S0")
    env_kind = data.draw(st.one_of(st.sampled_from(["jennings", "saragoni_hart", None]), ANY_SCALAR), label="env")
    kw["envelope"] = env_kind
    if data.draw(st.booleans(), label="give envelope_params"):
        keys = {"jennings": ["t1", "t2", "c"], "saragoni_hart": ["eps", "eta", "tw"]}.get(
            env_kind if isinstance(env_kind, str) else None, ["t1", "eps"])
        kw["envelope_params"] = data.draw(st.one_of(
            st.dictionaries(st.sampled_from(keys + ["nope"]), _maybe(st.floats(0.01, 0.9)), max_size=2), JUNK),
            label="envelope_params")
    try:
        rec = kanai_tajimi(**kw)
    except ValueError as e:
        ep = kw.get("envelope_params")
        assert_names(e, *kw, "pga", "S0", *(ep if isinstance(ep, dict) else ()))
        return
    assert (kw.get("pga") is None) != (kw.get("S0") is None)
    _check_record(rec, kw["duration"], kw["dt"])
    if kw.get("pga") is not None:
        assert np.max(np.abs(rec.data)) == pytest.approx(float(kw["pga"]), rel=1e-9)


_SOURCE = Record(0.01, np.sin(np.arange(50) * 0.3)[:, None], ("xg_ddot",), ("m/s^2",), "source")
_ROAD = Record(0.01, np.c_[np.sin(np.arange(50) * 0.3), np.cos(np.arange(50) * 0.3)], ("z_r", "zdot_r"),
               ("m", "m/s"))


@SOME
@given(record=st.one_of(st.just(_SOURCE), st.just(_ROAD), JUNK),
       time_scale=sized(st.floats(0.1, 5.0)), amplitude_scale=_maybe(st.floats(0.01, 100.0)),
       dt=st.one_of(st.none(), sized(st.floats(1e-3, 0.05))))
def test_scale_record_any_arguments(record, time_scale, amplitude_scale, dt):
    try:
        rec = scale_record(record, time_scale, amplitude_scale, dt)
    except ValueError as e:
        assert_names(e, "record", "time_scale", "amplitude_scale", "dt")
        return
    _check_record(rec)
    assert rec.channels == record.channels


# --- identification: the command dynamics and fault detection -----------------------------------------------------

@SOME
@given(v=arrays(np.float64, st.integers(2, 200), elements=st.floats(0.0, 2.0)), u0=st.floats(0.0, 2.0),
       eta=st.floats(1.0, 1e4), eta_fall=st.one_of(st.none(), st.floats(1.0, 1e4)), delay=st.floats(0.0, 0.02),
       dt=st.floats(1e-5, 1e-2))
def test_effective_command_stays_between_the_commands(v, u0, eta, eta_fall, delay, dt):
    from mrd_env.command_lag import effective_command
    from mrd_env.dampers import CommandSpec

    u = effective_command(CommandSpec("V", 0.0, 2.0, eta, eta_fall, delay), v, dt, u0)
    lo, hi = min(v.min(), u0), max(v.max(), u0)
    assert u.shape == v.shape and all_finite(u) and u[0] == u0
    assert np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12)


@SOME
@given(n=st.integers(3, 400), seed=st.integers(0, 2 ** 32 - 1), with_v=st.booleans(),
       clip=st.floats(0.2, 1.0), spikes=st.integers(0, 3))
def test_find_faults_spans_lie_in_the_record(n, seed, with_v, clip, spikes):
    from mrd_env.identification import find_faults

    g = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    x = np.cumsum(g.standard_normal(n)) * 1e-4
    F = np.minimum(g.standard_normal(n) * 100, clip * 300)
    for k in g.integers(0, n, spikes):
        F[k] += 1e5
    r = DamperRecord(t, x, np.zeros(n), F, g.standard_normal(n) if with_v else None)
    found = find_faults(r)
    for f in found:  # in order, apart; a segment holds its parts
        assert f.kind in ("saturation", "spike", "gap", "run-away", "segment")
        assert set(f.channel.split("+")) <= {"x", "v", "force", "t"}
        assert 0 <= f.i0 <= f.i1 < n and f.start == t[f.i0] and f.end == t[f.i1]
        assert all(f.i0 <= p.i0 <= p.i1 <= f.i1 for p in f.parts)
    assert all(a.i1 < b.i0 for a, b in zip(found, found[1:]))
    assert [p for f in found for p in (f.parts or (f,))] == find_faults(r, merge_gap=0)


@FEW
@given(arg=st.sampled_from(["saturation_duration", "saturation_tol", "clip_samples", "spike_threshold",
                            "gap_factor"]), value=st.one_of(NOT_POSITIVE, st.just(0.5)))
def test_find_faults_refuses_bad_settings(arg, value):
    from mrd_env.identification import find_faults

    assume(not (arg in ("saturation_duration", "saturation_tol") and value == 0.5))
    r = DamperRecord(np.arange(5.0), np.zeros(5), np.zeros(5), np.arange(5.0))
    with pytest.raises(ValueError) as info:
        find_faults(r, **{arg: value})
    assert_names(info.value, arg)
