"""The standard criteria of issue 39, item 5, on synthetic records whose values are known in closed form: the time
and share beyond a limit (the environments' constraint costs and exceedance shares), the building's control power
(the benchmarks' peak and total control power), VDV. That the environments' online values equal these functions
on their own histories is tests/envs/test_online_metrics.py."""
import math

import numpy as np
import pytest

from mrd_env import metrics as M
from mrd_env.plants.quarter_car import metrics as QM
from mrd_env.plants.shear_building import metrics as BM

DT = 1e-4
F = 2.0  # Hz
T = 3.0  # s: six whole periods


def _t():
    return np.arange(int(round(T / DT)) + 1) * DT  # n = T/dt + 1 samples: the rows of a T-second episode


@pytest.mark.parametrize("ratio", [0.25, 0.5, 0.9])
def test_exceedance_of_a_sinusoid(ratio):
    """x = A sin(2πft) is beyond |x| > L for a share 1 − (2/π)·asin(L/A) of whole periods, above L (or below −L)
    for half that."""
    x = 0.03 * np.sin(2 * np.pi * F * _t())
    L = ratio * 0.03
    share = 1.0 - 2.0 / np.pi * math.asin(ratio)
    tol = 4 * F * DT  # a sample at each of the 4 crossings per period, at most
    assert M.exceedance_share(DT, x, L) == pytest.approx(share, abs=tol)
    assert M.exceedance_time(DT, x, L) == pytest.approx(share * T, abs=tol * T)
    assert M.exceedance_share(DT, x, L, "above") == pytest.approx(share / 2, abs=tol)
    assert M.exceedance_share(DT, x, L, "below") == pytest.approx(share / 2, abs=tol)
    # channels: any of them; a limit per channel
    two = np.column_stack([x, -x])
    assert M.exceedance_time(DT, two, L, "above") == M.exceedance_time(DT, x, L)
    assert M.exceedance_time(DT, two, [L, 10.0], "above") == M.exceedance_time(DT, x, L, "above")
    # the first sample is the initial state: not counted
    assert M.exceedance_time(DT, np.array([1.0, 0.0, 1.0]), 0.5) == DT


def test_exceedance_rejects_bad_limits_and_sides():
    x = np.zeros((10, 2))
    with pytest.raises(ValueError, match="side"):
        M.exceedance_time(DT, x, 1.0, "up")
    with pytest.raises(ValueError, match="limit"):
        M.exceedance_time(DT, x, 0.0)
    with pytest.raises(ValueError, match="limit"):
        M.exceedance_time(DT, x, [1.0, 2.0, 3.0])
    assert M.exceedance_share(DT, x[:1], 1.0) == 0.0


def test_control_power_of_sinusoids():
    """One damper, force in phase with its velocity (a dashpot): p = F0·V0·sin², peak F0·V0, mean F0·V0/2; a second
    one in quadrature (a spring-like force): |F0·V0·sin·cos|, mean F0·V0/π; their sum peaks at F0·V0·(1 + √2)/2."""
    t = _t()
    w = 2 * np.pi * F
    F0, V0 = 800.0, 0.05
    v = V0 * np.sin(w * t)
    one = BM.control_power(DT, F0 * np.sin(w * t), v)
    assert one["control_power_peak"] == pytest.approx(F0 * V0, rel=1e-9)
    assert one["control_power_total"] == pytest.approx(F0 * V0 * T / 2, rel=1e-9)  # exact over whole periods
    two = BM.control_power(DT, np.column_stack([F0 * np.sin(w * t), F0 * np.cos(w * t)]), np.column_stack([v, v]))
    assert two["control_power_peak"] == pytest.approx(F0 * V0 * (1 + math.sqrt(2)) / 2, rel=1e-6)
    assert two["control_power_total"] == pytest.approx(F0 * V0 * T * (0.5 + 1 / np.pi), rel=1e-6)
    with pytest.raises(ValueError, match="damper_velocity"):
        BM.control_power(DT, np.zeros((10, 2)), np.zeros((10, 1)))


def test_vdv_and_stroke_exceedance_of_a_sinusoidal_quarter_car_record():
    """VDV of a sinusoidal weighted acceleration A·sin: A·(3T/8)^¼; the travel's exceedance share as above."""
    t = _t()
    a_w = 1.5 * np.sin(2 * np.pi * F * t)
    assert M.vdv(a_w[1:], DT) == pytest.approx(1.5 * (3 * T / 8) ** 0.25, rel=1e-4)
    travel = 0.04 * np.sin(2 * np.pi * F * t)
    m = QM.quarter_car_metrics(DT, a_w, travel, soft_stroke_limit=0.02)
    assert m["stroke_exceedance_share"] == pytest.approx(1 - 2 / np.pi * math.asin(0.5), abs=4 * F * DT)
    assert "stroke_exceedance_share" not in QM.quarter_car_metrics(DT, a_w, travel)
    with pytest.raises(ValueError, match="soft_stroke_limit"):
        QM.quarter_car_metrics(DT, a_w, travel, soft_stroke_limit=-1.0)
