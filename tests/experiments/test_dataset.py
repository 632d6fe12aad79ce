"""``mrd-env dataset``: a law's episodes on a suite, recorded as Minari datasets, load with ``minari.load_dataset``;
the recorded actions replayed in the recovered environment from the recorded seeds give the recorded rewards and
observations bit for bit; the episodes are the score's; bad input is one line and exit 2, and changes nothing."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("minari", reason="mrd-env dataset needs minari (pip install 'mrd-env[datasets]')")
pytest.importorskip("h5py", reason="Minari's HDF5 storage needs h5py (pip install 'mrd-env[datasets]')")

from experiments.cli import main  # noqa: E402

SUITE = "car-preview-v1"
LAW = "skyhook_continuous"
SCENARIOS = ("ISO-C 20 m/s", "bump 5 cm")
ARGV = ["dataset", "--suite", SUITE, "--controller", LAW, "--episodes", "2", "--no-progress",
        *[a for s in SCENARIOS for a in ("--scenario", s)]]
IDS = [f"mrd-env/{SUITE}/iso-c-20-m-s/skyhook-continuous-v0", f"mrd-env/{SUITE}/bump-5-cm/skyhook-continuous-v0"]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    root = tmp_path_factory.mktemp("datasets")
    assert main([*ARGV, "--out", str(root)]) == 0
    return root


def _load(root, dataset_id, monkeypatch):
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))  # Minari's own setting: what a user sets
    return minari.load_dataset(dataset_id)


def test_the_recorded_actions_replayed_give_the_recorded_rewards_and_observations(recorded, monkeypatch):
    import gymnasium as gym

    from mrd_env.suites import suite

    s = suite(SUITE)
    for dataset_id, scenario in zip(IDS, SCENARIOS):
        ds = _load(recorded, dataset_id, monkeypatch)
        sc = next(x for x in s.scenarios if x.name == scenario)
        seeds = [m["seed"] for m in ds.storage.get_episode_metadata(ds.episode_indices)]
        assert seeds == list(sc.seeds[:2])
        env = ds.recover_environment()
        assert env.unwrapped.control_dt == s.control_dt and env.spec.kwargs["road"] == sc.options["road"]
        assert isinstance(env.observation_space, gym.spaces.Box) and env.observation_space == ds.observation_space
        for ep, seed in zip(ds.iterate_episodes(), seeds):
            obs, info = env.reset(seed=seed)
            np.testing.assert_array_equal(obs, ep.observations[0])
            costs = [info["cost"]]
            for k, a in enumerate(ep.actions):
                obs, r, term, trunc, info = env.step(a)
                assert r == ep.rewards[k], (dataset_id, seed, k)          # bit for bit
                np.testing.assert_array_equal(obs, ep.observations[k + 1])
                assert (term, trunc) == (ep.terminations[k], ep.truncations[k])
                costs.append(info["cost"])
            assert ep.terminations[-1] or ep.truncations[-1]
            np.testing.assert_array_equal(ep.infos["cost"], costs)      # the CMDP cost, every step
            np.testing.assert_allclose(np.diff(ep.infos["t"]), s.control_dt, rtol=1e-9)
            assert np.all(ep.actions >= 0.0) and np.all(ep.actions <= env.action_space.high)
        env.close()


def test_the_episodes_are_the_scores(recorded, monkeypatch):
    """The returns recorded are those ``mrd-env score`` gives on the same episodes: the controller saw what the
    suite gives it (the suite's sensors with the preview, its control step, its seeds)."""
    from experiments.benchmark.scoring import score

    result = score(SUITE, LAW, episodes=2, progress=False, backend="serial")
    scored = {(e["scenario"], e["seed"]): e["return"] for e in result.episodes}
    for dataset_id, scenario in zip(IDS, SCENARIOS):
        ds = _load(recorded, dataset_id, monkeypatch)
        meta = ds.storage.metadata["mrd_env"]
        assert meta["causal"] is True and meta["suite"]["id"] == SUITE and meta["controller"]["name"] == LAW
        layout = meta["columns"]["observation"]   # what each column is: the suite's sensors, the preview last
        assert layout[-1]["sensor"] == "road_preview" and layout[-1]["columns"][1] == ds.observation_space.shape[0]
        for ep, m in zip(ds.iterate_episodes(), meta["episodes"]):
            assert float(np.sum(ep.rewards)) == pytest.approx(scored[(scenario, m["seed"])], abs=1e-12)
            assert m["return"] == pytest.approx(float(np.sum(ep.rewards)), abs=1e-12)
            assert m["passive"] < m["clairvoyant"]   # the suite's stored references, for the share


def test_bad_input_is_one_line_exit_2_and_changes_nothing(recorded, capsys):
    files = sorted((p, p.stat().st_mtime_ns, p.stat().st_size) for p in recorded.rglob("*") if p.is_file())
    errors = []
    for argv in ([*ARGV, "--out", str(recorded)],                                   # exists, no --overwrite
                 ["dataset", "--suite", "nope", "--controller", LAW, "--out", str(recorded)],
                 ["dataset", "--suite", SUITE, "--controller", "nope", "--out", str(recorded)],
                 ["dataset", "--suite", SUITE, "--controller", "groundhook_typo", "--out", str(recorded)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("mrd-env dataset: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
        errors.append(err)
    assert f"dataset {IDS[0]} exists" in errors[0] and "--overwrite" in errors[0], errors[0]
    assert sorted((p, p.stat().st_mtime_ns, p.stat().st_size) for p in recorded.rglob("*") if p.is_file()) == files


def test_overwrite_replaces_a_dataset_whole(recorded, monkeypatch):
    assert main(["dataset", "--suite", SUITE, "--controller", LAW, "--episodes", "1", "--scenario", SCENARIOS[1],
                 "--no-progress", "--overwrite", "--out", str(recorded)]) == 0
    ds = _load(recorded, IDS[1], monkeypatch)
    assert ds.total_episodes == 1 and not [p for p in recorded.rglob("*staging*")]


def test_without_minari_the_line_names_the_extra(monkeypatch, capsys, tmp_path):
    import sys

    monkeypatch.setitem(sys.modules, "minari", None)   # what a machine without the extra raises
    assert main(["dataset", "--suite", SUITE, "--controller", LAW, "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'mrd-env[datasets]'" in err, err
    assert not (tmp_path / "d").exists()
