"""The frozen benchmark suites (:mod:`mrd_env.suites`, docs/suites.md): the shipped files load and their digests
verify, an edited copy is refused, every shipped file is its profile's definition (a changed definition is a new
version), the procedure reproduces its references, and a twin's stored draws come back from its seed."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest

from experiments.benchmark import references as sr
from experiments.benchmark.certify import TOLERANCE
from mrd_env.plants import plants
from mrd_env.plants import suite_definition, suite_definitions
from mrd_env.suites import (SENSOR_OPTIONS, Suite, SuiteDefinition, SuiteScenario, content_digest, draws, read_suite,
                            suite, suite_path, suites, write_suite)


@pytest.fixture(scope="module")
def shipped() -> dict[str, Suite]:
    every = suites()
    assert every, "no suite is shipped"
    return every


def _car():
    """(plant name, env id, warm laws) of the plant that declares the preview suite (the profile with preview)."""
    spec = next(s for s in plants().values() if s.profile.preview and s.profile.suites)
    return spec.name, spec.physics_id, spec.profile.warm_laws


def test_shipped_suites_load_complete_and_verify(shipped):
    for sid, s in shipped.items():
        assert s.id == sid
        assert s.digest == content_digest({**s.to_json(), "digest": s.digest})
        assert s.complete(), f"{sid} lacks references"
        for label in s.labels():
            r = s.reference(label)
            assert math.isfinite(r.passive) and math.isfinite(r.clairvoyant)
            assert r.clairvoyant >= r.passive - 1e-12, label  # the best constant command is a warm start
            if math.isfinite(r.bound):
                assert r.bound >= r.clairvoyant - 1e-9, label
        # the command that built it: the maintenance script of the v1 suites, or the suite builder
        assert s.procedure.get("command", "").startswith(("python -m experiments.scripts.suite_references --suite ",
                                                          "mrd-env suite build "))


def test_every_certified_reference_is_the_best_of_two_paths_that_agree(shipped):
    """A suite built by procedure 2 or later stores, per episode, both paths' optimiser runs and the certificate:
    the two paths' best returns agree within 0.5 % of the range, the stored disagreement is theirs, and R_c is the
    agreed optimum (within the tolerance of the best run: it is the winning path's re-simulated commands)."""
    certified = {sid: s for sid, s in shipped.items() if s.procedure.get("version", 1) >= 2}
    assert certified, "no shipped suite is built by a certifying procedure"
    for sid, s in certified.items():
        for label in s.labels():
            ep, ref = s.procedure["episodes"][label], s.reference(label)
            best = {}
            for run in ep["solves"]:
                best[run["path"]] = max(best.get(run["path"], -math.inf), run["return"])
            assert set(best) == {"casadi", "gradient"}, (sid, label)
            top, gap = max(best.values()), max(best.values()) - ref.passive
            dis = abs(best["casadi"] - best["gradient"]) / gap
            cert = ep["certificate"]
            assert cert["certified"] and cert["round"] in (1, 2), (sid, label)
            assert dis <= TOLERANCE and dis == pytest.approx(cert["disagreement"], abs=1e-6), (sid, label, dis)
            assert ref.clairvoyant <= top + 1e-12 and top - ref.clairvoyant <= TOLERANCE * gap, (sid, label)


def test_an_edited_copy_is_refused(shipped, tmp_path):
    s = next(iter(shipped.values()))
    data = json.loads(suite_path(s.plant, s).read_text(encoding="utf-8"))
    label = next(iter(data["references"]))
    data["references"][label]["clairvoyant"] += 1e-6
    path = tmp_path / f"{s.id}.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(ValueError) as err:
        read_suite(path)
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg and "digest" in msg
    path.write_text("{not json", encoding="utf-8")
    with pytest.raises(ValueError, match="cannot be read"):
        read_suite(path)


def test_suite_ids_unique_and_files_are_their_definitions(shipped):
    every = suite_definitions()  # raises on a suite declared twice
    names = [d.name for _, _, d in every.values()]
    assert len(every) == len({(d.name, d.version) for _, _, d in every.values()})
    for name in set(names):  # several versions of one suite may ship (v1 stays scoreable): the name means the latest
        assert suite(name).version == max(d.version for _, _, d in every.values() if d.name == name), name
    for sid, s in shipped.items():
        assert sid in every, f"{sid} is shipped but no profile declares it"
        plant, env_id, d = every[sid]
        assert (s.plant, s.env_id) == (plant, env_id)
        # the file's definition is the profile's: a changed definition must be a new version (and a new file)
        assert s.definition_json() == d.suite(plant, env_id, s.randomised.get("draws")).definition_json(), sid
        assert suite(sid) is not None and suite(d.name).version >= s.version
    with pytest.raises(ValueError, match="suite must be one of"):
        suite("no-such-suite")


def test_preview_suite_says_who_has_preview_and_shares_references(shipped):
    _, _, d = suite_definition("car-preview")
    assert "road_preview" in d.options["sensors"] and d.options["preview"]
    _, _, comfort = suite_definition(d.references_id)
    # a name without version is the twin's own version: car-comfort-v2 leaves car-preview-v1 on car-comfort-v1's
    assert suite_definition("car-preview-v1")[2].references_id == "car-comfort-v1"
    assert "road_preview" not in comfort.options["sensors"]
    if d.id in shipped and comfort.id in shipped:
        p, c = shipped[d.id], shipped[comfort.id]
        assert p.references == c.references and p.procedure["references_of_digest"] == c.digest
        assert [p.reference_options(*e) for e in p.episodes()] == [c.reference_options(*e) for e in c.episodes()]


def test_every_suite_that_shares_references_has_the_same_episodes(shipped):
    """Every ``references_of`` suite (the preview twins, nominal and randomised) ships its source's references,
    and its episodes are the source's on the same plant: the same reference options, the same drawn plants."""
    sharing = [(sid, d) for sid, (_, _, d) in suite_definitions().items() if d.references_of]
    assert any(d.randomise for _, d in sharing), "no randomised twin shares references"
    for sid, d in sharing:
        _, _, src = suite_definition(d.references_id)
        assert sid in shipped and src.id in shipped, sid
        p, c = shipped[sid], shipped[src.id]
        assert p.references == c.references and p.procedure["references_of_digest"] == c.digest, sid
        assert [p.reference_options(*e) for e in p.episodes()] == [c.reference_options(*e) for e in c.episodes()]
        if d.randomise:
            assert p.randomised["draws"] and {k: {o: v for o, v in dr.items() if o not in SENSOR_OPTIONS}
                                               for k, dr in p.randomised["draws"].items()} == \
                {k: {o: v for o, v in dr.items() if o not in SENSOR_OPTIONS} for k, dr in c.randomised["draws"].items()}


def _constant_command_return(env_id: str, options: dict, seed: int, control_dt: float) -> float:
    import gymnasium as gym

    env = gym.make(env_id, **options, control_dt=control_dt)
    env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        _, r, term, trunc, _ = env.step(0.5 * (env.action_space.low + env.action_space.high))
        total, done = total + float(r), term or trunc
    env.close()
    return total


def test_the_sensor_options_change_no_episode(shipped):
    """The references are computed without the sensor options (preview, noise, ...): a constant command's return on
    the episode a controller meets (with them) must equal the one on the references' episode, on every shipped
    suite — a preview that changed the road (the full car's v2 did) would score controllers against other roads'
    references."""
    for s in shipped.values():
        sc, seed = s.episodes()[0]
        got = _constant_command_return(s.env_id, s.episode_options(sc, seed), seed, s.control_dt)
        want = _constant_command_return(s.env_id, s.reference_options(sc, seed), seed, s.control_dt)
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12), (s.id, got, want)


def test_reference_options_drop_the_sensors(shipped):
    s = shipped.get("car-preview-v1") or next(iter(shipped.values()))
    sc, seed = s.episodes()[0]
    assert not set(SENSOR_OPTIONS) & set(s.reference_options(sc, seed))
    assert s.episode_options(sc, seed)["sensors"] == list(s.options["sensors"])


def test_a_shipped_best_constant_command_is_reproduced(shipped):
    s = shipped["car-comfort-v1"] if "car-comfort-v1" in shipped else next(iter(shipped.values()))
    sc, seed = s.episodes()[-1]
    rp, vp = sr.best_constant(sr.episode_problem(s.env_id, s.reference_options(sc, seed), seed))
    ref = s.reference(sc.label(seed))
    assert abs(rp - ref.passive) <= 1e-9 * max(1.0, abs(ref.passive)) and vp == ref.passive_command


def test_the_procedure_is_deterministic_on_a_tiny_suite(tmp_path):
    plant, env_id, warm = _car()
    d = SuiteDefinition(name="tiny", version=1, description="one 0.2 s episode", options={}, control_dt=0.01,
                        scenarios=(SuiteScenario("ISO-C", {"road": "iso8608", "road_params": {"road_class": "C"},
                                                           "episode_seconds": 0.2}, (7,)),),
                        criteria=("acc_weighted_rms",))
    s = d.suite(plant, env_id)
    sc, seed = s.episodes()[0]
    a, b = (sr.episode_references(env_id, s.reference_options(sc, seed), sc.label(seed), seed, warm, cache=False)
            for _ in range(2))
    assert a["reference"] == b["reference"]
    r = a["reference"]
    assert r["passive"] <= r["clairvoyant"] <= r["bound"]
    from mrd_env.suites import Reference

    path = write_suite(replace(s, references={sc.label(seed): Reference(**r)}, procedure={"command": "test"}),
                       tmp_path / "tiny-v1.json")
    back = read_suite(path)
    assert back.references == {sc.label(seed): Reference(**r)} and back.complete()


def test_twin_draws_reproduce_from_the_seed(shipped):
    for sid, (plant, env_id, d) in suite_definitions().items():
        if not d.randomise:
            continue
        again = draws(d, env_id)
        assert set(again) == {sc.label(seed) for sc in d.scenarios for seed in sc.seeds}
        if sid in shipped:
            assert shipped[sid].randomised["draws"] == again, sid
        first = next(iter(again.values()))
        for name, (lo, hi) in d.randomise.get("sensor_noise", {}).items():
            assert lo <= first["sensor_noise"][name] <= hi
        assert first["sensor_delay"] in d.randomise["sensor_delay"]
        # different episodes draw different plants
        assert len({json.dumps(v["damper_params"], sort_keys=True) for v in again.values()}) == len(again)


def test_the_script_refuses_a_changed_definition(tmp_path, shipped):
    s = next(s for s in shipped.values() if not s.procedure.get("references_of"))
    path = tmp_path / f"{s.id}.json"
    write_suite(s, path)
    changed = replace(s, scenarios=s.scenarios[:-1])
    with pytest.raises(ValueError, match="another definition"):
        sr._check_out(path, changed, overwrite=True, shipped=True)
    with pytest.raises(ValueError, match="frozen"):
        sr._check_out(path, s, overwrite=False, shipped=True)
    sr._check_out(path, s, overwrite=True, shipped=True)


@pytest.mark.slow
def test_a_shipped_clairvoyant_is_reproduced(shipped):
    s = shipped["car-comfort-v1"]
    sc, seed = s.episodes()[-1]  # the bump: one episode of 3 s
    _, _, warm = _car()
    r = sr.episode_references(s.env_id, s.reference_options(sc, seed), sc.label(seed), seed, warm, cache=False)
    ref = s.reference(sc.label(seed))
    assert r["reference"]["clairvoyant"] == pytest.approx(ref.clairvoyant, rel=1e-6)
    assert r["reference"]["bound"] == pytest.approx(ref.bound, rel=1e-4)
