"""The scalar environments' entry points: each class, wrapped in a TimeLimit at its own episode length (issue 37);
:mod:`mrd_env.plants.registry` registers one per plant (``mrd_env.plants.registry:QuarterCarEnv``, ...).

Why: the episode length depends on the options (``episode_seconds``, ``control_dt``, the disturbance), so no
``max_episode_steps`` can be registered, yet Gymnasium reads the length from ``env.spec.max_episode_steps``
(``TimeAwareObservation``, Stable-Baselines3, RL Zoo) under the rule that a spec with ``max_episode_steps`` has a
TimeLimit at that length (its ``test_make_vec_wrappers``). An entry point may add its own wrappers: a TimeLimit
added here states the length in the spec as Gymnasium's own environments do, so ``gym.make(env.spec)`` and
``gym.make_vec(spec)`` re-create the environment with an equal spec (``make`` then adds Gymnasium's TimeLimit at the
same length around it). The environment truncates itself at that step, with its infos; the wrapper
(:class:`EpisodeTimeLimit`) only states the length and changes no episode.

Alternatives weighed: the environment setting ``spec.max_episode_steps`` itself (before) broke Gymnasium's rule and
``make_vec(spec)``'s re-creation; a registered length is wrong for most options; ``additional_wrappers`` in the
registration would fix one length too and forbid the native vector env (``vector_entry_point`` refuses them).
"""
from __future__ import annotations

import importlib
import os
import sys
import warnings
from typing import Any

from gymnasium.wrappers import TimeLimit


class EpisodeTimeLimit(TimeLimit):
    """Gymnasium's :class:`~gymnasium.wrappers.TimeLimit` at the environment's own episode length, which never
    changes a step: the environment truncates itself at that step, and an episode that ends by a termination on
    its last step stays terminated and not truncated (TimeLimit would set both flags). It counts the steps and
    states ``max_episode_steps`` in the spec as TimeLimit does."""

    def step(self, action: Any):
        observation, reward, terminated, truncated, info = self.env.step(action)
        self._elapsed_steps += 1
        if self._elapsed_steps >= self._max_episode_steps and not terminated:
            truncated = True  # the environment has said so already: a guard, not a change
        return observation, reward, terminated, truncated, info


class TimeLimitedEntryPoint:
    """An entry point: the environment class ``module:name`` built from the options, in an
    :class:`EpisodeTimeLimit` at its ``max_episode_steps`` (bare where that is unknown: a disturbance of records of
    unknown length without ``episode_seconds``). ``metadata`` is the class's, so that ``gym.make`` sees its render
    modes."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    @property
    def env_class(self) -> type:
        return getattr(importlib.import_module(self.module), self.name)

    @property
    def metadata(self) -> dict:
        return self.env_class.metadata

    def __call__(self, **options):
        warn_torch_threads()
        env = self.env_class(**options)
        n = env.max_episode_steps
        return env if n is None else EpisodeTimeLimit(env, int(n))

    def __repr__(self) -> str:
        return f"{type(self).__name__}('{self.module}:{self.name}')"


class FormerIdEntryPoint(TimeLimitedEntryPoint):
    """The entry point of a former id (a plant's ``former_ids``): the same environment, after a
    ``DeprecationWarning`` that names the id to use now."""

    def __init__(self, module: str, name: str, former: str, now: str):
        super().__init__(module, name)
        self.former, self.now = former, now

    def __call__(self, **options):
        import warnings

        warnings.warn(f"{self.former} is the former name of {self.now} (the same physics-level set-up): use "
                      f"{self.now}", DeprecationWarning, stacklevel=2)
        return super().__call__(**options)


# --- torch's threads (issue 49) ------------------------------------------------------------------------------------

#: Set to ``0`` to silence :class:`TorchThreadsWarning` (a process that chose its torch threads, a test suite).
TORCH_THREADS_VARIABLE = "MRD_ENV_TORCH_THREADS_WARNING"


class TorchThreadsWarning(UserWarning):
    """torch runs on several intra-op threads in a process that makes an mrd_env environment."""


_torch_threads_checked = False


def warn_torch_threads() -> None:
    """Warn once per process when an environment is made while torch is imported with more than one intra-op
    thread (the caller's process is not changed: ``torch.set_num_threads`` is process-wide and theirs to call).

    Why: Stable-Baselines3 trains networks of 64×64 units on batches of 64, too small for a second thread to help;
    torch's OpenMP threads spin while they wait, and on a machine whose cores are busy (the environment's own
    stepping, other processes) the spinning threads take the cores from the one doing the work: SB3's PPO ran 7 to
    10 times slower on 2 shared cores, all of it in the updates (``python -m experiments.measurements.speed.sb3_direct``;
    Gymnasium's Pendulum-v1 alike; ``OMP_WAIT_POLICY=PASSIVE`` recovers most of it). Whether the cores are busy
    changes from moment to moment, so the rule is the thread count alone. A process without torch, or with one
    thread, is not told."""
    global _torch_threads_checked
    if _torch_threads_checked:
        return
    torch = sys.modules.get("torch")
    if torch is None or not hasattr(torch, "get_num_threads"):  # not imported (yet), or half-imported
        return
    _torch_threads_checked = True
    threads = torch.get_num_threads()
    if threads <= 1 or os.environ.get(TORCH_THREADS_VARIABLE, "1") == "0":
        return
    warnings.warn(f"torch runs on {threads} intra-op threads: training small networks (Stable-Baselines3's "
                  "defaults) next to this environment runs up to 30x slower than on one thread when the cores are "
                  "busy, as its idle threads spin for them. Call torch.set_num_threads(1) before training "
                  "(docs/training.md, 'Stable-Baselines3 called directly'); silence this "
                  f"with {TORCH_THREADS_VARIABLE}=0 or a warnings filter on mrd_env.envs.entry.TorchThreadsWarning",
                  TorchThreadsWarning, stacklevel=_caller_level())


def _caller_level() -> int:
    """The ``stacklevel`` that names the first frame outside mrd_env, Gymnasium and SB3 (the user's ``gym.make``
    or ``make_vec_env`` line), counted from :func:`warn_torch_threads`'s caller."""
    inside = ("mrd_env", "gymnasium", "stable_baselines3", "sb3_contrib", "importlib")
    frame, level = sys._getframe(2), 2
    while frame is not None and any(f"{os.sep}{p}{os.sep}" in frame.f_code.co_filename for p in inside):
        frame, level = frame.f_back, level + 1
    return level
