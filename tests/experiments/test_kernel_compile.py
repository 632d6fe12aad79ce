"""The kernel-compilation script (experiments/measurements/speed/kernel_compile.py): refused options in one line,
exit 2, before anything is measured; its call probe runs a model through function pointers to the same bits."""
from __future__ import annotations

import pytest

from experiments.measurements.speed import kernel_compile


@pytest.mark.parametrize("args, said", [
    (["--models", "nope"], "--models must name damper models among"),
    (["--models", ","], "--models must name damper models"),
    (["--calls", "10"], "--calls must be in [1000, 100000000]"),
    (["--repeats", "0"], "--repeats must be in [1, 20]"),
])
def test_refused_options_say_which_and_write_nothing(tmp_path, capsys, args, said):
    out = tmp_path / "compile.json"
    assert kernel_compile.main(["--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and "\n" not in err
    assert not out.exists()


def test_a_model_called_through_pointers_gives_the_inlined_bits():
    row = kernel_compile.call_probe("dahl", 1_000, 1)
    assert row["same_bits"] and row["inlined_ns"] > 0 and row["pointer_ns"] > 0
