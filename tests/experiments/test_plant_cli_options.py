"""Plant options from the command line (issue 40): the building's ``--storeys`` and ``--damper-storeys`` and every
plant's ``--damper``, declared by the plant's profile and added to every command once; bad values are one line and
exit 2; a derived profile travels to a worker as itself; ``score`` refuses options that would change a suite's
plant."""
import pickle

import pytest

from experiments.cli import main
from experiments.common.plants import profile, profiles

BUILDING = next(p.name for p in profiles().values() if any(o.name == "storeys" for o in p.plant_options))
OTHER = next(p.name for p in profiles().values() if not p.plant_options)


def test_storeys_picks_the_six_storey_building_with_its_four_dampers_everywhere_it_trains_and_is_tested():
    base = profile(BUILDING)
    six = base.with_plant_options({"storeys": "6"})
    for options in (six.options, six.training, *(o for _, o, _ in six.tests(six.options, True))):
        assert options["plant_preset"] == "six_storey" and list(options["damper_floors"]) == [1, 1, 2, 2]
    assert six.training["ground_motion"] == base.training["ground_motion"]  # only the plant changes
    assert base.with_plant_options({}) is base and base.options.get("plant_preset") is None  # the registered one
    again = pickle.loads(pickle.dumps(six))
    assert again.options == six.options and again.applied == six.applied
    moved = six.with_plant_options({"damper-storeys": "1,3,3", "damper": "bouc_wen"})
    assert list(moved.options["damper_floors"]) == [1, 3, 3] and moved.options["damper"] == "bouc_wen"
    assert moved.options["plant_preset"] == "six_storey"
    # the three-storey building keeps the benchmark's damper storey unless told otherwise
    assert base.with_plant_options({"storeys": "3"}).options == base.options


@pytest.mark.parametrize("values,match", [({"storeys": "4"}, r"--storeys must be one of \[3, 6\]"),
                                          ({"storeys": "six"}, "--storeys"),
                                          ({"damper-storeys": "1,4"}, r"--damper-storeys .* 1\.\.3"),
                                          ({"storeys": "6", "damper-storeys": "0"}, r"1\.\.6"),
                                          ({"damper-storeys": "1;2"}, "--damper-storeys"),
                                          ({"damper": "nope"}, "--damper nope")])
def test_bad_plant_options_name_the_option_and_its_valid_values(values, match):
    with pytest.raises(ValueError, match=match):
        profile(BUILDING).with_plant_options(values)


def test_a_plant_without_the_option_refuses_it():
    with pytest.raises(ValueError, match="--storeys is not an option of the"):
        profile(OTHER).with_plant_options({"storeys": "6"})


@pytest.mark.parametrize("argv", [
    ["benchmark", "--plant", BUILDING, "--storeys", "5", "--episodes", "1"],
    ["benchmark", "--plant", BUILDING, "--damper-storeys", "9", "--episodes", "1"],
    ["benchmark", "--plant", BUILDING, "--storeys", "6", "--damper-storeys", "7", "--episodes", "1"],
    ["train", "--plant", BUILDING, "--damper-storeys", "x", "--timesteps", "1", "--eval-freq", "0"],
    ["benchmark", "--plant", OTHER, "--storeys", "6", "--episodes", "1"],
    # a plant no shipped suite has: a suite fixes its plant
    ["benchmark", "--plant", BUILDING, "--damper", "bouc_wen", "--episodes", "1"],
    ["score", "--suite", "building-seismic-v1", "--controller", "passive_on", "--storeys", "6"],
    ["score", "--suite", "building-seismic-v1", "--controller", "passive_on", "--damper", "bouc_wen"],
    # another plant's option on a suite (was an internal error: the car has no apply_plant_options)
    ["score", "--suite", "car-comfort-v1", "--controller", "passive_on", "--damper-storeys", "1,2"],
])
def test_bad_or_plant_changing_options_are_one_line_and_exit_2(argv, capsys, tmp_path):
    code = main([*argv, "--out", str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err


def test_score_names_the_suite_whose_plant_the_options_describe(capsys, tmp_path):
    main(["score", "--suite", "building-seismic-v1", "--controller", "passive_on", "--storeys", "6", "--out",
          str(tmp_path)])
    assert "score building-six-storey-v1" in capsys.readouterr().err
    # options that describe the suite's own plant pass the check (the run is refused later, for its controller)
    code = main(["score", "--suite", "building-six-storey-v1", "--controller", "nope", "--storeys", "6",
                 "--damper-storeys", "1,1,2,2", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "nope" in err and "would change the plant" not in err, err


def test_benchmark_runs_the_suites_of_the_six_storey_building(tmp_path, capsys):
    """The plant options choose the suites whose plant they describe: --storeys 6 the six-storey building's."""
    code = main(["benchmark", "--plant", BUILDING, "--storeys", "6", "--only", "passive_on", "--episodes", "1",
                 "--backend", "serial", "--no-progress", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "| building-six-storey-v1 |" in out and "building-seismic-v1" not in out
