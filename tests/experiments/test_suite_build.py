"""Your own suite (issue 50, item 2): ``mrd-env suite build SPEC`` from a small spec (strict checks, one line naming
the field), the same bytes serially and on a process pool, a build interrupted and resumed without solving its kept
episodes again, a scenario on the user's own record file, and every shipped suite's definition read from its spec."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import experiments.benchmark.references as sr
from experiments.cli import main
from mrd_env.plants import plant, suite_spec
from mrd_env.suites import PLANTS_FOLDER, build_record_path, read_spec, read_suite, suites

#: Short episodes, so that a build takes seconds: one ISO road seed and the user's road.
SECONDS = 0.2


def write_road(folder: Path) -> Path:
    """A measured road of the user's: height vs time (s, m), a seeded random walk, 0.5 s at 5 ms."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 0.5, 0.005)
    z = np.cumsum(rng.normal(0.0, 4e-4, t.size))
    lines = ["t [s],z [m]"] + [f"{a:.3f},{b - z[0]:.6f}" for a, b in zip(t, z)]
    path = folder / "roads" / "my-road.csv"
    path.parent.mkdir(exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def spec_data(**changes) -> dict:
    data = {"format": "mrd-env-suite-spec", "format_version": 1, "name": "tiny-build", "version": 1,
            "plant": "quarter_car", "description": "a test suite", "options": {"sensors": ["sprung_acc", "travel"]},
            "control_dt": 0.01,
            "scenarios": [{"name": "ISO-C", "options": {"road": "iso8608", "road_params": {"road_class": "C",
                                                                                         "speed": 20.0},
                                                        "episode_seconds": SECONDS}, "seeds": {"first": 6, "count": 1}},
                          {"name": "my road", "options": {"road": "csv", "road_params": {
                              "path": "roads/my-road.csv", "height_column": "z", "time_column": "t"},
                              "episode_seconds": SECONDS}, "seeds": [0]}],
            "criteria": ["acc_weighted_rms"], "procedure": 1}  # the fast procedure (2 is tested apart)
    data.update(changes)
    return data


def write_spec(folder: Path, data: dict) -> Path:
    write_road(folder)
    path = folder / "spec.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def serial(tmp_path_factory) -> Path:
    """The tiny suite built serially: (its file, its spec)."""
    folder = tmp_path_factory.mktemp("serial")
    spec = write_spec(folder, spec_data())
    plant_name, env_id, d = suite_spec(spec)
    b = sr.build_suite(d, plant_name, env_id, folder / "out" / "tiny-build-v1.json", backend="serial", progress=False,
                       command=sr.spec_command(spec), say=lambda _: None)
    return b.path


def _build(args, capsys) -> tuple[int, str, str]:
    rc = main(["suite", "build", *map(str, args)])
    out, err = capsys.readouterr()
    return rc, out, err


# ----------------------------------------------------------------------------------------------- the spec's checks

@pytest.mark.parametrize("change, field", [
    ({"bogus": 1}, "unknown field(s) ['bogus']"),
    ({"format_version": 2}, "format_version"),
    ({"plant": "tram"}, "plant must be one of"),
    ({"env_id": "mrd_env/ShearBuilding-v0"}, "env_id must be one of the quarter_car's"),
    ({"control_dt": -0.01}, "control_dt"),
    ({"version": 0}, "version"),
    ({"name": "car-comfort"}, "name must be a name of your own"),
    ({"criteria": "acc"}, "criteria"),
    ({"randomise": {"seed": 1, "plant_params": {"m_s": [1.1, 0.9]}}}, "randomise.plant_params.m_s"),
    ({"scenarios": []}, "scenarios must be a non-empty list"),
])
def test_a_bad_spec_is_one_line_naming_the_field(tmp_path, capsys, change, field):
    rc, out, err = _build([write_spec(tmp_path, spec_data(**change))], capsys)
    assert rc == 2 and err.count("\n") == 1 and field in err, err
    assert not list(tmp_path.glob("*.json.partial")) and not (tmp_path / "tiny-build-v1.json").exists()


@pytest.mark.parametrize("scenario, field", [
    ({"seeds": {"first": -1, "count": 2}}, "scenarios[0].seeds.first"),
    ({"seeds": {"first": 0, "count": 0}}, "scenarios[0].seeds.count"),
    ({"seeds": [1, 1]}, "distinct seeds"),
    ({"extra": 1}, "scenarios[0] must be an object of name, options and seeds"),
    ({"options": {"road": "csv", "road_params": {"path": "../elsewhere.csv", "height_column": "z",
                                                 "time_column": "t"}}}, "scenarios[0].options.road_params.path"),
    ({"options": {"road": "csv", "road_params": {"path": "roads/none.csv", "height_column": "z",
                                                 "time_column": "t"}}}, "cannot be read"),
    ({"options": {"road": "cobblestones"}}, "scenarios[0] ('ISO-C')"),
])
def test_a_bad_scenario_is_refused_before_anything_is_solved(tmp_path, capsys, scenario, field):
    data = spec_data()
    data["scenarios"][0].update(scenario)
    rc, out, err = _build([write_spec(tmp_path, data), "--out", tmp_path / "x.json"], capsys)
    assert rc == 2 and err.count("\n") == 1 and field in err, err
    assert not (tmp_path / "x.json").exists() and not (tmp_path / "x.json.partial").exists()


def test_an_existing_suite_file_is_replaced_only_when_asked(tmp_path, capsys):
    spec = write_spec(tmp_path, spec_data())
    (tmp_path / "taken.json").write_text("mine", encoding="utf-8")
    rc, _, err = _build([spec, "--out", tmp_path / "taken.json"], capsys)
    assert rc == 2 and "--overwrite" in err and (tmp_path / "taken.json").read_text() == "mine"
    rc, _, err = _build([spec, "--out", spec], capsys)
    assert rc == 2 and "the spec itself" in err


# ------------------------------------------------------------------------------------------------------ the build

def test_a_build_is_the_same_bytes_serially_and_on_a_pool(serial, tmp_path, capsys):
    """The suite file holds only what the procedure computes: the pool's workers give the same references and
    solver records to the last bit; the run's wall times and load go to the build record."""
    spec = write_spec(tmp_path, spec_data())
    rc, out, err = _build([spec, "--backend", "pool", "--jobs", "2", "--out", tmp_path / "pool.json"], capsys)
    assert rc == 0, err
    assert (tmp_path / "pool.json").read_bytes() == serial.read_bytes()
    assert "2 episodes" in out and "load average" in out and "pool.json" in out
    record = json.loads(build_record_path(tmp_path / "pool.json").read_text())
    assert record["backend"] == "pool" and record["episodes_solved"] == 2 and record["wall_s"] > 0
    assert set(record["episodes"]) == {"ISO-C", "my road"} and not (tmp_path / "pool.json.partial").exists()


def test_the_suite_holds_its_references_and_cost_and_reads_back(serial):
    s = read_suite(serial)
    assert s.complete() and s.id == "tiny-build-v1" and s.env_id == plant("quarter_car").physics_id
    for label in s.labels():
        r = s.reference(label)
        assert r.clairvoyant >= r.passive, label  # the clairvoyant starts from the best constant command
    cost = s.procedure["cost"]
    runs = [x for e in s.procedure["episodes"].values() for x in e["solves"]]
    assert cost["solver_iterations"] == sum(x["iterations"] for x in runs) > 0
    assert "seconds" not in json.dumps(s.procedure["episodes"]) and "wall" not in s.procedure
    assert s.procedure["command"] == "mrd-env suite build spec.json"


def test_a_record_file_scenario_uses_the_users_road(serial):
    """The user's road is copied beside the suite, named by its content, and the episode a controller meets is on it:
    the best constant command, replayed at the procedure's 1 ms step on the written suite's episode, pays the stored
    R_p; the same road with a 2 mm, 8 Hz ripple added would not."""
    s = read_suite(serial)
    sc = s.scenarios[1]
    name = sc.options["road_params"]["path"]
    assert name.startswith("data-") and name.endswith("-my-road.csv") and (serial.parent / name).is_file()
    content = (serial.parent / name).read_bytes()
    assert content == (serial.parent.parent / "roads" / "my-road.csv").read_bytes()
    assert s.procedure["files"] == {name: hashlib.sha256(content).hexdigest()}
    ref = s.reference(sc.label(0))

    def constant_return(options) -> float:
        env = gym.make(s.env_id, **options, control_dt=sr.STEP)
        env.reset(seed=0)
        total, done = 0.0, False
        while not done:
            _, r, term, trunc, _ = env.step(np.array([ref.passive_command]))
            total, done = total + float(r), term or trunc
        env.close()
        return total

    options = s.reference_options(sc, 0)
    assert constant_return(options) == pytest.approx(ref.passive, rel=1e-9, abs=1e-12)
    other = serial.parent / "other-road.csv"
    lines = content.decode().splitlines()
    other.write_text("\n".join([lines[0]] + [f"{t},{float(z) + 2e-3 * np.sin(16 * np.pi * float(t))}" for t, z in
                                               (x.split(",") for x in lines[1:])]) + "\n", encoding="utf-8")
    options["road_params"] = {**options["road_params"], "path": str(other)}
    assert abs(constant_return(options) - ref.passive) > 1e-6 * abs(ref.passive)


def test_an_interrupted_build_resumes_without_solving_its_kept_episodes(serial, tmp_path, monkeypatch):
    spec = write_spec(tmp_path, spec_data())
    plant_name, env_id, d = suite_spec(spec)
    out = tmp_path / "tiny-build-v1.json"
    real, calls = sr.episode_references, []

    def interrupted(*args, **kwargs):
        if calls:
            raise KeyboardInterrupt  # Ctrl-C while the second episode is being solved
        calls.append(args[2])
        return real(*args, **kwargs)

    monkeypatch.setattr(sr, "episode_references", interrupted)
    with pytest.raises(KeyboardInterrupt):
        sr.build_suite(d, plant_name, env_id, out, progress=False, command=sr.spec_command(spec), say=lambda _: None)
    assert not out.exists() and len(list(sr.partial_folder(out).glob("episode-*.json"))) == 1

    solved = []
    monkeypatch.setattr(sr, "episode_references", lambda *a, **k: solved.append(a[2]) or real(*a, **k))
    b = sr.build_suite(d, plant_name, env_id, out, progress=False, command=sr.spec_command(spec), say=lambda _: None)
    assert solved == ["my road"] and calls == ["ISO-C"]  # the kept episode was not solved again
    assert out.read_bytes() == serial.read_bytes() and not sr.partial_folder(out).exists()
    assert (b.record["episodes_kept"], b.record["episodes_solved"]) == (1, 1)
    assert b.record["episodes"]["ISO-C"]["kept"] and not b.record["episodes"]["my road"]["kept"]


@pytest.mark.slow
def test_a_build_is_the_same_bytes_on_ray(serial, tmp_path, capsys):
    """A local Ray instance's workers give the serial bytes (10 s, most of it Ray's start)."""
    pytest.importorskip("ray")
    spec = write_spec(tmp_path, spec_data())
    rc, _, err = _build([spec, "--backend", "ray", "--jobs", "2", "--out", tmp_path / "ray.json"], capsys)
    assert rc == 0, err
    assert (tmp_path / "ray.json").read_bytes() == serial.read_bytes()


def test_suite_show_prints_the_episodes_and_references(serial, capsys):
    assert main(["suite", "show", str(serial)]) == 0
    out = capsys.readouterr().out
    assert "tiny-build-v1" in out and "| my road | 1 |" in out and "2 episodes" in out


# -------------------------------------------------------------------------------------------- the shipped specs

def test_every_shipped_suite_is_built_from_its_spec():
    """One home per definition: each shipped suite's spec (``<plant>/suites/specs/<id>.json``) gives exactly the
    shipped file's definition (what its digest covers but the references and procedure), and each spec has its
    suite."""
    shipped = suites()
    specs = sorted(PLANTS_FOLDER.glob("*/suites/specs/*.json"))
    assert sorted(p.stem for p in specs) == sorted(shipped)
    for path in specs:
        s = shipped[path.stem]
        plant_name, env_id, d = suite_spec(path)
        assert (plant_name, env_id, d.id) == (s.plant, s.env_id, s.id) == (path.parent.parent.parent.name, s.env_id,
                                                                          path.stem)
        built = d.suite(plant_name, env_id, s.randomised.get("draws"))
        assert json.dumps(built.definition_json()) == json.dumps(s.definition_json()), s.id
        assert read_spec(path) == d and sr.spec_command(path).endswith(f"suites/specs/{s.id}.json")


# procedures 3's to 5's parts run in CI (tests/experiments/test_certify.py, the kept batch below,
# tests/jax/test_limit_penalty.py); their whole builds are slow
@pytest.mark.parametrize("procedure", [2, *(pytest.param(p, marks=pytest.mark.slow) for p in (3, 4, 5))])
def test_procedures_2_to_5_certify_the_clairvoyant_at_the_suites_control_step(procedure, tmp_path):
    """Procedure 2 (the default): the references in the suite's own action space, each episode's clairvoyant found by
    two solution paths that agree within 0.5 % of its range; the certificate is in the suite file, and the stored
    R_c is paid by the environment at the suite's control step to a command sequence the paths found. Procedure 3:
    the same, the gradient path's round 1 run for the scenario's episodes together; procedure 4: procedure 3 with
    round 2 from the other path's optimum first; procedure 5: procedure 4, the gradient path kept off the limits."""
    pytest.importorskip("jax")
    data = spec_data()
    del data["procedure"]
    if procedure != 2:
        data["procedure"] = procedure
    data["scenarios"] = data["scenarios"][:1]
    spec = write_spec(tmp_path, data)
    plant_name, env_id, d = suite_spec(spec)
    assert d.procedure == procedure
    said = []
    b = sr.build_suite(d, plant_name, env_id, tmp_path / "v2.json", backend="serial", progress=False,
                       command=sr.spec_command(spec), say=said.append)
    assert any("round 1 on its 1 episode(s) together" in x for x in said) == (procedure >= 3)
    s = read_suite(b.path)
    assert s.procedure["version"] == procedure
    (label,) = s.labels()
    cert = s.procedure["episodes"][label]["certificate"]
    assert cert["certified"] and cert["disagreement"] <= 0.005 and cert["round"] in (1, 2)
    r = s.reference(label)
    assert r.clairvoyant > r.passive
    paths = {x["path"] for x in s.procedure["episodes"][label]["solves"]}
    assert paths == {"casadi", "gradient"}
    # R_p is paid at the suite's 10 ms step: a constant command held for the episode in the environment itself
    env = gym.make(s.env_id, **s.episode_options(*s.episodes()[0]), control_dt=s.control_dt)
    env.reset(seed=s.episodes()[0][1])
    total, done = 0.0, False
    while not done:
        _, rew, term, trunc, _ = env.step(np.array([r.passive_command]))
        total += rew
        done = term or trunc
    assert total == pytest.approx(r.passive, rel=1e-9)


def test_a_spec_names_a_known_procedure(tmp_path, capsys):
    spec = write_spec(tmp_path, spec_data(procedure=6))
    rc, _, err = _build([spec], capsys)
    assert rc == 2 and "procedure must be one of [1, 2, 3, 4, 5]" in err and err.count("\n") == 1


def test_an_uncertified_episode_fails_the_build_after_the_others_are_kept(serial, tmp_path, monkeypatch):
    """An episode whose two paths disagree is never stored, and does not cost the build its other episodes: they are
    solved and kept, the build fails naming the uncertified one, and a build run again solves only that one."""
    spec = write_spec(tmp_path, spec_data())
    plant_name, env_id, d = suite_spec(spec)
    out = tmp_path / "tiny-build-v1.json"
    real = sr.episode_references

    def disagreeing(*args, **kwargs):
        if args[2] == "ISO-C":
            return {"uncertified": "ISO-C: the two solution paths disagree by 2.35% of its range", "wall_s": 0.0}
        return real(*args, **kwargs)

    monkeypatch.setattr(sr, "episode_references", disagreeing)
    with pytest.raises(sr.UncertifiedEpisode, match=r"1 episode\(s\) not certified.*ISO-C: the two solution paths"):
        sr.build_suite(d, plant_name, env_id, out, progress=False, command=sr.spec_command(spec), say=lambda _: None)
    assert not out.exists() and len(list(sr.partial_folder(out).glob("episode-*.json"))) == 1   # "my road" kept
    solved = []
    monkeypatch.setattr(sr, "episode_references", lambda *a, **k: solved.append(a[2]) or real(*a, **k))
    sr.build_suite(d, plant_name, env_id, out, progress=False, command=sr.spec_command(spec), say=lambda _: None)
    assert solved == ["ISO-C"] and out.read_bytes() == serial.read_bytes()


def test_procedure_3_keeps_each_scenarios_batch_and_a_build_run_again_uses_it(tmp_path, monkeypatch):
    """The batched round 1 of a scenario is kept in the build's folder as soon as it is solved (plain JSON), and a
    build run again reads it instead of solving the batch again: the same results, commands included."""
    from experiments.benchmark import certify

    calls = []

    def fake(problems, starts, n_starts, limit_penalty=False):
        calls.append(len(problems))
        return [certify.PathResult(-1.0 - i, np.full((p.n_steps, p.nd), 0.5 + i), -1.0 - i,
                                   [{"start": "best constant", "status": "s", "success": True, "iterations": 3,
                                     "evaluations": 4, "return": -1.0 - i}]) if i == 0 else
                certify.PathResult(-2.0, None, -np.inf, []) for i, p in enumerate(problems)]

    monkeypatch.setattr(certify, "batched_gradient_paths", fake)
    road = {"road": "iso8608", "road_params": {"road_class": "C", "speed": 20.0}, "episode_seconds": 0.2}
    eps = [("C s1", road, 1, "C"), ("C s2", road, 2, "C")]
    keys = {label: sr.episode_key("mrd_env/QuarterCarPhysical-v0", o, label, s, ("skyhook_on_off",), 3, 0.01)
            for label, o, s, _ in eps}
    args = ("mrd_env/QuarterCarPhysical-v0", eps, ("skyhook_on_off",), 0.01)
    said = []
    first = sr.batched_round_1(*args, say=said.append, keep=tmp_path, keys=keys)
    again = sr.batched_round_1(*args, say=said.append, keep=tmp_path, keys=keys)
    assert calls == [2] and "kept from an interrupted build" in said[-1]
    assert first.keys() == again.keys() == {"C s1", "C s2"}
    for label in first:
        a, b = first[label], again[label]
        assert (a.ret, a.commands_ret, a.runs, a.found) == (b.ret, b.commands_ret, b.runs, b.found)
        assert (a.commands is None and b.commands is None) or np.array_equal(a.commands, b.commands)
    kept = [json.loads(f.read_text()) for f in tmp_path.glob("*.json")]  # plain JSON: no NaN or Infinity
    assert len(kept) == 1 and "Infinity" not in json.dumps(kept, allow_nan=False)
    assert [f.name[:6] for f in tmp_path.glob("*.json")] == ["batch-"]  # not counted as a solved episode
