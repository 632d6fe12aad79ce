"""Agents and classical laws side by side on the held-out test scenarios: the rows of the comparison (the laws at
the agents' control step and at 1 ms, the plant's MPC rows, the agents) and their episodes, every controller on the
same sensors and episodes — what ``mrd-env evaluate`` tabulates and ``mrd-env yardstick`` scores against the
clairvoyant optimum."""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from .evaluation import Episode, controller_episodes
from .plants import PlantProfile
from .scenarios import held_out_scenarios, preview_options


def evaluate(plant: PlantProfile, agents=(), laws=None, *, seeds: int = 3, control_dt: float | None = None,
             laws_at_1ms: bool = True, mpc: bool = True, damper: str | None = None, progress: bool = True, quick: bool = False, backend: str = "serial",
             jobs: int | None = None, address: str | None = None) -> dict[str, list[Episode]]:
    """{controller name: episodes on every test scenario}: the agents, the laws (by default the plant's,
    :attr:`~.plants.PlantProfile.laws`) and the plant's model predictive control rows. Agents with the same name (an
    algorithm trained on several seeds) are pooled under one row. One task per controller and scenario
    (:mod:`mrd_env.executor`)."""
    from controllers import load_agent

    from mrd_env.executor import Task, run_tasks

    loaded = [load_agent(a) for a in agents]
    for a in loaded:
        if a.plant != plant.name:
            raise ValueError(f"agent {a.folder} was trained on the {a.plant} plant, not {plant.name}")
    obs_kw = dict(loaded[0].observation_kwargs) if loaded else {}
    if control_dt is not None:
        obs_kw["control_dt"] = float(control_dt)
    damper = comparison_damper(damper, [a.env_kwargs for a in loaded])
    extra = {} if damper is None else {"damper": damper}
    # the laws keep their own memory (filters, observers): the same sensors, without the agent's stacked history
    # and without the road ahead, which only the rows that say preview see (a preview agent listed first must not
    # hand it to the laws and the plain MPC rows)
    law_kw = {**{k: v for k, v in obs_kw.items() if k not in ("action_mode", "preview")}, "history": 1, **extra}
    if law_kw.get("sensors"):
        law_kw["sensors"] = tuple(s for s in law_kw["sensors"] if s != "road_preview")
    rows = [(f"agent {a.name.split(' s')[0]}", Path(a.folder), dict(extra)) for a in loaded]
    rows += law_rows(plant, plant.laws if laws is None else laws, law_kw, laws_at_1ms=laws_at_1ms, mpc=mpc)
    scenarios = held_out_scenarios(plant, seeds=seeds, quick=quick)
    tasks = [Task(controller_episodes, (ctrl, sc, plant.response(sc.options)), kw, label=f"{sc.name} / {label}")
             for sc in scenarios for label, ctrl, kw in rows]
    results = iter(run_tasks(tasks, backend=backend, jobs=jobs, address=address, progress=progress,
                             desc=f"evaluate {plant.name}"))
    out: dict[str, list[Episode]] = defaultdict(list)
    for _sc in scenarios:
        for label, _, _ in rows:
            out[label] += next(results)
    return dict(out)


def comparison_damper(damper: str | None, agents_env_kwargs) -> str | None:
    """The damper of every row: the one asked for, else the one the agents were trained with (a fitted preset
    file, say), else None (the plant's own)."""
    trained_on = {str(kw.get("damper")) for kw in agents_env_kwargs if kw.get("damper") is not None}
    if damper is None and trained_on:
        if len(trained_on) > 1:
            raise ValueError(f"the agents were trained on different dampers {sorted(trained_on)}: choose one with "
                             "--damper")
        damper = trained_on.pop()
    return damper


def law_rows(plant: PlantProfile, laws, law_kw: dict, *, laws_at_1ms: bool = True, mpc: bool = True) -> list[tuple]:
    """(row label, controller, environment options) of the laws at the comparison's step (``law_kw``'s
    control_dt) and at 1 ms, and of the plant's MPC rows (:attr:`~.plants.PlantProfile.mpc`: label, control step
    (None: the comparison's), controller options, preview); ``ValueError`` if two rows would share a label (their
    episodes would be pooled as one controller's)."""
    dt = law_kw.get("control_dt", 1e-3)
    rows = [(f"{name} @ {dt * 1e3:g} ms", name, law_kw) for name in laws]
    if laws_at_1ms and abs(dt - 1e-3) > 1e-12:
        rows += [(f"{name} @ 1 ms", name, {**law_kw, "control_dt": 1e-3}) for name in laws]
    if mpc:
        for label, step, options, preview in plant.mpc:
            if step is None and any(other == label and s is not None and abs(s - dt) < 1e-12
                                    for other, s, _, _ in plant.mpc):
                continue  # the row tuned for this very step stands for it (e.g. MPC+preview at 1 ms)
            kw = {**law_kw, "control_dt": dt if step is None else step}
            rows.append((f"{label} @ {kw['control_dt'] * 1e3:g} ms", ("mpc", options),
                         preview_options(plant, kw) if preview else kw))
    labels = [label for label, _, _ in rows]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise ValueError(f"--laws: the rows {twice} would each be evaluated twice (a law given twice, or one the MPC "
                         "rows hold: add --no-mpc)")
    return rows
