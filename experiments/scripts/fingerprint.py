"""Fingerprints of the project's outputs, for a refactor that must move no number: run it before and after, compare.

Hashes (SHA-256 of the raw float64 bytes, per case):
- a seeded rollout of every registered environment id (scalar, and the native vector env of 4), under a classical
  law that applies to it (else the midpoint of the action range): observations, rewards, flags, episode metrics;
- every shipped agent's actions on its plant's first test episode and the episode's return;
- the nominal reward scales the model-based laws design on.

``python -m experiments.scripts.fingerprint --out results/fingerprint.json`` writes {case: digest} (atomically);
``--compare OTHER.json`` prints the cases that differ and exits 1 if any does.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
import warnings
from pathlib import Path

import numpy as np


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(np.asarray(a, dtype=np.float64)).tobytes())
    return h.hexdigest()[:24]


def _law(env):
    from controllers import make_controller

    for name in ("clipped_optimal", "skyhook_continuous", "groundhook", "passive_on"):
        try:
            return make_controller(name, env)
        except ValueError:
            continue
    return None


def rollouts(seconds: float = 2.0) -> dict[str, str]:
    import gymnasium as gym

    import mrd_env  # noqa: F401
    from mrd_env.plants.registry import renamed

    RENAMED = renamed()

    out = {}
    for env_id in sorted(i for i in gym.registry if i.startswith("mrd_env/") and i not in RENAMED):
        env = gym.make(env_id, episode_seconds=seconds)
        law = _law(env)
        obs, _ = env.reset(seed=7)
        rows = []
        for _ in range(100_000):
            a = law.predict(obs)[0] if law is not None else 0.5 * (env.action_space.low + env.action_space.high)
            obs, r, term, trunc, info = env.step(a)
            rows.append(np.concatenate([np.ravel(obs), [r, term, trunc]]))
            if term or trunc:
                break
        metrics = info.get("episode_metrics", {})
        out[f"rollout {env_id}"] = _digest(np.array(rows), [metrics[k] for k in sorted(metrics)
                                                            if np.isscalar(metrics[k])])
        venv = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point", episode_seconds=seconds)
        obs, _ = venv.reset(seed=7)
        vrows = []
        for _ in range(50):
            a = np.broadcast_to(0.5 * (venv.single_action_space.low + venv.single_action_space.high),
                                venv.action_space.shape)
            obs, r, term, trunc, _ = venv.step(a)
            vrows.append(np.concatenate([np.ravel(obs), r, term, trunc]))
        out[f"vector {env_id}"] = _digest(np.array(vrows))
    return out


def agents() -> dict[str, str]:
    from controllers import load_agent
    from controllers.agents import shipped_agents

    out = {}
    for folder in shipped_agents():
        agent = load_agent(folder)
        import gymnasium as gym

        env = gym.make(agent.env_id, **{**agent.env_kwargs, "episode_seconds": 2.0})
        policy = agent.bind(env)
        obs, _ = env.reset(seed=11)
        acts, ret = [], 0.0
        for _ in range(100_000):
            a = policy.predict(obs)[0]
            obs, r, term, trunc, _ = env.step(a)
            acts.append(np.ravel(a))
            ret += float(r)
            if term or trunc:
                break
        out[f"agent {folder.name}"] = _digest(np.array(acts), [ret])
    return out


def nominal_scales() -> dict[str, str]:
    import gymnasium as gym

    from controllers.model_based import nominal_reference

    out = {}
    for env_id in ("mrd_env/QuarterCar-v1", "mrd_env/ShearBuilding-v1"):
        scales = nominal_reference(gym.make(env_id))
        out[f"nominal scales {env_id}"] = _digest([scales[k] for k in sorted(scales)])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m experiments.scripts.fingerprint", description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results/fingerprint.json"))
    ap.add_argument("--compare", type=Path, default=None, help="a fingerprint file to compare with")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    prints = {**rollouts(), **agents(), **nominal_scales()}
    from mrd_env import storage

    storage.write_json(args.out, prints, indent=1, sort_keys=True)
    print(f"{len(prints)} cases written to {args.out}")
    if args.compare is not None:
        other = json.loads(args.compare.read_text())
        differ = sorted(k for k in set(prints) | set(other) if prints.get(k) != other.get(k))
        for k in differ:
            print(f"differs: {k}: {other.get(k)} -> {prints.get(k)}")
        print(f"{len(prints) - len(differ)} of {len(set(prints) | set(other))} cases identical")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
