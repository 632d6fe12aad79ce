"""The build-cost script (experiments/measurements/speed/build_cost.py) refuses bad options in one line, exit 2,
before it measures anything."""
from __future__ import annotations

import pytest

from experiments.measurements.speed import build_cost

SPEC = "experiments/benchmark/pending_specs/building-six-storey-v2.json"


@pytest.mark.parametrize("args, said", [
    (["--batch", "0"], "--batch must be comma-separated ints in [1, 128]"),
    (["--batch", "2,x"], "--batch must be"),
    (["--repeats", "0"], "--repeats must be in [1, 20]"),
    (["--parts", "gradient,bogus"], "--parts must name gradient and/or casadi"),
    (["--episodes", "no such episode"], "--episodes: no episode 'no such episode' in building-six-storey-v2"),
])
def test_refused_options_say_which_and_write_nothing(tmp_path, capsys, args, said):
    out = tmp_path / "cost.json"
    assert build_cost.main(["--spec", SPEC, "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and "\n" not in err
    assert not out.exists()
