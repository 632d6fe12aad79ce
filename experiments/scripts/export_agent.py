"""Convert agent folders into the code-free format (:func:`controllers.agents.export_agent`): the policy's weights as
arrays with a JSON description of its network, each file's digest in ``agent.json``, no SB3 ``model.zip``.

    python -m experiments.scripts.export_agent results/agents/quarter_car_ppo_s0/best --to shared/quarter_car_ppo \\
        --trust-agent

An agent that has only SB3's ``model.zip`` is read from it, which runs the Python objects pickled in it: give
``--trust-agent`` only for a zip whose source you trust (your own training run). The exported agent's actions are
checked against the source's, bit for bit, before anything is written. Without a destination the folder is converted
where it is (its ``model.zip`` left out). ``--reference FILE`` also writes, for each source agent, observations and
the actions the source gives on them (what ``tests/controllers/test_agent_format.py`` checks the shipped agents
against).

How the shipped PPO agents were converted (their ``model.zip`` as trained, then removed)::

    python -m experiments.scripts.export_agent controllers/agents/*_ppo_residual* --trust-agent \\
        --reference tests/data/shipped_sb3_actions.npz
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np


def reference_actions(agent, n: int = 64, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(observations, actions) of ``agent`` (a :class:`controllers.agents.TrainedAgent`) on ``n`` raw observations."""
    from controllers.agents import reference_observations

    obs = reference_observations(agent, n, seed)
    agent.reset()
    return obs, np.asarray(agent.predict(obs)[0])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m experiments.scripts.export_agent",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", type=Path, nargs="+", help="agent folders")
    ap.add_argument("--to", type=Path, default=None, help="destination folder (one agent; default: where it is)")
    ap.add_argument("--trust-agent", action="store_true",
                    help="read SB3 model.zip files (pickles: they can run any code; only for a trusted source)")
    ap.add_argument("--reference", type=Path, default=None,
                    help="write the source agents' observations and actions to this .npz")
    args = ap.parse_args(argv)
    from controllers.agents import TrustedCodeWarning, agent_files, export_agent, load_agent, same_actions

    if args.to is not None and len(args.agents) != 1:
        ap.error("--to takes one agent")
    reference = {}
    for src in args.agents:
        dst = args.to or src
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TrustedCodeWarning)
            source = load_agent(src, trust=args.trust_agent)
            name = agent_files(src)[0].name
            if args.reference is not None:
                reference[f"{name}__obs"], reference[f"{name}__actions"] = reference_actions(source)
            export_agent(src, dst, trust=args.trust_agent)
        exported = load_agent(dst)
        same = same_actions(source, exported)
        print(f"{src} -> {dst}: {exported.meta['network']['class']}, same actions bit for bit: {same}")
        if not same:
            return 1
    if args.reference is not None:
        args.reference.parent.mkdir(parents=True, exist_ok=True)
        np.savez(args.reference, **reference)
        print(f"wrote {args.reference}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
