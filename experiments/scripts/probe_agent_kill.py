"""The kill test of agent saves: a process re-saving an agent folder in a loop, as the trainer does for ``best/``
(or for the run folder's own agent), is killed with SIGKILL at random moments; after each kill the folder must load
(:func:`controllers.load_agent`) and act exactly as one of the saved versions — the one its ``agent.json`` says —
never as a mix of the model of one save and the statistics of another.

    python -m experiments.scripts.probe_agent_kill --kills 12 --seed 0 --mode best
    python -m experiments.scripts.probe_agent_kill --kills 12 --seed 0 --mode run
    python -m experiments.scripts.probe_agent_kill --kills 12 --seed 0 --mode naive   # the control: not atomic

Each save is the trainer's: a PPO policy's weights (safetensors), its observation statistics, SB3's ``model.zip``
and ``agent.json`` (:func:`controllers.agents.save_agent`; ``best``: the folder written beside its target and
swapped in; ``run``: files named by their digest, ``agent.json`` last). The versions differ in both weights and
statistics. The saving process is forked from this one (Linux, macOS), so that a kill costs no interpreter start;
the moments are drawn uniformly over a window of several saves (seeded). Prints one line per kill and the count of
loadable folders; ``tests/controllers/test_agent_kill.py`` runs it.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

N_VERSIONS = 4
N_OBS = 9


def stub_env(n_obs: int):
    """A stand-in environment with a car's spaces (``n_obs`` observations, one command in [-1, 1]): a policy needs
    only the spaces."""
    import gymnasium as gym
    from gymnasium import spaces

    class Stub(gym.Env):
        observation_space = spaces.Box(-np.inf, np.inf, (n_obs,), np.float32)
        action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

        def reset(self, seed=None, options=None):
            return np.zeros(n_obs, np.float32), {}

        def step(self, action):
            return np.zeros(n_obs, np.float32), 0.0, False, False, {}

    return Stub()


def build_model():
    """A small PPO model (the trainer's kind of policy) on a stand-in environment of the quarter car's shape."""
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    return PPO("MlpPolicy", stub_env(N_OBS), n_steps=64, batch_size=64, device="cpu", seed=0,
               policy_kwargs={"net_arch": {"pi": [64, 64], "vf": [64, 64]}})


def set_version(model, base: dict, k: int):
    """Version ``k``: the weights moved by k·0.05, statistics of mean k/10 and variance 1 + k."""
    import torch

    from controllers.agents import ObservationNormalizer

    with torch.no_grad():
        for name, p in model.policy.state_dict().items():
            p.copy_(base[name] + 0.05 * k)
    return ObservationNormalizer(np.full(N_OBS, 0.1 * k), np.full(N_OBS, 1.0 + k))


def save_version(model, base: dict, k: int, folder: Path, mode: str) -> None:
    from controllers.agents import save_agent
    from mrd_env.plants.quarter_car import SPEC as QUARTER_CAR

    norm = set_version(model, base, k)
    meta = {"name": f"version {k}", "plant": QUARTER_CAR.name, "env_id": QUARTER_CAR.physics_id, "algo": "PPO",
            "env_kwargs": {}, "version": k}
    if mode == "naive":
        return naive_save(folder, meta, model, norm)
    save_agent(folder, meta, policy=model.policy, normalizer=norm, sb3_model=model, in_place=mode == "run")


def naive_save(folder: Path, meta: dict, model, norm) -> None:
    """The control: the same files written one after the other in place (what the trainer did before saves were
    atomic), to show that the test catches a folder left from two saves."""
    import hashlib
    import json

    from controllers.policy_format import describe_policy, policy_bytes

    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / "model.zip")
    files = {"policy.safetensors": policy_bytes(model.policy), "normalization.npz": norm.to_bytes()}
    for name, data in files.items():
        (folder / name).write_bytes(data)
    meta = {"format": "mrd-env-agent", **meta, "model": "policy.safetensors", "normalization": "normalization.npz",
            "network": describe_policy(model.policy),
            "files": {n: hashlib.sha256(d).hexdigest() for n, d in files.items()}}
    (folder / "agent.json").write_text(json.dumps(meta))


def leftovers(folder: Path, mode: str) -> int:
    """Traces of a save killed mid-write: staging folders beside ``best/``, temporaries in a run folder."""
    if mode == "best":
        return len(list(folder.parent.glob(f".{folder.name}.*.staging")))
    if mode == "naive":
        return 0
    return len([f for f in folder.iterdir() if f.name.startswith(".")])


def kill_test(workdir: Path, kills: int = 12, seed: int = 0, mode: str = "best", window: tuple = (0.02, 0.6),
              out=print) -> dict:
    """Run the kill test in ``workdir``; {"kills", "loadable", "versions" (found after each kill), "mid_write"
    (kills that left a trace of an unfinished save), "changed" (kills after which the version differed from the
    previous check's)}."""
    from controllers.agents import load_agent

    if not hasattr(os, "fork"):
        raise RuntimeError("the kill test forks the saving process (Linux, macOS)")
    workdir = Path(workdir)
    model = build_model()
    base = {k: v.clone() for k, v in model.policy.state_dict().items()}
    obs = np.random.default_rng(1).normal(0, 2, (32, N_OBS))
    expected = []
    for k in range(N_VERSIONS):  # each version saved once on its own, loaded: its actions
        save_version(model, base, k, workdir / "versions" / f"v{k}", "best")
        expected.append(np.asarray(load_agent(workdir / "versions" / f"v{k}").predict(obs)[0]))
    assert all(not np.array_equal(expected[0], e) for e in expected[1:]), "versions must act differently"
    folder = workdir / ("run/best" if mode == "best" else "run")
    save_version(model, base, 0, folder, mode)  # there is always a previous agent
    rng = np.random.default_rng(seed)
    result = {"kills": kills, "loadable": 0, "versions": [], "mid_write": 0, "changed": 0}
    previous = 0
    for i in range(kills):
        delay = float(rng.uniform(*window))
        start = int(rng.integers(N_VERSIONS))
        pid = os.fork()
        if pid == 0:  # the saving process: re-saves the folder until killed
            try:
                k = start
                while True:
                    k = (k + 1) % N_VERSIONS
                    save_version(model, base, k, folder, mode)
            finally:
                os._exit(1)
        time.sleep(delay)
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        trace = leftovers(folder, mode)
        try:
            agent = load_agent(folder)
            actions = np.asarray(agent.predict(obs)[0])
            found = [k for k, e in enumerate(expected) if np.array_equal(actions, e)]
            ok = found == [agent.meta["version"]]
            version = agent.meta["version"]
        except Exception as exc:  # noqa: BLE001  (what a reader would meet)
            ok, version, found = False, None, f"{type(exc).__name__}: {exc}"
        result["loadable"] += ok
        result["versions"].append(version)
        result["mid_write"] += trace > 0
        result["changed"] += version is not None and version != previous
        previous = version if version is not None else previous
        out(f"kill {i + 1:2d} after {delay * 1e3:5.0f} ms: {'loadable' if ok else 'NOT LOADABLE'}, version "
            f"{version} (actions match {found}), unfinished save left: {'yes' if trace else 'no'}")
    out(f"{mode}: {result['loadable']}/{kills} loadable after a kill, each acting as the version its agent.json "
        f"names; {result['mid_write']} kills interrupted a save mid-write, {result['changed']} found a newer version")
    return result


def main(argv: list[str] | None = None) -> int:
    import tempfile

    ap = argparse.ArgumentParser(prog="python -m experiments.scripts.probe_agent_kill",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mode", choices=("best", "run", "naive"), default="best",
                    help="best: the folder swapped in whole (best/, checkpoints); run: the run folder's own agent; "
                         "naive: the control, files written in place one after the other")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        r = kill_test(Path(tmp), args.kills, args.seed, args.mode)
    return 0 if r["loadable"] == r["kills"] else 1


if __name__ == "__main__":
    sys.exit(main())
