"""The six-storey separation script's gradient bound refuses what it cannot compute before computing anything."""
from pathlib import Path

import pytest

from experiments.measurements.accuracy.six_storey_separation import _gradient_bounds

SPEC = Path(__file__).parents[2] / "experiments/benchmark/pending_specs/building-six-storey-v2.json"


def _definition():
    from mrd_env.plants import suite_spec

    return suite_spec(SPEC)


def test_an_unknown_scenario_is_refused_by_name_and_nothing_is_kept(tmp_path):
    name, env_id, definition = _definition()
    with pytest.raises(ValueError, match=r"--gradient: no scenario 'Kanai' in the spec \(scenarios: .*Kanai–Tajimi"):
        _gradient_bounds(name, env_id, definition, ["Kanai"], tmp_path / "s.json")
    assert not any(tmp_path.iterdir())


def test_a_procedure_without_a_batched_round_1_is_refused(tmp_path):
    from dataclasses import replace

    name, env_id, definition = _definition()
    with pytest.raises(ValueError, match="procedure 2 has no batched round 1"):
        _gradient_bounds(name, env_id, replace(definition, procedure=2), ["Kanai–Tajimi"], tmp_path / "s.json")
