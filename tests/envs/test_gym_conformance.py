"""Gymnasium's own environment and vector-environment tests, for every registered id.

What Gymnasium's test suite asserts of its environments (``tests/envs/test_envs.py``), their specs
(``tests/envs/registration/test_make_vec.py``, ``test_env_spec.py``: every registered id, v0 and v1) and vector
environments (``tests/vector/test_vector_env.py``, ``test_autoreset_mode.py``, ``test_vector_env_info.py``), written here
for the mrd_env ids with the installed Gymnasium's checkers (``gymnasium.utils.env_checker``,
``passive_env_checker``, ``env_match``), nothing vendored; and the integrity points of issue 21 (refused calls
change nothing, batched infos as SyncVectorEnv's, reset masks, make_vec's keywords, episode lengths in the spec,
the options every id takes, render_fps, the SB3 bridge). Episodes are short (``SHORT``) to keep this fast.
"""
from __future__ import annotations

import copy
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence
from gymnasium.utils.env_match import check_environments_match
from gymnasium.utils.passive_env_checker import env_render_passive_checker
from gymnasium.vector import AutoresetMode

import mrd_env  # noqa: F401  (registers the environments)
from mrd_env.envs.vector import env_info
from mrd_env.plants import plant_of_id
from mrd_env.plants.registry import envs as _envs

ENVS = _envs()

IDS = tuple(ENVS)
SPECS = [gym.spec(i) for i in IDS]
SHORT = dict(episode_seconds=0.1, control_dt=0.01)
MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
#: the warnings Gymnasium's own test accepts (tests/envs/test_envs.py, CHECK_ENV_IGNORE_WARNINGS)
ACCEPTED = ("A Box observation space minimum value is -infinity", "A Box observation space maximum value is infinity",
            "For Box action spaces, we recommend using a symmetric and normalized space")


def _unexpected(caught) -> list[str]:
    return [str(w.message) for w in caught if not any(a in str(w.message) for a in ACCEPTED)]


def _frame_ok(frame) -> bool:
    """Gymnasium's check_rendered for "rgb_array"."""
    return isinstance(frame, np.ndarray) and frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8


# ---------------------------------------------------------------------------------------------------------------
# tests/envs/test_envs.py

@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_envs_pass_env_checker(spec):
    """check_env, render modes included, with no warnings but those Gymnasium's test accepts."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = spec.make(disable_env_checker=True, **SHORT).unwrapped
        check_env(env)
        env.close()
    assert not _unexpected(caught), _unexpected(caught)


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_env_determinism_rollout(spec):
    env_1 = spec.make(disable_env_checker=True, **SHORT)
    env_2 = spec.make(disable_env_checker=True, **SHORT)
    assert data_equivalence(env_1.reset(seed=0), env_2.reset(seed=0), exact=True)
    env_1.action_space.seed(0)
    for _ in range(50):  # five episodes
        action = env_1.action_space.sample()
        step_1, step_2 = env_1.step(action), env_2.step(action)
        assert env_1.observation_space.contains(step_1[0])
        assert data_equivalence(step_1, step_2, exact=True)
        if step_1[2] or step_1[3]:
            assert data_equivalence(env_1.reset(seed=0), env_2.reset(seed=0), exact=True)


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_render_modes(spec):
    env = spec.make(**SHORT)
    assert "rgb_array" in env.metadata["render_modes"]
    for mode in env.metadata["render_modes"]:
        if mode != "human":
            new_env = spec.make(render_mode=mode, **SHORT)
            new_env.reset()
            assert _frame_ok(new_env.render())
            new_env.step(new_env.action_space.sample())
            assert _frame_ok(new_env.render())
            new_env.close()
    env.close()


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_pickle_env(spec):
    env = spec.make(**SHORT)
    env.reset(seed=0)
    pickled_env = pickle.loads(pickle.dumps(env))
    assert data_equivalence(env.reset(), pickled_env.reset(), exact=True)  # the generator was copied too
    action = env.action_space.sample()
    assert data_equivalence(env.step(action), pickled_env.step(action), exact=True)
    env.close()
    pickled_env.close()


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_passive_env_checker_warns_of_nothing(spec):
    """gym.make wraps the env in PassiveEnvChecker: a rollout (reset, steps to the episode end, render) raises
    no warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = spec.make(render_mode="rgb_array", **SHORT)
        env.reset(seed=1)
        assert _frame_ok(env_render_passive_checker(env.unwrapped))
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(env.action_space.sample())
            done = term or trunc
        env.render()
    assert not [str(w.message) for w in caught], [str(w.message) for w in caught]


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_environments_match_a_copy(spec):
    """gymnasium.utils.env_match.check_environments_match: an env and its deep copy, renders included."""
    env_a = spec.make(render_mode="rgb_array", **SHORT)
    env_a.reset(seed=2)
    check_environments_match(env_a, copy.deepcopy(env_a), num_steps=12, seed=2, info_comparison="equivalence")


# ---------------------------------------------------------------------------------------------------------------
# tests/vector: the native vector env against SyncVectorEnv over the scalar envs

def _small_stroke_limit(env_id, fraction: float = 0.5) -> float:
    """A stroke limit the random commands exceed in some of the short episodes: ``fraction`` of the median over
    three seeds of the largest stroke a scalar environment reaches in 35 random steps (ended episodes restarted
    with the next seed) — the plant's own scale, so that every plant gets terminations among truncations."""
    env = gym.make(env_id, **SHORT).unwrapped
    env.action_space.seed(0)
    peaks = []
    for seed in range(3):
        env.reset(seed=seed)
        peak = 0.0
        for _ in range(35):
            _, _, term, trunc, _ = env.step(env.action_space.sample())
            peak = max(peak, float(np.abs(env.signal(env.roles["damper_stroke"])).max()))
            if term or trunc:
                env.reset()
        peaks.append(peak)
    return fraction * float(np.median(peaks))


def _pair(env_id, mode, num_envs=3, **kw):
    kw = {**SHORT, **kw}
    native = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                          **kw)
    sync = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode},
                        **kw)
    return native, sync


@pytest.mark.parametrize("mode", MODES, ids=[m.value for m in MODES])
@pytest.mark.parametrize("env_id", IDS)
def test_vector_env_equals_sync_vector_env(env_id, mode):
    """Gymnasium's test_vector_env_equal: spaces, observations, rewards, flags and infos (batched with their
    ``_key`` masks, ``final_obs``/``final_info`` in SAME_STEP mode) as SyncVectorEnv over the scalar envs gives
    them, bit for bit, over several autoresets and a termination (issue 21, items 3 and 4)."""
    # a stroke limit the random commands exceed in some environments: terminations among truncations
    native, sync = _pair(env_id, mode, stroke_limit=_small_stroke_limit(env_id), sensor_noise={"damper_force": 2.0})
    assert native.num_envs == sync.num_envs
    assert native.observation_space == sync.observation_space
    assert native.single_observation_space == sync.single_observation_space
    assert native.action_space == sync.action_space and native.single_action_space == sync.single_action_space
    assert native.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"] == mode
    assert data_equivalence(native.reset(seed=0), sync.reset(seed=0), exact=True)
    native.action_space.seed(0)
    reasons = set()
    for _ in range(35):
        actions = native.action_space.sample()
        out_n, out_s = native.step(actions), sync.step(actions)
        assert data_equivalence(out_n, out_s, exact=True), (out_n, out_s)
        info = out_n[4] if mode != AutoresetMode.SAME_STEP else out_n[4].get("final_info", {})
        reasons |= {r for r in info.get("termination_reason", ()) if r is not None}
        ended = out_n[2] | out_n[3]
        if mode == AutoresetMode.DISABLED and ended.any():
            mask = {"reset_mask": ended}
            assert data_equivalence(native.reset(options=dict(mask)), sync.reset(options=dict(mask)), exact=True)
    assert "stroke_limit" in reasons


def _sprung_energy(period):
    return -float(np.sum(period["sprung_acc"] ** 2))


@pytest.mark.parametrize("mode", MODES, ids=[m.value for m in MODES])
def test_vector_env_pays_a_callable_reward_as_sync_vector_env(mode):
    """A reward given as a Python function of the period's signals: the native vector env pays it, as the scalar
    environments under SyncVectorEnv do (it paid the compiled part only, zero here)."""
    native, sync = _pair("mrd_env/QuarterCarPhysical-v0", mode, reward=_sprung_energy)
    assert data_equivalence(native.reset(seed=0), sync.reset(seed=0), exact=True)
    native.action_space.seed(0)
    paid = []
    for _ in range(25):
        actions = native.action_space.sample()
        out_n, out_s = native.step(actions), sync.step(actions)
        assert data_equivalence(out_n, out_s, exact=True), (out_n[1], out_s[1])
        paid.append(out_n[1])
        ended = out_n[2] | out_n[3]
        if mode == AutoresetMode.DISABLED and ended.any():
            mask = {"reset_mask": ended}
            assert data_equivalence(native.reset(options=dict(mask)), sync.reset(options=dict(mask)), exact=True)
    assert np.min(paid) < 0.0


@pytest.mark.parametrize("env_id", IDS)
def test_reset_info_names_the_disturbance(env_id):
    venv = gym.make_vec(env_id, num_envs=2, **SHORT)
    _, info = venv.reset(seed=0)
    assert set(info) == {"t", "_t", "disturbance", "_disturbance", "cost", "_cost", "cost_terms", "_cost_terms"}
    assert info["_disturbance"].all() and all(isinstance(n, str) and n for n in info["disturbance"])


@pytest.mark.parametrize("env_id", IDS)
def test_autoreset_next_step(env_id):
    """Gymnasium's test_autoreset_next_step: the step after an episode ends returns the next episode's first
    observation, reward 0, both flags false, t = 0."""
    venv = gym.make_vec(env_id, num_envs=2, **SHORT)
    scalar = gym.make(env_id, **SHORT)
    venv.reset(seed=[4, 7])
    scalar.reset(seed=4)
    a = venv.action_space.sample()
    for _ in range(10):
        _, r, term, trunc, info = venv.step(a)
        scalar.step(a[0])
    assert (term | trunc).all() and "episode_metrics" in info
    obs, r, term, trunc, info = venv.step(a)
    assert np.all(r == 0.0) and not (term | trunc).any() and np.all(info["t"] == 0.0) and info["_disturbance"].all()
    np.testing.assert_array_equal(obs[0], scalar.reset()[0])


@pytest.mark.parametrize("env_id", IDS)
def test_same_step_final_obs_and_info(env_id):
    """Gymnasium's test_same_step_final_obs / test_vector_env_info: final_obs of the ended environments in the
    single observation space, None elsewhere; their final_info holds the episode's metrics."""
    venv = gym.make_vec(env_id, num_envs=3, autoreset_mode=AutoresetMode.SAME_STEP, **SHORT)
    venv.reset(seed=0)
    for _ in range(10):
        obs, _, term, trunc, info = venv.step(venv.action_space.sample())
    done = term | trunc
    assert done.all()
    np.testing.assert_array_equal(info["_final_obs"], done)
    np.testing.assert_array_equal(info["_final_info"], done)
    for i in range(3):
        assert info["final_obs"][i] in venv.single_observation_space
        assert not np.array_equal(info["final_obs"][i], obs[i])  # obs is the new episode's first
    assert info["final_info"]["_episode_metrics"].all() and "episode_metrics" not in info
    assert np.all(info["t"] == 0.0) and np.all(info["final_info"]["t"] == pytest.approx(0.1))


@pytest.mark.parametrize("env_id", IDS)
def test_autoreset_disabled(env_id):
    """Gymnasium's test_autoreset_disabled: an ended environment waits for reset(options={"reset_mask": ...});
    stepping it before is refused and changes nothing."""
    venv = gym.make_vec(env_id, num_envs=2, autoreset_mode=AutoresetMode.DISABLED, **SHORT)
    venv.reset(seed=0)
    a = venv.action_space.sample()
    for _ in range(10):
        obs, _, term, trunc, _ = venv.step(a)
    assert (term | trunc).all()
    before = copy.deepcopy(venv.unwrapped.core.driver.fs)
    with pytest.raises(RuntimeError, match="reset_mask"):
        venv.step(a)
    np.testing.assert_array_equal(venv.unwrapped.core.driver.fs, before)
    obs2, info = venv.reset(options={"reset_mask": np.array([True, False])})
    np.testing.assert_array_equal(obs2[1], obs[1])
    with pytest.raises(RuntimeError, match=r"environments \[1\]"):
        venv.step(a)
    venv.reset(options={"reset_mask": np.array([False, True])})
    venv.step(a)


@pytest.mark.parametrize("env_id", IDS)
def test_partial_reset(env_id):
    """Gymnasium's test_partial_reset: a reset mask restarts only the masked environments (issue 21, item 4);
    a masked environment restarts as a scalar env with its seed, the others go on as if nothing happened."""
    venv = gym.make_vec(env_id, num_envs=3, autoreset_mode=AutoresetMode.DISABLED, **SHORT)
    initial_obs, _ = venv.reset(seed=[0, 1, 2])
    venv.action_space.seed(123)
    for _ in range(3):
        step_obs, *_ = venv.step(venv.action_space.sample())
    untouched = copy.deepcopy(venv)
    mask_obs, mask_info = venv.reset(seed=[0, 1, 0], options={"reset_mask": np.array([True, True, False])})
    assert np.all(mask_obs[:2] == initial_obs[:2])
    assert np.all(mask_obs[2] == step_obs[2])
    np.testing.assert_array_equal(mask_info["_t"], [True, True, False])
    a = venv.action_space.sample()
    np.testing.assert_array_equal(venv.step(a)[0][2], untouched.step(a)[0][2])


@pytest.mark.parametrize("env_id", IDS)
def test_partial_reset_failure(env_id):
    """Gymnasium's test_partial_reset_failure: bad masks are refused (ValueError here) and change nothing."""
    venv = gym.make_vec(env_id, num_envs=3, autoreset_mode=AutoresetMode.DISABLED, **SHORT)
    with pytest.raises(ValueError, match="first reset"):
        venv.reset(options={"reset_mask": np.array([True, True, False])})
    venv.reset(options={"reset_mask": np.array([True, True, True])}, seed=0)
    before = venv.unwrapped.core.driver.fs.copy()
    for bad in (np.array([True]), np.array([True, True, False, False]), np.array([[True, True, True]]),
                np.array([[1, 1, 0]]), np.array([1.0, 1.0, 0.0]), [True, True, False],
                np.array([False, False, False])):
        with pytest.raises(ValueError, match="reset_mask"):
            venv.reset(options={"reset_mask": bad})
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=[0, 1, -1])
    with pytest.raises(ValueError, match=r"reset options \['reset_msk'\] are not known; valid: \['reset_mask'\]"):
        venv.reset(seed=5, options={"reset_msk": np.array([True, False, False])})  # misspelt: not a reset of all
    np.testing.assert_array_equal(venv.unwrapped.core.driver.fs, before)


@pytest.mark.parametrize("env_id", IDS)
def test_unknown_reset_options_are_refused_and_change_nothing(env_id):
    env = gym.make(env_id, **SHORT)
    env.reset(seed=3)
    obs, _, _, _, _ = env.step(env.action_space.sample())
    state = env.unwrapped.np_random.bit_generator.state
    with pytest.raises(ValueError, match=r"reset options \['reset_mask'\] are not known"):
        env.reset(seed=9, options={"reset_mask": np.array([True])})
    assert env.unwrapped.np_random.bit_generator.state == state
    env.reset(seed=3, options={})  # no options: fine


@pytest.mark.parametrize("env_id", IDS)
def test_random_seeding_basics(env_id):
    venv = gym.make_vec(env_id, num_envs=3, **SHORT)
    venv.reset(seed=42)
    assert venv.unwrapped.np_random_seed == (42, 43, 44)
    venv.reset(seed=None)  # keeps the generators, as SyncVectorEnv's sub-environments do
    assert venv.unwrapped.np_random_seed == (42, 43, 44)


@pytest.mark.parametrize("env_id", IDS)
def test_vector_obs_action_spaces(env_id):
    venv = gym.make_vec(env_id, num_envs=3, **SHORT)
    obs, _ = venv.reset(seed=0)
    assert obs in venv.observation_space
    obs, *_ = venv.step(venv.action_space.sample())
    assert obs in venv.observation_space


@pytest.mark.parametrize("mode", MODES, ids=[m.value for m in MODES])
@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_autoreset(env_id, mode):
    for given in (mode, mode.value):
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode=given,
                            **SHORT)
        assert venv.metadata["autoreset_mode"] == mode
        venv.close()
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec(env_id, num_envs=2, autoreset_mode="Sometimes", **SHORT)


# ---------------------------------------------------------------------------------------------------------------
# tests/envs/registration (test_make_vec.py, test_env_spec.py): specs that round-trip (issue 37), every registered id

ALL_IDS = tuple(sorted(i for i in gym.registry if i.startswith("mrd_env/")))
#: make_vec's keywords in Gymnasium's test_make_vec_with_spec, for our ids: every vectorization mode, with and
#: without render_mode, vector_kwargs, wrappers, a step cap, and options of the environment's own
VEC_ROWS = {
    "default": {}, "num_envs": {"num_envs": 3}, "native": {"vectorization_mode": "vector_entry_point"},
    "sync": {"vectorization_mode": "sync"}, "async": {"vectorization_mode": "async"},
    "sync-copy": {"vectorization_mode": "sync", "vector_kwargs": {"copy": False}},
    "sync-wrappers": {"vectorization_mode": "sync", "wrappers": (gym.wrappers.TimeAwareObservation,)},
    "native-rgb": {"vectorization_mode": "vector_entry_point", "render_mode": "rgb_array"},
    "sync-rgb": {"vectorization_mode": "sync", "render_mode": "rgb_array"},
    "async-rgb": {"vectorization_mode": "async", "render_mode": "rgb_array"},
    "native-cap": {"vectorization_mode": "vector_entry_point", "max_episode_steps": 5},
    "sync-cap": {"vectorization_mode": "sync", "max_episode_steps": 5},
    "native-options": dict(SHORT), "sync-options": {"vectorization_mode": "sync", **SHORT},
}


def _has_wrapper(env, wrapper_type: type) -> bool:
    """Gymnasium's tests' has_wrapper: a wrapper of that type (or a subclass) in the stack."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, wrapper_type):
            return True
        env = env.env
    return False


def _same_rollout(a, b, steps: int = 3, vector: bool = True) -> None:
    assert data_equivalence(a.reset(seed=0), b.reset(seed=0), exact=True)
    a.action_space.seed(1)
    for _ in range(steps):
        action = a.action_space.sample()
        assert data_equivalence(a.step(action), b.step(action), exact=True)


@pytest.mark.parametrize("row", VEC_ROWS)
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_make_vec_with_spec(env_id, row):
    """Gymnasium's test_make_vec_with_spec: make_vec(envs.spec) re-creates the vector env with an equal spec, the
    same type, number of environments, spaces and render mode (and here the same rollout); the registered spec
    given instead of the id builds the same (issue 37, item 1: the native rows failed, the re-created spec had
    gained the keyword max_episode_steps)."""
    kwargs = VEC_ROWS[row]
    envs = gym.make_vec(env_id, **kwargs)
    assert envs.spec is not None
    recreated = gym.make_vec(envs.spec)
    assert envs.spec == recreated.spec
    assert envs.num_envs == recreated.num_envs and type(envs) is type(recreated)
    assert envs.observation_space == recreated.observation_space
    assert envs.single_observation_space == recreated.single_observation_space
    assert envs.action_space == recreated.action_space and envs.single_action_space == recreated.single_action_space
    assert envs.render_mode == recreated.render_mode == kwargs.get("render_mode")
    _same_rollout(envs, recreated)
    if "wrappers" not in kwargs:  # a callable does not go to JSON (Gymnasium refuses it)
        from_json = gym.envs.registration.EnvSpec.from_json(envs.spec.to_json())
        assert from_json == envs.spec
        assert gym.make_vec(from_json).spec == envs.spec
    by_spec = gym.make_vec(gym.spec(env_id), **kwargs)
    assert by_spec.spec == envs.spec and type(by_spec) is type(envs)
    for e in (envs, recreated, by_spec):
        e.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_make_vec_wrappers(env_id):
    """Gymnasium's test_make_vec_wrappers: a sub-environment whose spec states max_episode_steps is wrapped in a
    TimeLimit (issue 37, item 1: the spec stated it with no TimeLimit); wrappers given are applied to every
    sub-environment. Also for gym.make and gym.make(env.spec)."""
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **SHORT)
    assert isinstance(envs, gym.vector.SyncVectorEnv) and len(envs.envs) == 2
    for sub_env in envs.envs:
        assert isinstance(sub_env, gym.Env) and sub_env.spec is not None
        assert sub_env.spec.max_episode_steps == 10
        assert _has_wrapper(sub_env, gym.wrappers.TimeLimit)
        assert not _has_wrapper(sub_env, gym.wrappers.TransformObservation)
    space = envs.single_observation_space
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **SHORT,
                        wrappers=[lambda e: gym.wrappers.TransformObservation(e, lambda obs: obs * 2, space)])
    assert all(_has_wrapper(e, gym.wrappers.TransformObservation) for e in envs.envs)
    for env in (gym.make(env_id, **SHORT), gym.make(gym.make(env_id, **SHORT).spec)):
        assert env.spec.max_episode_steps == 10 and _has_wrapper(env, gym.wrappers.TimeLimit)


def _specs_of(env_id):
    """The specs Gymnasium's test_env_spec_to_from_json takes, and the vector envs'."""
    env = gym.make(env_id, **SHORT)
    yield "registered", gym.spec(env_id)
    yield "unwrapped", env.unwrapped.spec
    yield "made", env.spec
    yield "wrapped", gym.wrappers.NormalizeReward(gym.wrappers.TimeAwareObservation(env), gamma=0.8).spec
    for mode in ("vector_entry_point", "sync"):
        yield mode, gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, **SHORT).spec


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_every_spec_survives_json_and_recreation(env_id):
    """Issue 37 (must show): every registered spec, and the specs of the environments made from it (scalar, wrapped,
    native and sync vector), survive EnvSpec.to_json/from_json unchanged (item 2: ShearBuilding-v1's tuple
    damper_floors came back a list), and gym.make / gym.make_vec of a made environment's spec re-create an equal
    spec."""
    for name, spec in _specs_of(env_id):
        assert gym.envs.registration.EnvSpec.from_json(spec.to_json()) == spec, name
        if name in ("vector_entry_point", "sync"):
            assert gym.make_vec(spec).spec == spec, name
        elif name in ("made", "wrapped"):
            assert gym.make(spec).spec == spec, name
    registered = gym.spec(env_id)
    assert all(type(v) in (int, float, str, bool, list, dict) for v in registered.kwargs.values())
    if env_id == "mrd_env/ShearBuilding-v1":  # the list [2]: one damper, in storey 2 (neither a range nor choices)
        assert gym.make(env_id, **SHORT).unwrapped.plant_params.damper_floors == (2,)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_full_spec_integration(env_id):
    """Gymnasium's test_full_integration: a wrapped environment's spec, through JSON, re-creates the same stack
    (wrappers, render mode, the environment class) and the same steps."""
    env = gym.make(env_id, render_mode="rgb_array", **SHORT)
    env = gym.wrappers.NormalizeReward(gym.wrappers.TimeAwareObservation(env), gamma=0.8)
    spec = env.spec
    assert len(spec.additional_wrappers) == 2 and spec.max_episode_steps == 10
    recreated_spec = gym.envs.registration.EnvSpec.from_json(spec.to_json())
    assert recreated_spec == spec and recreated_spec.additional_wrappers == spec.additional_wrappers
    recreated = gym.make(recreated_spec)
    assert recreated.render_mode == "rgb_array" and recreated.spec == spec
    assert isinstance(recreated, gym.wrappers.NormalizeReward) and recreated.gamma == 0.8
    assert isinstance(recreated.env, gym.wrappers.TimeAwareObservation)
    assert type(recreated.unwrapped) is type(env.unwrapped)
    assert env.spec.pprint(disable_print=True) == recreated_spec.pprint(disable_print=True)
    _same_rollout(env, recreated, steps=10)  # the whole episode


def _ends_on_a_termination_at_the_last_step(env_id) -> dict:
    """Short episodes whose first (seed 0, commands at the low end) ends by a stroke-limit termination on its last
    (10th) step where the stroke peaks then (a limit between its peaks before and in that step), with terminations
    among truncations in the random episodes that follow."""
    env = gym.make(env_id, **SHORT)
    env.reset(seed=0)
    for _ in range(10):
        env.step(env.action_space.low)
    stroke = np.abs(env.unwrapped.signal(env.unwrapped.roles["damper_stroke"])).max(axis=1)
    before, last = stroke[:91].max(), stroke.max()  # 10 physics rows a step
    if last > before:
        return dict(SHORT, stroke_limit=float(np.sqrt(before * last)))
    return dict(SHORT, stroke_limit=_small_stroke_limit(env_id))  # the stroke peaks early: terminations elsewhere


def _peaks_on_the_last_step(env_id) -> bool:
    """Whether :func:`_ends_on_a_termination_at_the_last_step` ends the first episode by a termination on its last
    step (its stroke peaks there)."""
    env = gym.make(env_id, **SHORT)
    env.reset(seed=0)
    for _ in range(10):
        env.step(env.action_space.low)
    stroke = np.abs(env.unwrapped.signal(env.unwrapped.roles["damper_stroke"])).max(axis=1)
    return bool(stroke.max() > stroke[:91].max())


def _rollouts(env, episodes: int = 4):
    env.action_space.seed(0)
    for ep in range(episodes):
        yield ("reset", *env.reset(seed=ep if ep < 2 else None))
        k, done = 0, False
        while not done:
            k += 1
            out = env.step(env.action_space.low if ep == 0 else env.action_space.sample())
            yield (k, *out)
            done = out[2] or out[3]


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_the_entry_points_time_limit_changes_no_step(env_id):
    """Issue 37: gym.make's TimeLimit (the entry point's, at the environment's own length) states the length and
    changes nothing: every reset and step, flags and infos included, as the environment class built alone gives
    them; an episode that ends by a termination on its last step stays terminated and not truncated (a plain
    TimeLimit would flag it truncated too)."""
    kw = _ends_on_a_termination_at_the_last_step(env_id)
    env = gym.make(env_id, **kw)
    bare = type(env.unwrapped)(**{**gym.spec(env_id).kwargs, **kw})
    assert isinstance(_unwrap_all(env)[-2], gym.wrappers.TimeLimit) and bare.spec is None
    last_step_terminations = 0
    for a, b in zip(_rollouts(env), _rollouts(bare), strict=True):
        assert data_equivalence(a, b, exact=True), (a, b)
        last_step_terminations += a[0] == 10 and a[3] and not a[4]
    assert last_step_terminations >= _peaks_on_the_last_step(env_id)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_made_from_its_spec_steps_as_the_original(env_id):
    """gym.make(env.spec) adds Gymnasium's TimeLimit at the spec's length around the environment: the same
    episodes, ended at the same step, with the same infos (terminations and their reasons included); Gymnasium's
    TimeLimit only flags a termination on the episode's last step truncated as well."""
    env = gym.make(env_id, **_ends_on_a_termination_at_the_last_step(env_id))
    again = gym.make(env.spec)
    assert again.spec == env.spec and type(again.unwrapped) is type(env.unwrapped)
    assert isinstance(again, gym.wrappers.TimeLimit) and again._max_episode_steps == 10
    for a, b in zip(_rollouts(env), _rollouts(again), strict=True):
        if a[0] == 10 and a[3]:
            a = (*a[:4], True, a[5])
        assert data_equivalence(a, b, exact=True), (a, b)


# ---------------------------------------------------------------------------------------------------------------
# issue 21: refused calls, make_vec's keywords, episode lengths, options, render_fps, SB3

@pytest.mark.parametrize("env_id", IDS)
def test_a_refused_batch_changes_nothing(env_id):
    """Item 2: a batch with one non-finite action is refused before any environment steps."""
    venv = gym.make_vec(env_id, num_envs=3, **SHORT).unwrapped
    venv.reset(seed=0)
    a = venv.action_space.sample().astype(np.float64)
    venv.step(a)
    twin = copy.deepcopy(venv)
    bad = a.copy()
    bad[2, -1] = np.nan
    state = [x.copy() for x in (venv.core.driver.fs, venv.core.driver.is_, venv.core.obs)]
    with pytest.raises(ValueError, match="finite"):
        venv.step(bad)
    for x, y in zip(state, (venv.core.driver.fs, venv.core.driver.is_, venv.core.obs)):
        np.testing.assert_array_equal(x, y)
    assert data_equivalence(venv.step(a), twin.step(a), exact=True)


def test_a_refused_scalar_action_changes_nothing():
    """Item 2, scalar: with two dampers, a NaN second command used to leave the first one written."""
    env = gym.make("mrd_env/HalfCarPhysical-v0", **SHORT).unwrapped
    env.reset(seed=0)
    env.step([1.0, 1.0])
    cmd, fs = env.command, env.core.driver.fs.copy()
    with pytest.raises(ValueError, match="finite"):
        env.step([2.0, np.nan])
    np.testing.assert_array_equal(env.command, cmd)
    np.testing.assert_array_equal(env.core.driver.fs, fs)


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_max_episode_steps_truncates_like_time_limit(env_id):
    """Item 5: make_vec(..., max_episode_steps=k) in the vector entry point truncates at k steps, as
    gym.make(..., max_episode_steps=k)'s TimeLimit does for SyncVectorEnv."""
    kw = dict(episode_seconds=0.1, control_dt=0.005)  # 20 steps; cut at 7
    native = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=7, **kw)
    sync = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", max_episode_steps=7, **kw)
    assert native.unwrapped.spec.max_episode_steps == 7 and native.unwrapped.max_episode_steps == 7
    native.reset(seed=0)
    sync.reset(seed=0)
    a = native.action_space.sample()
    for k in range(1, 16):
        out_n, out_s = native.step(a), sync.step(a)
        assert data_equivalence(out_n[:4], out_s[:4], exact=True)
        assert out_n[3].all() == (k in (7, 15))
    assert native.unwrapped.core.episode_metrics(0)["duration"] == pytest.approx(7 * 0.005)
    for bad in (0, -1, 2.5, True, "7"):
        with pytest.raises(ValueError, match="max_episode_steps"):
            gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=bad, **kw)


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_rgb_array_renders_every_environment(env_id):
    """Item 5: make_vec(id, render_mode="rgb_array") renders one frame per environment (what Gymnasium's vector
    RecordVideo asserts: a sequence of num_envs frames); each is that environment's own."""
    venv = gym.make_vec(env_id, num_envs=2, render_mode="rgb_array", **SHORT)
    assert venv.render_mode == "rgb_array"
    venv.reset(seed=[0, 1])
    a = venv.action_space.sample()
    a[1] = venv.single_action_space.high  # the two environments' frames must differ
    for _ in range(4):
        venv.step(a)
    frames = venv.render()
    assert isinstance(frames, tuple) and len(frames) == venv.num_envs and all(_frame_ok(f) for f in frames)
    assert not np.array_equal(frames[0], frames[1])
    with pytest.raises(ValueError, match="render_mode"):
        gym.make_vec(env_id, num_envs=2, render_mode="human", **SHORT)


@pytest.mark.parametrize("kw", [{}, SHORT, dict(episode_seconds=0.25, control_dt=0.003)],
                         ids=["defaults", "short", "uneven"])
@pytest.mark.parametrize("env_id", IDS)
def test_spec_max_episode_steps_is_the_episode_length(env_id, kw):
    """Item 6: env.spec.max_episode_steps is the length of the env's own episodes; issue 37: stated, as Gymnasium
    states it, by a TimeLimit at that length (the entry point's), while the environment truncates itself at the
    same step (unwrapped, and with make's max_episode_steps=-1); the native vector env states it in its spec and in
    the spec's keywords, so that make_vec(spec) re-creates it."""
    kw = {"control_dt": 0.01, **kw}
    env = gym.make(env_id, **kw)
    n = env.spec.max_episode_steps
    assert isinstance(n, int) and n == env.unwrapped.max_episode_steps
    limits = [w for w in _unwrap_all(env) if isinstance(w, gym.wrappers.TimeLimit)]
    assert [w._max_episode_steps for w in limits] == [n]
    for e in (env, env.unwrapped, gym.make(env_id, max_episode_steps=-1, **kw)):
        e.reset(seed=0)
        steps = 0
        while True:
            steps += 1
            _, _, term, trunc, _ = e.step(e.action_space.low)
            if term or trunc:
                break
        assert trunc and steps == n
    venv = gym.make_vec(env_id, num_envs=2, **kw)
    assert venv.unwrapped.spec.max_episode_steps == venv.unwrapped.spec.kwargs["max_episode_steps"] == n


def _unwrap_all(env) -> list:
    chain = [env]
    while isinstance(chain[-1], gym.Wrapper):
        chain.append(chain[-1].env)
    return chain


@pytest.mark.parametrize("env_id", IDS)
def test_time_aware_observation(env_id):
    """Item 6: TimeAwareObservation reads the episode length from the spec."""
    env = gym.wrappers.TimeAwareObservation(gym.make(env_id, **SHORT))
    obs, _ = env.reset(seed=0)
    assert obs[-1] == 0 and env.observation_space.high[-1] == 10
    done = False
    while not done:
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        assert obs in env.observation_space
        done = term or trunc
    assert obs[-1] == 10


def test_spec_of_a_mixture_bounds_its_episodes():
    """Episodes of different lengths (a mixture of roads): the spec states the longest."""
    from mrd_env.disturbances import bump, sine_sweep
    from mrd_env.envs.disturbance import FixedRecord, Mixture
    from mrd_env.plants.quarter_car.env import ROAD_CHANNELS, ROAD_UNITS

    roads = [FixedRecord(r, ROAD_CHANNELS, ROAD_UNITS, 1e-3) for r in
             (bump(0.02, 1.0, 10.0, t_start=0.1, duration=0.3, dt=1e-3),
              sine_sweep(0.01, 1.0, 5.0, 0.5, dt=1e-3))]
    env = gym.make("mrd_env/QuarterCarPhysical-v0", road=Mixture(roads), control_dt=0.01)
    assert env.spec.max_episode_steps == 50
    lengths = set()
    for seed in range(8):
        env.reset(seed=seed)
        n, done = 0, False
        while not done:
            n += 1
            _, _, term, trunc, _ = env.step([0.0])
            done = term or trunc
        lengths.add(n)
    assert lengths == {30, 50}


COMMON_OPTIONS = {  # the README's options for every environment, each at a value valid for all of them
    "damper": "spencer_dyke", "damper_params": {"c0a": 2.0e4}, "plant_params": {}, "dt": 1e-3,
    "control_dt": 0.002, "episode_seconds": 0.05, "sensors": ("damper_force", "command"),
    "sensor_noise": {"damper_force": 1.0}, "sensor_delay": 1, "history": 2, "action_mode": "normalized",
    "reward_weights": {"termination": 5.0}, "reward": (lambda period: -1.0), "stroke_limit": 0.2,
    "render_mode": "rgb_array",
}


def _own_options(env_id) -> dict:
    """The plant's own options, given together: its training set-up (a disturbance drawn per episode and the
    options every experiment gives it, from its profile) on its default preset, named."""
    import inspect

    spec = plant_of_id(env_id)
    preset = inspect.signature(spec.scalar_env.build).parameters["plant_preset"].default
    return {**spec.profile.training, "plant_preset": preset}


def _foreign_option(env_id) -> str:
    """An option another plant's environment takes and this one does not."""
    import inspect

    def options(spec):
        return set(inspect.signature(spec.scalar_env.build).parameters)

    own = options(plant_of_id(env_id))
    return min(set().union(*(options(plant_of_id(i)) for i in IDS)) - own)


@pytest.mark.parametrize("env_id", IDS)
def test_every_env_takes_the_options_common_to_all(env_id):
    """Item 7: every id takes the README's options for all environments (scalar and vector), and says which
    it does not take."""
    for given in [{name: value} for name, value in COMMON_OPTIONS.items()] + [_own_options(env_id)]:
        env = gym.make(env_id, **{"episode_seconds": 0.05, **given})
        env.reset(seed=0)
        _, r, *_ = env.step(env.action_space.sample())
        if "reward" in given:
            assert r == -1.0
        env.close()
    env = gym.make(env_id, **{**_own_options(env_id), **COMMON_OPTIONS})
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert _frame_ok(env.render())
    vec = {k: v for k, v in {**_own_options(env_id), **COMMON_OPTIONS}.items() if k != "render_mode"}
    venv = gym.make_vec(env_id, num_envs=2, **vec)
    venv.reset(seed=0)
    venv.step(venv.action_space.sample())
    other = _foreign_option(env_id)
    with pytest.raises(ValueError, match=rf"unknown option\(s\) \['{other}'\]"):
        gym.make(env_id, **{other: None})


def test_half_car_takes_roads_and_reward_weights():
    """Item 7: the half car's road and reward options act (the weights scale the reward; a Record is replayed)."""
    from mrd_env.disturbances import Record

    kw = dict(episode_seconds=0.05)
    rewards = []
    for weights in ({}, {"comfort": 2.0, "travel": 1.0, "tyre": 1.0}):
        env = gym.make("mrd_env/HalfCarPhysical-v0", reward_weights=weights, **kw)
        env.reset(seed=0)
        rewards.append(env.step([1.0, 1.0])[1])
    assert rewards[1] == pytest.approx(2 * rewards[0], rel=1e-12)
    z = np.linspace(0.0, 0.01, 200)
    rec = Record(1e-3, np.column_stack([z, np.full(200, 0.05), z, np.full(200, 0.05)]),
                 ("z_rf", "zdot_rf", "z_rr", "zdot_rr"), ("m", "m/s", "m", "m/s"), "ramp")
    env = gym.make("mrd_env/HalfCarPhysical-v0", road=rec, **kw)
    _, info = env.reset(seed=0)
    assert info["disturbance"] == "ramp"
    for bad, match in ((dict(road="bump"), "road: unknown kind"), (dict(road_params={"speed": -1.0}), "speed"),
                       (dict(reward_weights={"pitch": 1.0}), "reward_weights"), (dict(reward=3), "reward")):
        with pytest.raises(ValueError, match=match):
            gym.make("mrd_env/HalfCarPhysical-v0", **kw, **bad)


@pytest.mark.parametrize("env_id", IDS)
def test_sb3_make_vec_env_builds_every_id(env_id):
    """Item 7: SB3's make_vec_env passes render_mode="rgb_array" and falls back only on TypeError."""
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(env_id, n_envs=2, seed=0, env_kwargs=SHORT)
    venv.reset()
    venv.step(np.stack([venv.action_space.sample()] * 2))
    assert venv.render_mode == "rgb_array"
    venv.close()


@pytest.mark.parametrize("env_id", IDS)
def test_render_fps_is_simulated_time(env_id):
    """Item 8: one frame per control step played at 1/control_dt frames per second is real time."""
    for control_dt, fps in ((1e-3, 1000), (0.01, 100), (0.004, 250)):
        env = gym.make(env_id, control_dt=control_dt, episode_seconds=0.1)
        venv = gym.make_vec(env_id, num_envs=2, control_dt=control_dt, episode_seconds=0.1)
        assert env.metadata["render_fps"] == venv.metadata["render_fps"] == fps
    assert gym.make(env_id, control_dt=0.003, episode_seconds=0.1).metadata["render_fps"] == pytest.approx(1 / 0.003)


@pytest.mark.parametrize("env_id", IDS)
def test_unknown_option_is_a_value_error_listing_the_valid_ones(env_id):
    """Item 10."""
    for make in (lambda **kw: gym.make(env_id, **kw), lambda **kw: gym.make_vec(env_id, num_envs=2, **kw)):
        with pytest.raises(ValueError, match=r"unknown option\(s\) \['nonsense'\]; valid: .*'episode_seconds'"):
            make(nonsense=1)


def test_sb3_bridge_logs_episode_returns_without_vec_monitor():
    """Item 9: SB3 fills ep_info_buffer (ep_rew_mean) from the bridge's Monitor-style infos."""
    from stable_baselines3 import PPO

    from mrd_env.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mrd_env/QuarterCarPhysical-v0", n_envs=2, seed=0, episode_seconds=0.05, control_dt=0.01)
    venv.reset()
    total = np.zeros(2)
    for k in range(5):
        venv.step_async(np.full((2, 1), 1.0, dtype=np.float32))
        _, rewards, dones, infos = venv.step_wait()
        total += rewards
    assert dones.all() and [d["episode"]["l"] for d in infos] == [5, 5]
    assert [d["episode"]["r"] for d in infos] == pytest.approx(total)
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=32)
    assert len(model.ep_info_buffer) >= 4 and all(e["l"] == 5 for e in model.ep_info_buffer)


def test_sb3_bridge_gives_what_dummy_vec_env_gives():
    """Observations, rewards, dones, every step's infos (with TimeLimit.truncated; at an end the last step's info
    and its observation) and reset_infos as SB3's DummyVecEnv over the scalar environments, over several episodes
    with terminations; set_options is refused as the environments refuse reset options."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from mrd_env.envs.sb3 import make_sb3_vec_env

    kw = dict(episode_seconds=0.03, control_dt=0.01, stroke_limit=3e-3)
    bridge = make_sb3_vec_env("mrd_env/QuarterCarPhysical-v0", n_envs=3, seed=0, **kw)
    dummy = DummyVecEnv([lambda: gym.make("mrd_env/QuarterCarPhysical-v0", **kw) for _ in range(3)])
    dummy.seed(0)
    np.testing.assert_array_equal(bridge.reset(), dummy.reset())
    assert bridge.reset_infos == dummy.reset_infos
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(12):
        a = rng.uniform(0.0, 2.0, size=(3, 1)).astype(np.float32)
        bridge.step_async(a)
        dummy.step_async(a)
        (o1, r1, d1, i1), (o2, r2, d2, i2) = bridge.step_wait(), dummy.step_wait()
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for a1, a2 in zip(i1, i2):
            a1 = {k: v for k, v in a1.items() if k != "episode"}  # the Monitor's record, which DummyVecEnv lacks
            assert data_equivalence(a1, a2, exact=True), (a1, a2)
        assert bridge.reset_infos == dummy.reset_infos
        ended += int(d1.sum())
    assert ended >= 6
    bridge.set_options({"reset_mask": np.ones(3, bool)})
    with pytest.raises(ValueError, match="reset options"):
        bridge.reset()


def test_sb3_bridge_set_attr_and_env_method_honour_indices():
    """Item 9: the environments share one native vector env; a subset of indices is refused, not ignored."""
    from mrd_env.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("mrd_env/QuarterCarPhysical-v0", n_envs=3, seed=0, **SHORT)
    venv.set_attr("tag", "x")
    venv.set_attr("tag", "y", indices=[2, 0, 1])
    assert venv.get_attr("tag", indices=[0, 2]) == ["y", "y"]
    assert venv.env_method("signal_matrices", "travel", indices=None)[0]["C"].shape == (1, 4)
    for call in (lambda: venv.set_attr("tag", "z", indices=[1]), lambda: venv.env_method("close", indices=0),
                 lambda: venv.set_attr("tag", "z", indices=[0, 1, 5])):
        with pytest.raises(ValueError, match="indices"):
            call()
    assert venv.get_attr("tag") == ["y"] * 3


@pytest.mark.parametrize("env_id", IDS)
def test_record_episode_statistics_scalar_and_vector(env_id):
    """Gymnasium's episode statistics wrappers (scalar and vector) see the env's own episode ends."""
    env = gym.wrappers.RecordEpisodeStatistics(gym.make(env_id, **SHORT))
    env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        _, r, term, trunc, info = env.step(env.action_space.sample())
        total += r
        done = term or trunc
    assert info["episode"]["l"] == 10 and info["episode"]["r"] == pytest.approx(total)
    venv = gym.wrappers.vector.RecordEpisodeStatistics(gym.make_vec(env_id, num_envs=2, **SHORT))
    venv.reset(seed=0)
    for _ in range(10):
        _, _, _, _, info = venv.step(venv.action_space.sample())
    assert info["_episode"].all() and np.all(info["episode"]["l"] == 10)
    assert env_info(info, 1)["episode_metrics"]["duration"] == pytest.approx(0.1)


@pytest.mark.parametrize("env_id", IDS)
def test_vector_record_video_records_in_simulated_time(env_id, tmp_path, monkeypatch):
    """Items 5 and 8: Gymnasium's vector RecordVideo runs on the native vector env and writes its clip at
    render_fps = 1/control_dt (moviepy, not installed here, is replaced by a recorder of what it is given)."""
    import sys
    import types

    clips = []

    class ImageSequenceClip:
        def __init__(self, frames, fps):
            self.frames, self.fps = frames, fps

        def write_videofile(self, path, logger=None):
            clips.append((self.frames, self.fps, path))

    for name in ("moviepy", "moviepy.video", "moviepy.video.io", "moviepy.video.io.ImageSequenceClip"):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    sys.modules["moviepy.video.io.ImageSequenceClip"].ImageSequenceClip = ImageSequenceClip
    venv = gym.make_vec(env_id, num_envs=2, render_mode="rgb_array", episode_seconds=0.05, control_dt=0.01)
    venv = gym.wrappers.vector.RecordVideo(venv, str(tmp_path / "videos"), episode_trigger=lambda e: e == 0,
                                           video_length=0)
    venv.reset(seed=0)
    for _ in range(6):  # the episode (5 steps) and the autoreset step
        venv.step(venv.action_space.sample())
    venv.close()
    (frames, fps, _), = clips
    assert fps == 100 and len(frames) == 6
    h, w, c = venv.env.render()[0].shape
    assert frames[0].shape == (h, 2 * w, c)  # the two environments side by side
