"""Hostile suite files (issue 48): a suite file may come from another lab (``mrd-env score --suite their.json``), so
loading one runs no code, reads only a bounded regular file, confines the files it names to its folder, refuses a
forged shipped suite, and answers every malformed structure with one ``ValueError`` naming the file and the field
(from the CLI: one line on stderr, exit 2) — never a traceback, a hang or an "internal error"."""
from __future__ import annotations

import copy
import hashlib
import json
import os
import sys
from pathlib import Path

import pytest

from mrd_env import suites as S
from tests.deadline import deadline

pytestmark = pytest.mark.hostile

#: The shipped suite the malformed ones are made from (the smallest: 7 KB).
BASE = "building-six-storey-v1"
#: A shipped car suite (the forged one of the issue).
CAR = "car-comfort-v1"


def _shipped_json(sid: str) -> dict:
    s = S.suites()[sid]
    return json.loads(S.suite_path(s.plant, s).read_text(encoding="utf-8"))


def _digest(data: dict) -> str:
    """The digest as :func:`mrd_env.suites.content_digest` computes it, also for content it refuses (NaN)."""
    body = {k: v for k, v in data.items() if k != "digest"}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _own(data: dict, name: str = "their-suite") -> dict:
    """``data`` under a name of its own, its digest recomputed: what only its content can make refused."""
    data = {**data, "name": name}
    data["digest"] = _digest(data)
    return data


def _write(folder: Path, data: dict, name: str = "their-suite.json") -> Path:
    path = folder / name
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def base() -> dict:
    return _shipped_json(BASE)


def test_the_base_under_its_own_name_is_accepted(base, tmp_path):
    """The corruptions below are refused for what they change: the base itself, renamed, loads."""
    s = S.read_suite(_write(tmp_path, _own(base)))
    assert s.id == "their-suite-v1" and s.complete() and s.env_id == base["env_id"]


# ----------------------------------------------------------------------------------- malformed structures (8a, 8d)

def _first_label(d):
    return next(iter(d["references"]))


def _set(path, value):
    """A corruption: the field at ``path`` (keys; a callable key computes it from the data) set to ``value``."""
    def corrupt(d):
        target = d
        keys = [k(d) if callable(k) else k for k in path]
        for k in keys[:-1]:
            target = target[k]
        target[keys[-1]] = value
    return corrupt


def _drop(path):
    def corrupt(d):
        target = d
        keys = [k(d) if callable(k) else k for k in path]
        for k in keys[:-1]:
            target = target[k]
        del target[keys[-1]]
    return corrupt


def _deep(n: int):
    v: list = []
    for _ in range(n):
        v = [v]
    return v


_REF = ("references", _first_label)
#: (case id, corruption, what the message must name)
MALFORMED = [
    ("references as a list", lambda d: d.update(references=list(d["references"].values())), "references"),
    ("references as text", _set(("references",), "none"), "references"),
    ("a reference as a list", _set(_REF, [1.0, 2.0, 3.0, 4.0, 5.0]), "references["),
    ("a reference's extra field", lambda d: d["references"][_first_label(d)].update(extra=1.0), "references["),
    ("a reference's missing field", _drop((*_REF, "f_max")), "references["),
    ("a reference's passive as text", _set((*_REF, "passive"), "-0.3"), ".passive"),
    ("a reference's passive null", _set((*_REF, "passive"), None), ".passive"),
    ("a reference's clairvoyant true", _set((*_REF, "clairvoyant"), True), ".clairvoyant"),
    ("a reference's bound as a list", _set((*_REF, "bound"), [0.1]), ".bound"),
    ("a reference's f_max as an object", _set((*_REF, "f_max"), {"v": 1}), ".f_max"),
    ("a reference's passive_command huge", _set((*_REF, "passive_command"), 10 ** 400), ".passive_command"),
    ("a reference of no episode", lambda d: d["references"].update({"no such episode": d["references"][
        _first_label(d)]}), "references"),
    ("scenarios not a list", lambda d: d.update(scenarios={"a": d["scenarios"][0]}), "scenarios"),
    ("scenarios empty", _set(("scenarios",), []), "scenarios"),
    ("a scenario as text", _set(("scenarios", 0), "El Centro"), "scenarios[0]"),
    ("a scenario's extra field", _set(("scenarios", 0, "weight"), 2), "scenarios[0]"),
    ("a scenario's name a number", _set(("scenarios", 0, "name"), 7), "scenarios[0].name"),
    ("a scenario's name on two lines", _set(("scenarios", 0, "name"), "a\nb"), "scenarios[0].name"),
    ("a scenario's name twice", lambda d: d["scenarios"][1].update(name=d["scenarios"][0]["name"]), "scenarios"),
    ("a scenario's options a list", _set(("scenarios", 0, "options"), [["episode_seconds", 2.0]]), ".options"),
    ("a scenario's options text", _set(("scenarios", 0, "options"), "episode_seconds=2"), ".options"),
    ("seeds not a list", _set(("scenarios", 2, "seeds"), 1000000), ".seeds"),
    ("seeds empty", _set(("scenarios", 2, "seeds"), []), ".seeds"),
    ("a seed as text", _set(("scenarios", 2, "seeds", 0), "1000000"), ".seeds[0]"),
    ("a seed fractional", _set(("scenarios", 2, "seeds", 0), 1.5), ".seeds[0]"),
    ("a seed true", _set(("scenarios", 2, "seeds", 0), True), ".seeds[0]"),
    ("a seed negative", _set(("scenarios", 2, "seeds", 0), -1), ".seeds[0]"),
    ("a seed over 2**32 - 1", _set(("scenarios", 2, "seeds", 0), 2 ** 32), ".seeds[0]"),
    ("a seed twice", lambda d: d["scenarios"][2].update(seeds=[d["scenarios"][2]["seeds"][0]] * 2), ".seeds"),
    ("options a list", _set(("options",), []), "options"),
    ("options nested 40 deep", _set(("options", "plant_params"), _deep(40)), "options.plant_params"),
    ("an option NaN", _set(("options", "episode_seconds"), float("nan")), "options.episode_seconds"),
    ("control_dt text", _set(("control_dt",), "0.01"), "control_dt"),
    ("control_dt zero", _set(("control_dt",), 0), "control_dt"),
    ("control_dt negative", _set(("control_dt",), -0.01), "control_dt"),
    ("control_dt infinite", _set(("control_dt",), float("inf")), "control_dt"),
    ("control_dt true", _set(("control_dt",), True), "control_dt"),
    ("control_dt null", _set(("control_dt",), None), "control_dt"),
    ("name a number", _set(("name",), 12), "name"),
    ("name with a slash", _set(("name",), "../car-comfort"), "name"),
    ("name on two lines", _set(("name",), "mine\n| forged |"), "name"),
    ("version text", _set(("version",), "1"), "version"),
    ("version zero", _set(("version",), 0), "version"),
    ("version true", _set(("version",), True), "version"),
    ("plant unknown", _set(("plant",), "spaceship"), "plant"),
    ("plant a list", _set(("plant",), ["shear_building"]), "plant"),
    ("env_id a number", _set(("env_id",), 3), "env_id"),
    ("env_id of Gymnasium's", _set(("env_id",), "CartPole-v1"), "env_id"),
    ("description a list", _set(("description",), ["a"]), "description"),
    ("criteria text", _set(("criteria",), "J1"), "criteria"),
    ("a criterion a number", _set(("criteria", 0), 1), "criteria"),
    ("procedure a list", _set(("procedure",), []), "procedure"),
    ("procedure nested 40 deep", _set(("procedure", "note"), _deep(40)), "procedure.note"),
    ("randomised a list", _set(("randomised",), []), "randomised"),
    ("randomised's draws a list", _set(("randomised",), {"bands": {}, "draws": []}), "randomised.draws"),
    ("a draw of no episode", _set(("randomised",), {"bands": {}, "draws": {"nope": {}}}), "randomised.draws"),
    ("a draw not options", _set(("randomised",), {"bands": {}, "draws": {"Kanai–Tajimi s1000000": 3}}),
     "randomised.draws["),
    ("an unknown field", _set(("extra",), 1), "extra"),
    ("a missing field", _drop(("criteria",)), "criteria"),
    ("format_version text", _set(("format_version",), "1"), "format version"),
]


@pytest.mark.parametrize("corrupt, field", [pytest.param(c, f, id=i) for i, c, f in MALFORMED])
def test_a_malformed_suite_names_the_field(base, corrupt, field, tmp_path):
    data = copy.deepcopy(base)
    corrupt(data)
    data = _own(data) if isinstance(data.get("name"), str) and data["name"] == base["name"] else \
        {**data, "digest": _digest(data)}
    where = str(tmp_path / "their-suite.json")
    with pytest.raises(ValueError) as err:
        S.from_json(data, where=f"suite file {where}", folder=tmp_path)
    msg = str(err.value)
    assert where in msg and field in msg, msg
    assert "\n" not in msg and len(msg) < 2000, msg[:300]


@pytest.mark.hostile
def test_an_env_id_of_another_plant_is_refused_where_the_suite_is_resolved(base, tmp_path):
    """The suite module checks the id and the plant each alone (it imports no plant); their pairing is checked where
    a suite is resolved for scoring, so a building suite cannot run the quarter car under the building's units."""
    from experiments.benchmark.scoring import resolve_suite

    data = copy.deepcopy(base)
    data["env_id"] = "mrd_env/QuarterCarPhysical-v0"
    path = _write(tmp_path, _own(data))
    assert S.read_suite(path).env_id == "mrd_env/QuarterCarPhysical-v0"
    with pytest.raises(ValueError, match="is not an environment of the plant 'shear_building'"):
        resolve_suite(path)


def test_a_negative_seed_names_its_scenario(base, tmp_path):
    """8d: seeds=[-1] was Gymnasium's own error at the first reset; now the suite's, naming the scenario."""
    data = copy.deepcopy(base)
    data["scenarios"][2]["seeds"] = [-1]
    with pytest.raises(ValueError, match=r"scenarios\[2\] \('Kanai–Tajimi'\)\.seeds\[0\] must be a whole number "
                                         r"in \[0, 4294967295\]"):
        S.read_suite(_write(tmp_path, _own(data)))


def test_deep_nesting_in_the_file_is_refused(tmp_path):
    """``json.loads`` raises RecursionError on a file nested 100 000 deep: one line naming the file instead."""
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000, encoding="utf-8")
    with pytest.raises(ValueError, match="deep.json: cannot be read .*nested too deeply"):
        S.read_suite(path)
    path.write_text('{"format": "mrd-env-suite", "control_dt": NaN}', encoding="utf-8")
    with pytest.raises(ValueError, match="deep.json: cannot be read .*NaN"):
        S.read_suite(path)


def _cli(argv: list[str], capsys) -> tuple[int, str]:
    from experiments.cli import main

    code = main(argv)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("case", ["references as a list", "a seed negative", "control_dt zero", "an option NaN",
                                  "scenarios not a list", "nested file", "env_id of Gymnasium's"])
def test_the_cli_answers_a_malformed_suite_with_one_line_and_exit_2(base, case, tmp_path, capsys):
    if case == "nested file":
        path = tmp_path / "bad.json"
        path.write_text("[" * 100_000 + "]" * 100_000, encoding="utf-8")
    else:
        data = copy.deepcopy(base)
        next(c for i, c, _ in MALFORMED if i == case)(data)
        path = _write(tmp_path, _own(data), "bad.json")
    code, err = _cli(["score", "--suite", str(path), "--controller", "skyhook_continuous",
                      "--out", str(tmp_path / "out")], capsys)
    assert code == 2, err
    assert err.startswith("mrd-env score: error: ") and err.count("\n") == 1 and "bad.json" in err, err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


# ----------------------------------------------------------------------------------------- no code runs (1)

EVIL = """from pathlib import Path
Path(__file__).with_name("ran").write_text("the suite ran code")
import gymnasium
class Evil(gymnasium.Env):
    pass
"""


@pytest.fixture
def evil_suite(base, tmp_path, monkeypatch):
    """A suite whose env_id names a module shipped beside it (on the import path, as the cwd of a user who runs
    ``mrd-env score --suite their-suite.json`` in its folder is)."""
    (tmp_path / "their_env.py").write_text(EVIL)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    data = copy.deepcopy(base)
    data["env_id"] = "their_env:Evil"
    yield _write(tmp_path, _own(data))
    sys.modules.pop("their_env", None)


def test_a_suite_whose_env_id_names_a_module_runs_no_code(evil_suite, capsys):
    from experiments.benchmark.scoring import resolve_suite

    for load in (S.read_suite, lambda p: S.suite(str(p)), resolve_suite, lambda p: resolve_suite(str(p))):
        with pytest.raises(ValueError, match=r"env_id must be an environment of mrd_env, one of \[.*"
                                             r"'mrd_env/ShearBuildingPhysical-v0'.*\]; got 'their_env:Evil'"):
            load(evil_suite)
    code, err = _cli(["score", "--suite", str(evil_suite), "--controller", "skyhook_continuous", "--out",
                      str(evil_suite.parent / "out")], capsys)
    assert code == 2 and "env_id" in err and err.count("\n") == 1, err
    assert not (evil_suite.parent / "ran").exists() and "their_env" not in sys.modules


def test_a_suite_file_without_json_ending_takes_the_same_checks(evil_suite):
    """``resolve_suite`` reads an existing file of any name: the same reader, the same checks."""
    from experiments.benchmark.scoring import resolve_suite

    other = evil_suite.with_name("their-suite")
    other.write_bytes(evil_suite.read_bytes())
    with pytest.raises(ValueError, match="env_id"):
        resolve_suite(str(other))
    assert not (evil_suite.parent / "ran").exists()


# ------------------------------------------------------------------------------------- forged shipped suites (4)

def test_the_digest_list_is_the_shipped_files(tmp_path):
    """The list of shipped digests matches the shipped files, and :func:`write_shipped_digests` (what the
    maintenance script runs after writing a suite) writes it again byte for byte."""
    every = S.suites()
    assert S.shipped_digests() == {sid: s.digest for sid, s in every.items()}
    assert all(S.shipped_digest(sid) == s.digest for sid, s in every.items())
    assert S.shipped_digest("no-such-suite-v1") is None and S.shipped_digest(None) is None
    again = S.write_shipped_digests(tmp_path / "digests.json")
    assert again.read_bytes() == S.SHIPPED_DIGESTS.read_bytes()


def test_a_forged_shipped_suite_is_refused(tmp_path):
    """An edited car-comfort-v1 with its digest recomputed passed as the shipped suite (its leaderboard then
    showed skyhook at share 40): a shipped id means the shipped content."""
    data = _shipped_json(CAR)
    assert S.read_suite(_write(tmp_path, data, "copy.json")).digest == S.shipped_digest(CAR)  # a true copy loads
    for r in data["references"].values():
        r["clairvoyant"] = r["passive"] + 0.025 * (r["clairvoyant"] - r["passive"])
    data["digest"] = _digest(data)
    forged = _write(tmp_path, data, "forged.json")
    with pytest.raises(ValueError, match="car-comfort-v1 is the id of a shipped suite, whose content differs .*a "
                                         "suite of your own needs a name of its own"):
        S.read_suite(forged)
    with pytest.raises(ValueError, match="not a shipped version of the suite 'car-comfort'"):
        S.read_suite(_write(tmp_path, {**data, "version": 99, "digest": _digest({**data, "version": 99})}, "v99.json"))
    mine = S.read_suite(_write(tmp_path, _own(data, "my-comfort"), "mine.json"))  # under a name of its own: fine
    assert mine.id == "my-comfort-v1" and mine.references != S.suites()[CAR].references


def test_check_shipped_id_for_result_files():
    """What the leaderboard asks of a result file's suite: its id and digest."""
    S.check_shipped_id(CAR, S.shipped_digest(CAR))
    S.check_shipped_id("my-comfort-v1", "0" * 64)
    with pytest.raises(ValueError, match="needs a name of its own"):
        S.check_shipped_id(CAR, "0" * 64, where="result file r.json")


# --------------------------------------------------------------------------------- bounded, regular reads (6c)

def test_the_size_cap_leaves_room_for_the_shipped_suites():
    largest = max(os.path.getsize(S.suite_path(s.plant, s)) for s in S.suites().values())
    assert 10 * largest <= S.MAX_SUITE_BYTES <= 16 * 1024 ** 2


def test_a_device_a_fifo_or_a_huge_file_is_refused(tmp_path):
    with deadline():
        with pytest.raises(ValueError, match="suite file /dev/zero: not a regular file"):
            S.read_suite("/dev/zero")
        fifo = tmp_path / "fifo.json"
        os.mkfifo(fifo)
        with pytest.raises(ValueError, match="fifo.json: not a regular file"):
            S.suite(str(fifo))
        huge = tmp_path / "huge.json"
        with open(huge, "wb") as fh:  # sparse: no disk used
            fh.truncate(S.MAX_SUITE_BYTES + 1)
        with pytest.raises(ValueError, match=f"huge.json: {S.MAX_SUITE_BYTES + 1} bytes, more than the "
                                             f"{S.MAX_SUITE_BYTES} bytes a suite file may hold"):
            S.read_suite(huge)


# ----------------------------------------------------------------------------- files a suite names (3, suite half)

def _with_road_path(data: dict, where: str, name) -> dict:
    """``data`` with a measured road (``road: csv``) whose ``path`` is ``name``, at ``where``: the suite's options,
    a scenario's, a road object's, or a drawn episode's damper preset."""
    data = copy.deepcopy(data)
    road = {"road": "csv", "road_params": {"path": name, "height_column": "z", "time_column": "t",
                                           "units": {"z": "m", "t": "s"}}}
    if where == "suite":
        data["options"].update(road)
    elif where == "scenario":
        data["scenarios"][0]["options"].update(road)
    elif where == "road object":
        data["scenarios"][0]["options"]["road"] = {"kind": "csv", **road["road_params"]}
        data["scenarios"][0]["options"].pop("road_params", None)
    elif where == "ground-motion mixture":
        data["scenarios"][0]["options"] = {"ground_motion": "mixture", "ground_motion_params": {
            "sources": ["el_centro", {"kind": "at2", "path": name}]}, "episode_seconds": 2.0}
    elif where == "draw":
        data["randomised"] = {"bands": {}, "draws": {data["scenarios"][0]["name"]: {"damper": name}}}
    return data


PLACES = ["suite", "scenario", "road object", "ground-motion mixture", "draw"]
OUTSIDE = [("/etc/passwd", "no absolute path"), ("/dev/zero", "no absolute path"),
           ("../outside.csv", "no '..'"), ("sub/../../outside.csv", "no '..'"), ("", "a file name"),
           (["road.csv"], "a file name"), ("road\x00.csv", "no NUL"), ("x" * 5000, "at most 4096 characters")]


@pytest.mark.parametrize("where", PLACES)
@pytest.mark.parametrize("name, why", OUTSIDE, ids=[repr(n)[:20] for n, _ in OUTSIDE])
def test_a_file_outside_the_suites_folder_is_refused(base, where, name, why, tmp_path):
    if where == "draw":  # a damper names a file by its .json ending (a model name otherwise)
        if not isinstance(name, str) or not name:
            pytest.skip("a damper that is not a name ending in .json names no file")
        name += ".json"
    (tmp_path / "outside.csv").write_text("t,z\n0,0\n1,0\n")
    folder = tmp_path / "suite"
    folder.mkdir()
    path = _write(folder, _own(_with_road_path(base, where, name)))
    with pytest.raises(ValueError, match=why) as err:
        S.read_suite(path)
    assert str(path) in str(err.value) and ("path" in str(err.value) or "damper" in str(err.value))


def test_a_link_leaving_the_folder_and_a_fifo_inside_it_are_refused(base, tmp_path):
    folder = tmp_path / "suite"
    folder.mkdir()
    (folder / "road.csv").symlink_to("/etc/passwd")
    with pytest.raises(ValueError, match="road_params.path 'road.csv' in .*: it is a link that leaves the folder"):
        S.read_suite(_write(folder, _own(_with_road_path(base, "scenario", "road.csv"))))
    (folder / "road.csv").unlink()
    os.mkfifo(folder / "road.csv")
    with deadline(), pytest.raises(ValueError, match="road.csv' in .*: not a regular file"):
        S.read_suite(_write(folder, _own(_with_road_path(base, "scenario", "road.csv"))))
    (folder / "road.csv").unlink()
    with pytest.raises(ValueError, match="road.csv' in .*: cannot be read"):
        S.read_suite(_write(folder, _own(_with_road_path(base, "scenario", "road.csv"))))


def test_a_suite_given_as_content_names_no_file(base):
    with pytest.raises(ValueError, match=r"scenarios\[0\]\.options\.road_params\.path names the file 'road.csv': "
                                         "only a suite read from its file names files"):
        S.from_json(_own(_with_road_path(base, "scenario", "road.csv")), where="their suite")


def test_no_shipped_suite_names_a_file():
    for s in S.suites().values():
        assert not S._files_named(s.to_json()), s.id


def test_a_road_in_the_suites_folder_is_the_one_driven(tmp_path, monkeypatch):
    """A relative name is resolved in the suite file's folder (not the working folder) when an episode is made."""
    import gymnasium as gym
    import numpy as np

    car = _shipped_json(CAR)
    folder = tmp_path / "suite"
    folder.mkdir()
    t = np.arange(0, 0.5, 0.001)
    (folder / "road.csv").write_text("t,z\n" + "\n".join(f"{a:.3f},{0.01 * np.sin(20 * a):.6f}" for a in t))
    data = _with_road_path(car, "scenario", "road.csv")
    data["scenarios"] = data["scenarios"][:1]
    data["scenarios"][0].update(seeds=[0], name="measured")
    data["scenarios"][0]["options"]["episode_seconds"] = 0.2
    data["references"], data["randomised"] = {}, {}
    s = S.read_suite(_write(folder, _own(data, "my-road")))
    monkeypatch.chdir(tmp_path)  # no road.csv here
    options = s.episode_options(*s.episodes()[0])
    assert options["road_params"]["path"] == str(folder.resolve() / "road.csv")
    assert s.to_json()["scenarios"][0]["options"]["road_params"]["path"] == "road.csv"  # the file is unchanged
    env = gym.make(s.env_id, **options, control_dt=s.control_dt)
    try:
        env.reset(seed=0)
        env.step(env.action_space.low)
    finally:
        env.close()
