"""A command resolves ``--plant`` once into the plant's profile and hands the profile down (issue 38): a former name
(the building's) still works, with a DeprecationWarning, but is not offered; an agent that records a former name is
found under today's; the profile travels to a process pool's workers as itself."""
import dataclasses
import json
import pickle
import re
import shutil

import pytest

from controllers import load_agent, shipped_agents
from controllers.agents import recorded_plant
from experiments.cli import build_parser
from experiments.common.plants import chosen_plants, default_plant, plant_choices, profile, profiles

#: The commands with a ``--plant`` option.
COMMANDS = ("benchmark", "train", "tune")


def renamed() -> tuple[str, str]:
    """(a former name, the plant's name today)."""
    return next((former, name) for name, p in profiles().items() for former in p.spec.former_names)


@pytest.mark.parametrize("command", COMMANDS)
def test_a_former_plant_name_still_works_but_is_not_offered(command, capsys):
    former, name = renamed()
    with pytest.warns(DeprecationWarning, match=f"now called '{name}'"):
        args = build_parser(command).parse_args([command, "--plant", former])
    assert args.plant == name
    with pytest.raises(SystemExit):
        build_parser(command).parse_args([command, "--help"])
    offered = re.search(r"--plant \{([^}]*)\}", capsys.readouterr().out).group(1).split(",")
    assert former not in offered and name in offered
    assert offered == plant_choices(both=command == "benchmark")


def test_the_single_plant_commands_default_to_the_one_training_default():
    assert [name for name, p in profiles().items() if p.train_default] == [default_plant()]
    for command in ("train", "tune"):
        assert build_parser(command).parse_args([command]).plant == default_plant()


def test_chosen_plants_are_profiles():
    assert chosen_plants("both") == [p for p in profiles().values() if p.published]
    assert {p.name for p in chosen_plants("all")} == set(profiles())
    former, name = renamed()
    with pytest.warns(DeprecationWarning):
        assert chosen_plants(former) == [profile(name)]


def test_a_profile_travels_to_a_worker_as_itself():
    """A profile holds lambdas, which do not pickle: it pickles as its plant's name, and a worker takes the same
    profile from the registry. A profile the registry does not hold is refused rather than swapped."""
    for p in profiles().values():
        assert pickle.loads(pickle.dumps(p)) is p
    edited = dataclasses.replace(next(iter(profiles().values())), laws=())
    with pytest.raises(pickle.PicklingError, match="not the registered one"):
        pickle.dumps(edited)


def test_an_agent_recording_a_former_plant_name_is_found_under_todays(tmp_path):
    former, name = renamed()
    folder = shutil.copytree(shipped_agents(name)[0], tmp_path / "old_agent")
    meta = json.loads((folder / "agent.json").read_text())
    (folder / "agent.json").write_text(json.dumps({**meta, "plant": former}))
    with pytest.warns(DeprecationWarning):
        assert load_agent(folder).plant == name
    assert recorded_plant({"plant": name}) == name
    assert recorded_plant({"plant": "no_such_plant"}) == "no_such_plant"  # named as it is in the error that follows


def test_the_cars_passive_reference_is_the_presets_dashpot():
    """The quarter car's conventional passive reference (its profile's ``passive_ref``): the MR damper replaced by set A's 1500 N·s/m
    dashpot (a Bingham damper without friction), set B's 1000 N·s/m."""
    reference = profile("quarter_car").passive_reference
    name, options = reference({})
    assert name == "passive_ref (c=1500)"
    assert options == {"damper": "bingham", "damper_params": {"fc_a": 0.0, "fc_b": 0.0, "c0a": 1500.0, "c0b": 0.0,
                                                              "f0": 0.0}}
    assert reference({"plant_preset": "set_b"})[1]["damper_params"]["c0a"] == 1000.0
    assert profile("shear_building").passive_reference is None
