"""One container for a damper time series: the rig's output, a sensor readout and a loaded file are all
:class:`mrd_env.records.DamperRecord` and feed the identification interchangeably."""
import numpy as np
import pytest

from mrd_env import make_damper
from mrd_env.identification import DamperRecord, SensorSet, apply_sensors
from mrd_env.identification.prepare import prepare_record
from mrd_env.records import DamperRecord as Home
from mrd_env.rig import random_test, sinusoidal_test


def test_rig_output_sensor_readout_and_loaded_record_are_one_class(tmp_path):
    d = make_damper("bingham")
    rig = random_test(d, rms=0.004, bandwidth=8.0, duration=0.5, switch_rate=4.0, dt=2.5e-4, rng=1)
    readout = apply_sensors(rig.t, rig.x, rig.force, SensorSet(), 2, command=rig.command, label="readout")
    loaded = DamperRecord.read_csv(readout.to_csv(tmp_path / "readout.csv"))
    assert DamperRecord is Home
    assert type(rig) is type(readout) is type(loaded) is DamperRecord
    assert rig.model == "bingham" and rig.u is not None and readout.u is None
    assert readout.saturated_force is not None and loaded.saturated_force is None  # flags are not written
    preps = [prepare_record(r, d.command, dt=1e-3, faults="keep") for r in (rig, readout, loaded)]
    assert len({p.series.n for p in preps}) == 1
    for k in ("t", "x", "v", "command", "force"):  # the readout and its file prepare alike, bit for bit
        np.testing.assert_array_equal(getattr(preps[1].series, k), getattr(preps[2].series, k))
    np.testing.assert_array_equal(preps[1].a, preps[2].a)
    # the rig's record (resampled to the sensors' rate) and the readout describe the same test
    assert np.corrcoef(preps[0].series.force, preps[1].series.force)[0, 1] > 0.99


def test_the_rig_record_round_trips_and_its_helpers_apply_to_a_measured_record(tmp_path):
    r = sinusoidal_test("bouc_wen", 0.01, 2.0, [1.0], cycles=2)[0]
    path = r.to_csv(tmp_path / "rig.csv")
    assert path.read_text().splitlines()[0] == "t_s,x_m,v_m_per_s,command_V,u_V,force_N"
    back = DamperRecord.read_csv(path)
    for k in ("t", "x", "v", "command", "force"):
        np.testing.assert_array_equal(getattr(back, k), getattr(r, k))
    measured = DamperRecord(r.t, r.x, r.command, r.force)  # no velocity column: dx/dt
    sl = measured.steady_cycles(2.0)
    assert sl == r.steady_cycles(2.0)
    assert measured.dissipated_energy(sl) == pytest.approx(r.dissipated_energy(sl), rel=1e-3)


def test_optional_columns_are_validated_and_follow_selections():
    t = np.arange(20) * 1e-3
    x, F = np.sin(50 * t), np.cos(50 * t)
    flags = np.arange(20) % 7 == 0
    with pytest.raises(ValueError, match="column 'u'"):
        DamperRecord(t, x, 0 * t, F, u=x[:-1])
    with pytest.raises(ValueError, match="column 'u' has a non-finite value"):
        DamperRecord(t, x, 0 * t, F, u=np.where(t > 0.01, np.nan, 0.0))
    with pytest.raises(ValueError, match="column 'saturated_x' must be a 1-D boolean mask"):
        DamperRecord(t, x, 0 * t, F, saturated_x=flags.astype(float))
    r = DamperRecord(t, x, 0 * t, F, u=0.5 + 0 * t, saturated_force=flags, model="bingham")
    part = r.slice(0.005, 0.015)
    np.testing.assert_array_equal(part.saturated_force, flags[5:16])
    assert part.u.shape == (11,) and part.model == "bingham" and part.saturated_x is None
    coarse = r.resample(2e-3, antialias=False)
    np.testing.assert_array_equal(coarse.saturated_force, flags[::2])
    assert not coarse.u.flags.writeable
