"""The native vector environment's default thread count (issue 36): one thread below 64 environments, from 64 the
faster of one and every numba thread, timed while stepping; the results never depend on it. Timings themselves:
``experiments/measurements/speed/vector_threads.py`` (docs/speed.md)."""
import copy
from types import SimpleNamespace

import gymnasium as gym
import numba
import numpy as np
import pytest

from mrd_env.envs.vector import ThreadTuner, default_threads


def _venv(N, **kw):
    return gym.make_vec("mrd_env/QuarterCar-v1", num_envs=N, vectorization_mode="vector_entry_point",
                        episode_seconds=0.3, **kw).unwrapped


def test_the_default_resolves_as_documented():
    assert default_threads(63) == 1 and default_threads(64) == numba.get_num_threads()
    small = _venv(8)
    assert small.thread_tuner is None and small.core.driver.threads == 1
    big = _venv(64)
    if numba.get_num_threads() > 1:
        assert big.thread_tuner.many == big.core.driver.threads == min(numba.get_num_threads(), 64)
    else:
        assert big.thread_tuner is None and big.core.driver.threads == 1
    for n in (1, 2):  # a given count is kept, untimed
        fixed = _venv(64, threads=n)
        assert fixed.thread_tuner is None and fixed.core.driver.threads == n


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def _fake(cost):
    """A tuner over a fake core whose step takes cost[threads] seconds of a fake clock."""
    clock = _Clock()
    core = SimpleNamespace(driver=SimpleNamespace(threads=2))

    def step(action):
        clock.now += cost[core.driver.threads]
        return 0

    core.step = step
    return ThreadTuner(2, clock=clock), core, clock


def _run(tuner, core, clock, steps):
    """The thread counts of ``steps`` steps."""
    used = []
    for _ in range(steps):
        tuner.step(core, None)
        used.append(core.driver.threads)
    return used


@pytest.mark.parametrize("cost, chosen", [({1: 1.0, 2: 0.6}, 2), ({1: 1.0, 2: 0.95}, 1), ({1: 1.0, 2: 4.0}, 1)])
def test_the_tuner_runs_the_faster_count_and_tries_the_other_again(cost, chosen):
    """It starts on one thread; after ``probe`` timed steps it tries every thread (one untimed step, then up to
    ``probe`` timed), kept only if 10 % faster; a count that cannot win is dropped after a step or two. Until
    ``interval`` s later the chosen count runs alone; then the other is tried again."""
    tuner, core, clock = _fake(cost)
    p = tuner.probe
    used = _run(tuner, core, clock, 1 + p + 1 + p)
    assert used[:1 + p] == [1] * (1 + p)  # the first (untimed) and p timed steps on one thread
    tried = used[1 + p:].count(2) if chosen == 1 else 1 + p
    assert used[1 + p:1 + p + tried] == [2] * tried
    if cost[2] > 2 * cost[1]:
        assert tried == 3  # stopped after 2 timed steps: 2 × 4 s > 0.9 × 5 × 1 s
    assert tuner.threads == chosen and tuner.choices == [chosen == 1, chosen == 2]
    while clock.now < tuner._last + tuner.interval:  # the interval runs from the end of the last trial
        tuner.step(core, None)
        assert core.driver.threads == tuner.threads == chosen
    cost[1], cost[2] = cost[2], cost[1]  # the machine changed: the next trial turns the choice round, or not
    _run(tuner, core, clock, 4 * (p + 1))  # a trial, and a second one once the running mean has seen the change
    assert tuner.threads == (2 if cost[2] < tuner.margin * cost[1] else 1)


def test_a_slower_choice_is_tried_again_before_the_interval():
    """The chosen count slows down past the other's last trial: the other is tried ``soonest`` s after the last
    trial, not ``interval``."""
    cost = {1: 1.0, 2: 0.5}
    tuner, core, clock = _fake(cost)
    _run(tuner, core, clock, 2 * (tuner.probe + 1))
    assert tuner.threads == 2
    cost[2] = 3.0  # a process starts beside it: threads now spin
    last, tried = tuner._last, None
    for _ in range(30):
        before = clock.now
        tuner.step(core, None)
        if core.driver.threads == 1 and tried is None:
            tried = before  # the trial of one thread starts
    assert tuner.threads == 1 and tried < last + tuner.interval


class _Restless(ThreadTuner):
    interval, probe, trial = 0.0, 1, 0.0

    def _wins(self, t_other):
        return True


def test_switching_threads_changes_no_result():
    """A tuner switching every other step (trials of one step, no interval, every trial won) gives the rollout of
    one thread, bit for bit, autoresets included; a copy of the environment starts its tuner again and steps
    alike."""
    runs = []
    for tuned in (False, True):
        venv = _venv(64, threads=2 if tuned else 1)
        if tuned:
            venv.thread_tuner = _Restless(2)
        obs, _ = venv.reset(seed=3)
        rng = np.random.default_rng(0)
        out = [obs]
        for k in range(40):  # 0.3 s episodes at 10 ms: autoresets at steps 30 and 31
            a = rng.uniform(venv.single_action_space.low, venv.single_action_space.high, (64, 1))
            if k == 20 and tuned:
                twin = copy.deepcopy(venv)
                assert twin.thread_tuner.threads == 1 and twin.thread_tuner._last == -np.inf  # started again
                o1, r1, *_ = twin.step(a)
            obs, r, term, trunc, _ = venv.step(a)
            if k == 20 and tuned:
                assert np.array_equal(o1, obs) and np.array_equal(r1, r)
            out += [obs, r, term, trunc]
        runs.append(out)
    assert all(np.array_equal(a, b) for a, b in zip(*runs))
    assert min(venv.thread_tuner.choices) >= 5  # it did switch, many times
