"""The every-plant JAX benchmark's functions on the isolator (the smallest plant: the quickest compiles) over 2
control steps (a smoke test: the figures themselves come from the script's runs)."""
from __future__ import annotations

import pytest

pytest.importorskip("jax")

import mrd_env.jax  # noqa: E402,F401  (float64)
from experiments.measurements.speed import jax_plants as b  # noqa: E402

pytestmark = pytest.mark.xdist_group("jax")


def test_accuracy_rows_compare_the_exact_scheme_with_the_native_env():
    rows, compile_s = b.accuracy("isolator", 1, 0.02, schemes=("exact", "differentiable"))
    (row,) = rows
    assert row["seed"] == b.HELD_OUT and row["steps"] == 2 and row["same_end"]
    # the native numba environment is the independent reference: the exact scheme agrees to rounding
    assert row["exact_reward_rel"] < 1e-10 and row["exact_state_rel_peak"] < 1e-10
    assert row["exact_force_rel_peak"] < 1e-10
    assert 0 <= row["differentiable_state_nrmse"] < 1e-2 and 0 <= row["differentiable_reward_nrmse"] < 1e-2
    assert set(compile_s) == {"exact", "differentiable"} and all(t > 0 for t in compile_s.values())


def test_throughput_row_times_both_environments():
    rows, compile_s = b.throughput("isolator", [2], 1, 0.01, schemes=("differentiable",), bank=2)
    (row,) = rows
    assert row["N"] == 2 and row["native"] > 0 and row["jax_differentiable"] > 0
    assert row["x_differentiable"] == pytest.approx(row["jax_differentiable"] / row["native"])
    assert list(compile_s) == ["differentiable, N=2"]


def test_unknown_plant_is_refused():
    with pytest.raises(SystemExit):
        b.main(["--plants", "tandem_car"])
