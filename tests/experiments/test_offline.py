"""Offline agents (issue 53 item 3): behaviour cloning recovers a known policy from its recorded episodes, TD3+BC
trains on a dataset into an agent that loads and scores, both bit for bit from their seed, and a dataset that does
not fit the agent is one line on stderr with exit 2, before anything is written."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("minari")
pytest.importorskip("h5py")

from experiments.benchmark.dataset import record  # noqa: E402
from experiments.cli import main  # noqa: E402
from experiments.common.plants import profile  # noqa: E402
from experiments.common.scenarios import preview_options  # noqa: E402
from experiments.training.offline import training_suite  # noqa: E402
from experiments.training.trainers import env_options, train_one  # noqa: E402
from mrd_env.suites import SuiteScenario  # noqa: E402

CAR = profile("quarter_car")
#: The known policy's weights on (travel_rate, sprung_vel, road_preview at 50 ms): its command is linear in them.
WEIGHTS = {"travel_rate": 1.5, "sprung_vel": 2.0, "road_preview": 6.0}


class LinearPolicy:
    """A command linear in three sensors, u = 1 A + w·o (A), clipped to the damper's 0-2 A: the policy to recover."""

    def __init__(self, env):
        layout = {n: sl for n, sl, _ in env.sensor_layout}
        self.w = np.zeros(env.single_observation_space.shape[0])
        self.w[layout["travel_rate"].start] = WEIGHTS["travel_rate"]
        self.w[layout["sprung_vel"].start] = WEIGHTS["sprung_vel"]
        self.w[layout["road_preview"].start + 4] = WEIGHTS["road_preview"]
        box = env.single_action_space
        self.low, self.high = float(box.low[0]), float(box.high[0])

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        mid = 0.5 * (self.low + self.high)
        return np.clip(mid + obs @ self.w, self.low, self.high)[:, None].astype(np.float32), state


def tiny_suite(seeds: int, first_seed: int = 0, seconds: float = 1.0):
    """The training distribution (seeds first_seed ...) in episodes of ``seconds``, car-preview-v1's sensors."""
    s = training_suite(CAR, episodes=seeds, first_seed=first_seed)
    sc = s.scenarios[0]
    return replace(s, scenarios=(SuiteScenario(sc.name, {**sc.options, "episode_seconds": seconds}, sc.seeds),))


@pytest.fixture(scope="module")
def linear_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("offline") / "datasets"
    record(tiny_suite(8), LinearPolicy, name="linear", root=root)
    return root


def preview_kwargs():
    return preview_options(CAR, env_options(CAR))


def test_behaviour_cloning_recovers_a_known_linear_policy_on_unseen_episodes(linear_dataset, tmp_path):
    from controllers import load_agent
    from experiments.benchmark.dataset import load

    folder = train_one(CAR, "bc", 0, out=tmp_path, timesteps=3000, eval_freq=0, dataset=linear_dataset,
                       env_kwargs=preview_kwargs(), hyper={"batch_size": 64})
    agent = load_agent(folder)
    assert agent.name == "BC preview s0" and agent.meta["dataset"]["episodes"] == 8
    # unseen episodes of the same distribution (seeds 100-103), the commands mapped onto [-1, 1] as the agent acts
    held_out = record(tiny_suite(4, first_seed=100), LinearPolicy, name="linear", root=tmp_path / "held-out")[0]
    eps = list(load(held_out.dataset_id, tmp_path / "held-out").iterate_episodes())
    obs = np.concatenate([e.observations[:-1] for e in eps])
    want = np.concatenate([e.actions for e in eps])[:, 0] - 1.0     # 0-2 A onto [-1, 1]
    assert 0.05 < np.mean(np.abs(want) > 0.999) < 0.5, "the policy must be linear on most steps, clipped on some"
    got = agent.predict(obs)[0][:, 0]
    r2 = 1 - np.mean((got - want) ** 2) / np.var(want)
    assert r2 > 0.99, f"BC explains {r2:.3f} of the policy's variance on unseen episodes"
    # the dependence itself, not only the commands seen: where the policy is not clipped, moving one sensor moves
    # the agent's command by that sensor's weight
    import gymnasium as gym

    env = gym.make_vec(CAR.env_id, num_envs=1, vectorization_mode="vector_entry_point", **preview_kwargs())
    layout = {n: sl.start for n, sl, _ in env.unwrapped.sensor_layout}
    env.close()
    free = obs[np.abs(want) < 0.8]
    for sensor, w in WEIGHTS.items():
        col = layout[sensor] + (4 if sensor == "road_preview" else 0)
        step = 0.02 / w                                          # a 0.02 change of the command
        moved = free.copy()
        moved[:, col] += step
        slope = np.median((agent.predict(moved)[0][:, 0] - agent.predict(free)[0][:, 0]) / step)
        assert slope == pytest.approx(w, rel=0.2), f"d command / d {sensor}: {slope:.3f}, the policy's {w}"


def test_bc_and_td3bc_are_bit_for_bit_from_their_seed_and_td3bc_scores(linear_dataset, tmp_path):
    pytest.importorskip("torchrl")
    from controllers import load_agent
    from experiments.benchmark.scoring import score

    runs = {}
    for algo, steps in (("bc", 200), ("td3bc", 30)):
        for k in (1, 2):
            folder = train_one(CAR, algo, 3, out=tmp_path / f"{algo}{k}", timesteps=steps, eval_freq=0,
                               dataset=linear_dataset, env_kwargs=preview_kwargs(),
                               hyper={"batch_size": 32, "critic_hidden": [32, 32]} if algo == "td3bc" else None)
            runs[algo, k] = load_agent(folder)
        a, b = runs[algo, 1], runs[algo, 2]
        assert np.array_equal(a.model.theta, b.model.theta), f"{algo}: two runs of seed 3 differ"
    assert not np.array_equal(runs["bc", 1].model.theta[:10], runs["td3bc", 1].model.theta[:10])
    agent = runs["td3bc", 1]
    assert agent.meta["algo"] == "TD3+BC" and agent.meta["gradient_steps_done"] == 30
    result = score("car-preview-v1", str(agent.folder), episodes=1, backend="serial")
    assert len(result.episodes) == 4 and all(np.isfinite(e["return"]) for e in result.episodes)
    assert np.isfinite(result.pooled_shares()["all scenarios"][0])


def _fails(argv, capsys, out: Path, *words):
    assert main([*argv, "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    assert not out.exists() or not any(out.iterdir()), "a refused command wrote something"
    return err


def test_a_dataset_that_does_not_fit_is_refused_in_one_line_before_anything_is_written(linear_dataset, tmp_path,
                                                                                      capsys):
    out = tmp_path / "agents"
    _fails(["train", "--algo", "bc", "--preview"], capsys, out, "--dataset")
    _fails(["train", "--algo", "ppo", "--dataset", str(linear_dataset)], capsys, out, "--dataset applies", "bc")
    _fails(["train", "--algo", "bc", "--preview", "--dataset", str(tmp_path / "nowhere")], capsys, out,
           "not a folder")
    _fails(["train", "--algo", "bc", "--preview", "--dataset", str(tmp_path)], capsys, out, "no Minari dataset")
    # recorded with the road preview, trained without it: other observations
    _fails(["train", "--algo", "bc", "--dataset", str(linear_dataset)], capsys, out, "other observations",
           "road preview")
    _fails(["train", "--algo", "td3bc", "--preview", "--dataset", str(linear_dataset), "--set", "alpha=-1"], capsys,
           out, "alpha")
    # the benchmark's own episodes are never training data
    suite_data = tmp_path / "suite-data"
    record("car-preview-v1", "passive_on", root=suite_data, episodes=1, scenarios=["bump 5 cm"])
    _fails(["train", "--algo", "bc", "--preview", "--dataset", str(suite_data)], capsys, out,
           "benchmark suite car-preview-v1")
