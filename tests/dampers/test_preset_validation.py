"""Preset files are checked for their structure when they are read (issue 36, item 6): a shared file that is not
what it claims gives one ValueError naming the file and the field — one line and exit 2 from the commands —, never
an AttributeError or a RecursionError; a file it names is resolved inside its folder, one level at most."""
from __future__ import annotations

import json
import os

import gymnasium as gym
import pytest

import mrd_env  # noqa: F401  (registers the environments)
from experiments.cli import main
from mrd_env.dampers import damper_class, load_damper_preset, make_damper
from mrd_env.dampers.preset_file import preset_model, read_preset
from mrd_env.identification import load_preset, save_preset

pytestmark = pytest.mark.hostile  # every case here is a hostile file (a count: pytest -m hostile)


@pytest.fixture
def folder(tmp_path):
    save_preset(make_damper("bouc_wen", "spencer1997"), tmp_path / "good.json")
    return tmp_path


def _doc(folder) -> dict:
    return json.loads((folder / "good.json").read_text())


def _write(folder, name: str, doc: dict):
    path = folder / name
    path.write_text(json.dumps(doc))
    return path


def _bad(folder, name: str, **changes):
    return _write(folder, name, {**_doc(folder), **changes})


CASES = {  # file name: (changes, what the message names)
    "self.json": (dict(model="self.json"), ('"model"', "itself")),
    "list_parameters.json": (dict(parameters=[1.0, 2.0]), ('"parameters"', "an object", "a list")),
    "number_parameters.json": (dict(parameters={"alpha_b": 5.0}), ('"parameters"."alpha_b"', "a number")),
    "text_value.json": (dict(parameters={"alpha_b": {"value": "x", "unit": "N/m"}}),
                        ('"parameters"."alpha_b"."value"', "must be a number")),
    "text_command.json": (dict(command="V"), ('"command"', "an object", "text")),
    "short_command.json": (dict(command={"unit": "V"}), ('"command"', "lacks", "'v_min'")),
    "number_unit.json": (dict(command={"unit": 1, "v_min": 0, "v_max": 1, "eta": 50}), ('"command"."unit"',)),
    "escape.json": (dict(model="../good.json"), ('"model"', "'../good.json'", "inside the folder")),
    "absolute.json": (dict(model="/etc/passwd.json"), ('"model"', "inside the folder")),
    "number_model.json": (dict(model=3), ('"model"', "a number")),
    "unknown_model.json": (dict(model="nope"), ('"model"', "'nope'", "available")),
    "neural_no_network.json": (dict(model="neural", network=[1]), ('"network"',)),
    "bad_range.json": (dict(command={"unit": "V", "v_min": 0.0, "v_max": -1.0, "eta": 50.0}), ('"command"', "v_max")),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_malformed_preset_is_named_with_its_field(folder, name):
    changes, names = CASES[name]
    path = _bad(folder, name, **changes)
    # damper_class reads the model alone: a command out of range is the damper's to refuse
    loaders = (make_damper, load_damper_preset, load_preset) + (() if name == "bad_range.json" else (damper_class,))
    for load in loaders:
        with pytest.raises(ValueError) as info:
            load(str(path))
        msg = str(info.value)
        assert str(path) in msg and names[0] in msg, (load.__name__, msg)
        if load is make_damper:
            assert all(n in msg for n in names), msg
    with pytest.raises(ValueError, match=str(path)):
        gym.make("mrd_env/QuarterCar-v1", damper=str(path), episode_seconds=0.1)


def test_a_preset_may_name_another_in_its_folder_one_level(folder):
    one = _bad(folder, "one.json", model="good.json")
    assert preset_model(one) == "bouc_wen" and damper_class(str(one)).name == "bouc_wen"
    assert make_damper(str(one)).params == make_damper(str(folder / "good.json")).params
    two = _bad(folder, "two.json", model="one.json")
    with pytest.raises(ValueError, match=r"two\.json.*one level at most"):
        make_damper(str(two))
    # a circle of two files is a chain too: refused at once, no RecursionError
    _bad(folder, "a.json", model="b.json")
    _bad(folder, "b.json", model="a.json")
    with pytest.raises(ValueError, match="one level at most"):
        make_damper(str(folder / "a.json"))


def test_a_link_leaving_the_folder_is_refused(folder, tmp_path_factory):
    outside = tmp_path_factory.mktemp("outside")
    save_preset(make_damper("bouc_wen", "spencer1997"), outside / "elsewhere.json")
    os.symlink(outside / "elsewhere.json", folder / "link.json")
    path = _bad(folder, "linked.json", model="link.json")
    with pytest.raises(ValueError, match="link that leaves the folder"):
        make_damper(str(path))


def test_the_written_preset_still_reads(folder):
    doc = read_preset(folder / "good.json")
    assert doc["model"] == "bouc_wen" and load_damper_preset(folder / "good.json").name == "bouc_wen"


@pytest.mark.parametrize("name", ["self.json", "list_parameters.json", "text_command.json", "escape.json"])
@pytest.mark.parametrize("command", [["rig", "--damper", "{path}", "--cycles", "1"],
                                     ["benchmark", "--plant", "shear_building", "--damper", "{path}", "--episodes",
                                      "1", "--no-progress"]])
def test_the_commands_say_one_line_and_exit_2(folder, capsys, name, command):
    changes, names = CASES[name]
    path = _bad(folder, name, **changes)
    argv = [a.replace("{path}", str(path)) for a in command] + ["--out", str(folder / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and names[0] in err, err
    assert "internal error" not in err
