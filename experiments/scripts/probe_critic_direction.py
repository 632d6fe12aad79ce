"""Does a residual agent's critic know which way to correct its law? Two measurements on saved agents (issue 23,
docs/rl-agents.md, "TD3 with the actor frozen while the critic warms up").

``--agent PATH`` (a residual TD3 agent, typically stopped at the end of its actor warm-up, when its actor is
still exactly the law): on ``validation_split``'s episodes, each of these corrections to the law is scored paired
against the law itself (return minus the law's return, episode by episode; mean and 95 % Student-t interval):

* ε along the critic's action gradient at the law: a = ε·sign(∂Q₁/∂a) at a = 0, for each ``--eps``;
* ε with a random sign (a seeded ``numpy.random.Generator``, ``--seed``; one new generator per ε);
* the critic's argmax: a = argmax Q₁(s, a) over 25 points of [−0.3, 0.3].

If the critic's gradient were informative, the first row would beat the law and the random sign.

``--final PATH [PATH ...]`` (trained residual TD3 agents): along each agent's own trajectories (``--final-episodes``
episodes of its training distribution, seeds 910 000 on), the share of steps where its critic rates the actor's
correction above the law's command, Q₁(s, π(s)) − Q₁(s, 0) > 0, with the mean magnitude of the correction a and the mean command.

The tables are written to ``<out>/critic_direction.{md,csv}`` and ``<out>/critic_agreement.{md,csv}``. The figures
of docs/rl-agents.md come from (15 CPU-s)::

    python -m experiments.scripts.probe_critic_direction \\
        --agent results/issue23/td3_warmup30k_at_warmup_end/quarter_car_td3-residual-paired_s0 \\
        --final results/issue23/td3_warmup30k/quarter_car_td3-residual-paired_s0 \\
                results/issue23/td3_warmup30k_actorlr3e-5/quarter_car_td3-residual-paired_s0 \\
        --out results/issue23
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

#: The critic's argmax is taken over these corrections (a residual action is in [−1, 1]).
GRID = np.linspace(-0.3, 0.3, 25)
#: First seed of the ``--final`` episodes (the training distribution on seeds its training did not draw).
FINAL_SEED = 910_000


class CriticProbe:
    """A policy with SB3's ``predict`` on the residual agent's observations (the law's command appended) whose
    correction comes from ``agent``'s critic Q₁: ``"gradient"`` (ε·sign ∂Q₁/∂a at a = 0), ``"random"`` (ε, random
    sign drawn by ``rng``) or ``"argmax"`` (over :data:`GRID`)."""

    def __init__(self, agent, kind: str, eps: float = 0.0, rng: np.random.Generator | None = None):
        self.agent, self.kind, self.eps, self.rng = agent, kind, eps, rng

    def reset(self, mask=None) -> None:
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        import torch

        q1 = self.agent.model.critic.q1_forward
        o = torch.as_tensor(self.agent.normalize(obs))
        n = o.shape[0]
        if self.kind == "random":
            a = self.eps * self.rng.choice([-1.0, 1.0], size=(n, 1))
        elif self.kind == "gradient":
            zero = torch.zeros(n, 1, requires_grad=True)
            q1(o, zero).sum().backward()
            a = self.eps * torch.sign(zero.grad).numpy()
        else:
            with torch.no_grad():
                q = torch.stack([q1(o, torch.full((n, 1), float(g))).squeeze(-1) for g in GRID], dim=1)
            a = GRID[q.argmax(dim=1).numpy()][:, None]
        return a.astype(np.float32), None


class AgreementProbe:
    """``agent``'s own policy, recording at each step Q₁(s, π(s)) − Q₁(s, 0), the size of the correction a, and the law's and the final
    command (physical units) of ``residual`` (the controller's :class:`~controllers.residual.Residual`)."""

    def __init__(self, agent, residual):
        self.agent, self.residual = agent, residual
        self.gap, self.abs_a, self.law, self.command = [], [], [], []

    def reset(self, mask=None) -> None:
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        import torch

        obs = np.atleast_2d(obs)
        res = self.residual
        o = torch.as_tensor(self.agent.normalize(obs))
        with torch.no_grad():
            a = self.agent.model.actor(o)   # TD3's deterministic actor
            q1 = self.agent.model.critic.q1_forward
            self.gap += (q1(o, a) - q1(o, torch.zeros_like(a))).squeeze(-1).tolist()
        a = a.numpy()

        def volts(x):   # an action in [-1, 1] as the physical command
            return res.v_min + (np.asarray(x) + 1.0) * 0.5 * (res.v_max - res.v_min)

        u_law = volts(obs[:, -res.n_dampers:])   # the law's command, as the residual appended it
        u = res.combine(u_law, a)
        self.abs_a.append(float(np.abs(a).mean()))
        self.law.append(float(u_law.mean()))
        self.command.append(float((volts(u) if res.normalized else u).mean()))
        return a, None


def _residual_critic(path: Path, ap: argparse.ArgumentParser, option: str, trust: bool = False):
    from controllers import load_agent

    agent = load_agent(path, trust=trust)
    if agent.meta["algo"] != "TD3" or not agent.meta.get("residual"):
        ap.error(f"{option} {path}: needs a TD3 agent trained with a residual, got {agent.meta['algo']}"
                 f"{' residual' if agent.meta.get('residual') else ''}")
    return agent


def direction_rows(agent, eps: list[float], episodes: int, seed: int) -> list[dict]:
    """The law and each correction of :class:`CriticProbe`, paired against the law on the validation episodes."""
    from controllers.agents import agent_controller
    from experiments.common.evaluation import controller_episodes, evaluate_batch, mean_ci
    from experiments.common.plants import profile
    from experiments.training.trainers import validation_split

    scenario, obs_kwargs = validation_split(profile(agent.plant), agent.env_kwargs, episodes)
    residual = agent.meta["residual"]
    law = np.array([e.episode_return for e in controller_episodes(residual["law"], scenario, **obs_kwargs)])
    policies = [(f"the law ({residual['law']})", None)]
    for e in eps:
        policies += [(f"ε = {e:g} along the critic's gradient", CriticProbe(agent, "gradient", e)),
                     (f"ε = {e:g}, random sign", CriticProbe(agent, "random", e, np.random.default_rng(seed)))]
    policies.append((f"the critic's argmax over [{GRID[0]:g}, {GRID[-1]:g}]", CriticProbe(agent, "argmax")))
    rows = []
    for label, probe in policies:
        ret = law if probe is None else np.array([e.episode_return for e in evaluate_batch(
            lambda v, p=probe, n=label: agent_controller(v, p, residual, name=n), scenario, "", **obs_kwargs)])
        m, lo, hi = mean_ci(ret - law)
        rows.append({"correction to the law": label, "return (per episode)": float(ret.mean()),
                     "minus the law (per episode)": m, "95 % t low": lo, "95 % t high": hi, "episodes": len(ret)})
    return rows


def agreement_row(agent, episodes: int) -> dict:
    """:class:`AgreementProbe` along ``agent``'s own episodes of its training distribution."""
    import gymnasium as gym

    from experiments.common.evaluation import evaluate

    env = gym.make(agent.env_id, **agent.env_kwargs)
    ctrl = agent.bind(env)
    probe = ctrl.model = AgreementProbe(agent, ctrl.residual)
    for i in range(episodes):
        evaluate(ctrl, env, FINAL_SEED + i, "")
    env.close()
    gap = np.asarray(probe.gap)
    return {"agent": str(agent.folder), "steps": gap.size, "Q1(s, π(s)) − Q1(s, 0) > 0 (% of steps)":
            100.0 * float((gap > 0).mean()), "mean Q1(s, π(s)) − Q1(s, 0)": float(gap.mean()),
            "mean magnitude of a (of [−1, 1])": float(np.mean(probe.abs_a)), "mean command (V)": float(np.mean(probe.command)),
            "the law's mean command (V)": float(np.mean(probe.law))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--agent", type=Path, help="residual TD3 agent whose critic's direction is probed")
    ap.add_argument("--eps", type=float, nargs="+", default=[0.02, 0.05], help="step sizes ε, each in (0, 1]")
    ap.add_argument("--episodes", type=int, default=8, help="validation episodes (>= 1; default 8)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random signs (>= 0; default 0)")
    ap.add_argument("--final", type=Path, nargs="+", default=[], metavar="PATH",
                    help="trained residual agents: does the critic rate the actor above the law?")
    ap.add_argument("--final-episodes", type=int, default=4, help="episodes per --final agent (>= 1; default 4)")
    ap.add_argument("--out", type=Path, default=Path("results/critic_direction"))
    ap.add_argument("--trust-agent", action="store_true",
                    help="also load agents that only have SB3's model.zip (pickles: they can run any code; only "
                         "for agents you trust, e.g. your own runs saved before the code-free format)")
    args = ap.parse_args(argv)
    if args.agent is None and not args.final:
        ap.error("give --agent PATH (the critic's direction), --final PATH ... (the agreement), or both")
    if not all(0.0 < e <= 1.0 for e in args.eps):
        ap.error(f"--eps must be in (0, 1] (a correction of the residual's action range [-1, 1]), got {args.eps}")
    for option, value in (("--episodes", args.episodes), ("--final-episodes", args.final_episodes)):
        if value < 1:
            ap.error(f"{option} must be >= 1, got {value}")
    if args.seed < 0:
        ap.error(f"--seed must be >= 0, got {args.seed}")
    import torch

    import mrd_env  # noqa: F401  (registers the environments)
    from mrd_env.report import write_table

    torch.set_num_threads(1)   # tiny networks: a second thread only spins when the machine is busy

    agent = _residual_critic(args.agent, ap, "--agent", args.trust_agent) if args.agent else None
    finals = [_residual_critic(p, ap, "--final", args.trust_agent) for p in args.final]
    if agent is not None:
        md, _ = write_table(direction_rows(agent, args.eps, args.episodes, args.seed), args.out / "critic_direction",
                            title=f"Corrections from the critic of {agent.folder}, paired against the law",
                            floatfmt=".4g")
        print(md.read_text())
    if finals:
        md, _ = write_table([agreement_row(a, args.final_episodes) for a in finals], args.out / "critic_agreement",
                            title="Does the critic rate the actor's correction above the law's command?",
                            floatfmt=".4g")
        print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
