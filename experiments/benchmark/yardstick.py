"""The yardstick of one episode, computed on the spot: the best any controller could do on it, and bounds from above
— what the learning curves draw against (:mod:`experiments.scripts.learning_curves`), what the tests and the
accuracy measurements check the optimisers with. The benchmark's suites store their references instead, computed
once by :mod:`experiments.benchmark.references` (which builds on :func:`warm_starts` and :func:`force_peak`).

Per episode (a scenario and a seed):

* **best passive** R_p — the best constant command (a grid of 9 from v_min to v_max, passive-off and passive-on
  included), re-simulated in the environment;
* **clairvoyant** R_c — the full-knowledge optimal command sequence at 1 ms (:func:`mrd_env.optimal.clairvoyant`:
  CasADi + IPOPT on the smoothed model, warm-started from every law's and every shipped agent's own commands on
  the episode), re-simulated in the environment: an achievable return, so the true semi-active optimum is ≥ R_c;
* **active bound** R_b — the same episode with an ideal actuator of force up to the largest damper force any
  compared controller used on it (passive-on, the laws, the agents, the clairvoyant; :func:`mrd_env.optimal.
  active_bound`, a convex QP): no semi-active controller whose force stays within it scores more, so the true
  optimum lies in [R_c, R_b];
* **passivity-aware bound** R_d ≤ R_b — the active bound of the same force limit with the actuator never having
  given the plant more energy than it took (:func:`mrd_env.optimal.dissipative_bound`): it still bounds every
  semi-active damper, and tells how much of the active bracket is the ideal actuator's energy injection
  (docs/yardstick.md: a third of it on a bump, next to nothing on rough roads and ground motions);
* the **share of the achievable gain** a controller captures, (R − R_p) / (R_c − R_p): 0 is the best passive
  setting, 1 the clairvoyant optimum; negative is worse than the best passive setting.

Savaresi & Spelta (2007) use the full-knowledge optimum as the bound of semi-active performance; the active bound
is the customary ideal-actuator reference of the structural literature (Dyke et al. 1996).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from experiments.common.plants import PlantProfile
from experiments.common.scenarios import Scenario

#: The clairvoyant's control step: every controller's rate (1 ms, 10 ms) is a multiple of it, so its command
#: sequences are candidate solutions and the optimum at 1 ms dominates them all.
YARDSTICK_DT = 1e-3
#: Bumped when the yardstick changes what it computes for the same episode (part of its cache key); 3: the
#: stepping's Newton predictor and the corrected hybrid law (2026-11-25) move the replayed returns.
VERSION = 3
#: Warm starts the clairvoyant tries, best first, when the optimiser fails from the best one.
RETRY_STARTS = 3
#: Constant commands tried for the best passive setting (fractions of the command range).
PASSIVE_GRID = np.linspace(0.0, 1.0, 9)


def check_plant(plant: PlantProfile) -> None:
    """``ValueError`` (one line) if ``plant`` has no yardstick (no laws to warm-start the clairvoyant from,
    :attr:`~.plants.PlantProfile.warm_laws`)."""
    if not plant.warm_laws:
        raise ValueError(f"the yardstick does not support the {plant.title}: {plant.no_yardstick}")


@dataclass
class EpisodeYardstick:
    """The yardstick of one episode (returns as the environment pays them; see the module docstring)."""

    scenario: str
    seed: int
    passive: float
    passive_command: float
    clairvoyant: float
    source: str
    clairvoyant_seconds: float
    bound: float = math.nan
    f_max: float = math.nan
    bound_seconds: float = math.nan
    warm_starts: dict = field(default_factory=dict)
    dissipative: float = math.nan            #: R_d, the passivity-aware bound with the same f_max
    dissipative_seconds: float = math.nan

    @property
    def label(self) -> str:
        return self.scenario

    def share(self, ret: float) -> float:
        """(R − R_p) / (R_c − R_p): the share of the achievable gain a return captures."""
        gap = self.clairvoyant - self.passive
        return (ret - self.passive) / gap if gap > 0 else math.nan

    @property
    def bracket(self) -> float:
        """(R_b − R_c) / (R_b − R_p): the width of the bracket on the true optimum, as a share of the range from
        the best passive setting to the bound (0: the clairvoyant is the optimum)."""
        span = self.bound - self.passive
        return (self.bound - self.clairvoyant) / span if span > 0 else math.nan

    @property
    def dissipative_bracket(self) -> float:
        """(R_d − R_c) / (R_d − R_p): the bracket with the passivity-aware bound R_d (≤ :attr:`bracket`)."""
        span = self.dissipative - self.passive
        return (self.dissipative - self.clairvoyant) / span if span > 0 else math.nan


def warm_starts(problem, warm_laws, agents=()) -> dict[str, np.ndarray]:
    """{name: commands (n_steps, nd) at the problem's step}: every law of ``warm_laws`` (the plant's
    :attr:`~.plants.PlantProfile.warm_laws`) at 1 ms and every agent at its own control step, observation and
    action options, on the problem's episode."""
    from controllers import load_agent, make_controller

    out = {}
    for name in warm_laws:
        out[name] = problem.commands_of(lambda env, n=name: make_controller(n, env))
    for path in agents:
        agent = load_agent(path)
        kw = dict(agent.observation_kwargs)
        cdt = kw.pop("control_dt", problem.control_dt)
        out[f"agent {agent.name}"] = problem.commands_of(agent.bind, control_dt=cdt, **kw)
    return out


def force_peak(problem, commands) -> float:
    """The largest |F − F_static| (N) of the damper on the problem's episode under ``commands``."""
    tr = problem.replay(commands, states=True)
    return float(np.nanmax(np.abs(tr.F - problem.F_static)))


def best_passive(problem) -> tuple[float, float]:
    """(return, command) of the best constant command on the problem's episode."""
    best = (-math.inf, math.nan)
    for f in PASSIVE_GRID:
        v = problem.v_min + f * (problem.v_max - problem.v_min)
        r = problem.replay(np.full((problem.n_steps, problem.nd), v)).ret
        best = max(best, (r, v))
    return best


def yardstick_key(problem, label: str, warm_laws, agents=()) -> dict:
    """What an episode's yardstick is cached under: the episode and its options, the problem's digest (the plant,
    the reward, the disturbance: what a changed default changes while the options stay the same), the warm starts
    (laws and agents) and the solver's settings — so that a stale yardstick is never served."""
    from controllers.agents import agent_digest
    from mrd_env.optimal.full_knowledge import problem_digest

    return {**problem.key(), "problem_digest": problem_digest(problem), "scenario": label,
            "agents": [agent_digest(a) for a in agents], "warm_laws": list(warm_laws),
            "retry_starts": RETRY_STARTS, "passive_grid": PASSIVE_GRID.tolist(), "version": VERSION}


def episode_yardstick(scenario: Scenario, seed: int, warm_laws, *, agents=(), bound: bool = True,
                      cache: bool = True, solve: bool = True, progress: bool = False) -> EpisodeYardstick | None:
    """The yardstick of ``scenario`` with ``seed``, warm-started from the laws ``warm_laws`` (the plant's) and the
    ``agents`` (a plain function of picklable inputs: sweeps run it anywhere).

    Cached per episode, plant, damper, options and warm starts (:mod:`mrd_env.optimal.cache`); with
    ``solve=False`` only a cached yardstick is returned (None if there is none)."""
    from mrd_env.optimal import cache as store, episode_problem

    problem = episode_problem(scenario.env_id, seed=int(seed), control_dt=YARDSTICK_DT, **scenario.options)
    key = yardstick_key(problem, scenario.label(seed), warm_laws, agents)
    hit = store.load("yardstick", key) if cache else None
    if hit is not None and (hit.get("bound") is not None or not bound):
        y = EpisodeYardstick(**{k: (math.nan if v is None else v) for k, v in hit.items()})
        if bound and solve and math.isnan(y.dissipative):  # cached before R_d was reported: R_d alone, then stored
            _dissipative(problem, y)
            store.store("yardstick", key, _plain(y))
        return y
    if not solve:
        return None
    from mrd_env.optimal import clairvoyant

    rp, vp = best_passive(problem)
    starts = warm_starts(problem, warm_laws, agents)
    starts["best constant"] = np.full((problem.n_steps, problem.nd), vp)  # so that the optimum is never below it
    cv = clairvoyant(problem, warm_starts=starts, cache=cache, progress=progress)  # its own cache: commands too
    if cv.failed:  # the optimiser stopped at its start (a line search that found no descent): from the next ones
        cv = clairvoyant(problem, warm_starts=starts, n_starts=RETRY_STARTS, cache=cache, progress=progress)
    y = EpisodeYardstick(scenario.label(seed), int(seed), rp, vp, float(cv.ret), str(cv.source), float(cv.wall_time),
                         warm_starts={k: float(v) for k, v in cv.warm_returns.items()})
    if bound:
        from mrd_env.optimal import active_bound

        t0 = time.perf_counter()
        # the actuator may use the largest force any compared controller used on the episode: passive-on, the laws,
        # the agents and the clairvoyant (the bound then holds for each of them)
        on = np.full((problem.n_steps, problem.nd), problem.v_max)
        y.f_max = max(force_peak(problem, U) for U in [on, *starts.values(), cv.commands])
        b = active_bound(problem, f_max=y.f_max)
        y.bound, y.bound_seconds = float(b.bound), time.perf_counter() - t0
        _dissipative(problem, y)
    if cache:
        store.store("yardstick", key, _plain(y))
    return y


def _dissipative(problem, y: EpisodeYardstick) -> None:
    """R_d of ``problem`` with ``y``'s force limit, into ``y``: at the default tolerance, then a looser one where
    the solver stalls (R_d is its certified dual objective either way); left NaN where both fail (the table says
    nan: no R_d is reported rather than a wrong one)."""
    from mrd_env.optimal import dissipative_bound

    t0 = time.perf_counter()
    for tol in (1e-8, 1e-6):
        try:
            y.dissipative = float(dissipative_bound(problem, f_max=y.f_max, tol=tol).bound)
            break
        except RuntimeError:
            continue
    y.dissipative_seconds = time.perf_counter() - t0


def _plain(y: EpisodeYardstick) -> dict:
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in asdict(y).items()}


def yardsticks(plant: PlantProfile, scenarios: list[Scenario], *, agents=(), bound: bool = True,
               cache: bool = True, solve: bool = True, progress: bool = True, backend: str = "serial",
               jobs: int | None = None, address: str | None = None) -> list[EpisodeYardstick]:
    """The yardstick of every episode of ``scenarios`` (one task each, on the chosen backend; the workers get the
    plant's warm-start laws); with ``solve=False`` the cached ones only."""
    from mrd_env.executor import Task, run_tasks

    check_plant(plant)
    options = {"agents": tuple(agents), "bound": bound, "cache": cache, "solve": solve}
    tasks = [Task(episode_yardstick, (sc, seed, plant.warm_laws), options, label=f"{sc.label(seed)}")
             for sc in scenarios for seed in sc.seeds]
    out = run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress and solve,
                    desc=f"yardstick {plant.name}")
    return [y for y in out if y is not None]
