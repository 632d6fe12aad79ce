"""``mrd-env benchmark``: a controller × scenario matrix on the same environments, one evaluation loop.

Writes ``<out>/<plant>_benchmark.md`` and ``.csv`` (per scenario and controller, and the worst case over
the scenarios), time histories of the key responses for every controller on one plot per scenario, bar
charts of the normalised metrics, and damper force–velocity loops.

Quarter car: Wk-weighted RMS sprung acceleration, RMS and peak suspension travel, RMS dynamic tyre load,
each also normalised by the passive-off damper. Building: peak and RMS interstorey drift, peak absolute
acceleration, peak base shear, peak damper force; J1–J6 normalised by the uncontrolled building.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np

from mrd_env.report import markdown_table, write_table

QC_SENSORS = ("sprung_acc", "unsprung_acc", "travel", "travel_rate", "sprung_vel", "unsprung_vel",
              "damper_force", "command")
BUILDING_SENSORS = ("abs_acc", "drift", "floor_vel", "damper_force", "damper_stroke", "damper_velocity",
                    "ground_acc", "command")

QC_CONTROLLERS = ("passive_off", "passive_on", "skyhook_on_off", "skyhook_continuous", "groundhook", "hybrid",
                  "clipped_optimal")
# (skyhook is left out for the building: with the damper at the ground floor, the floor velocity relative to
# the ground and the damper velocity are the same signal, so the law degenerates to passive-on)
BUILDING_CONTROLLERS = ("passive_off", "passive_on", "clipped_optimal", "lyapunov", "max_energy_dissipation",
                        "modulated_friction")
#: The quarter-car scenarios record the peak travel instead of stopping at the environment's default 0.1 m
#: rattle-space limit, so that every controller is scored over the whole road.
QC_STROKE_LIMIT = 0.25

QC_METRICS = ("acc_weighted_rms", "travel_rms", "travel_peak", "tyre_load_rms")
BUILDING_METRICS = ("J1", "J2", "J3", "J4", "J5", "J6", "drift_peak", "acc_peak", "damper_force_peak")


@dataclass(frozen=True)
class Scenario:
    """An environment set-up scored over ``seeds`` (one vector environment, one episode per seed)."""

    name: str
    env_id: str
    options: dict = field(default_factory=dict)
    seeds: tuple = (0,)

    def label(self, seed: int) -> str:
        return f"{self.name} s{seed}" if len(self.seeds) > 1 else self.name


def default_scenarios(plant: str, quick: bool = False, seeds: int = 2) -> list[Scenario]:
    """The embedded scenarios: ISO 8608 roads C and D at 20 m/s and a bump (quarter car); El Centro
    replayed 5× faster, Kanai–Tajimi motions and another PEER record (building)."""
    if plant == "quarter_car":
        dur = 3.0 if quick else 10.0
        n = 1 if quick else seeds
        out = [Scenario(f"ISO-{c} 20 m/s", "mrd_env/QuarterCar-v0",
                        dict(road="iso8608", road_params={"road_class": c, "speed": 20.0}, episode_seconds=dur,
                             stroke_limit=QC_STROKE_LIMIT), seeds=tuple(range(n)))
               for c in ("C", "D")]
        if not quick:
            out.append(Scenario("bump 5 cm", "mrd_env/QuarterCar-v0",
                                dict(road="bump", road_params={"height": 0.05, "length": 0.5, "speed": 10.0},
                                     episode_seconds=3.0, stroke_limit=QC_STROKE_LIMIT)))
        return out
    if plant == "building":
        out = [Scenario("El Centro NS (×0.2 time)", "mrd_env/ShearBuilding-v0",
                        dict(ground_motion="el_centro", ground_motion_params={"time_scale": 0.2},
                             **({"episode_seconds": 4.0} if quick else {})))]
        if not quick:
            out.append(Scenario("El Centro EW (×0.2 time)", "mrd_env/ShearBuilding-v0",
                                dict(ground_motion="el_centro",
                                     ground_motion_params={"component": "EW", "time_scale": 0.2})))
            out.append(Scenario("Kanai–Tajimi", "mrd_env/ShearBuilding-v0",
                                dict(ground_motion="kanai_tajimi", episode_seconds=10.0), seeds=tuple(range(seeds))))
        return out
    raise ValueError(f"plant must be 'quarter_car' or 'building', got {plant!r}")


@dataclass
class Episode:
    controller: str
    scenario: str
    metrics: dict
    t: np.ndarray
    response: np.ndarray   # key response history (sprung acceleration or first-storey drift)
    force: np.ndarray
    velocity: np.ndarray   # damper velocity
    wall_time: float
    episode_return: float = float("nan")


def evaluate(controller, env, seed: int, response: str) -> Episode:
    """Run one episode of a scalar environment with ``controller`` (classical laws and agents alike)."""
    base = env.unwrapped
    layout = {n: sl for n, sl, *_ in base.sensor_layout}
    rate = base.roles.get("damper_velocity", "")

    def first(o, name):
        v = o[layout[name]] if name in layout else np.zeros(0)
        return float(v[0]) if v.size else float("nan")

    obs, _ = env.reset(seed=seed)
    controller.reset()
    t, resp, force, vel = [], [], [], []
    total = 0.0
    t0 = time.perf_counter()
    while True:
        action, _ = controller.predict(obs, deterministic=True)
        obs, r, terminated, truncated, info = env.step(action)
        total += r
        t.append(info["t"])
        resp.append(first(obs, response))
        force.append(float(base.damper_force[0]))
        vel.append(first(obs, rate))
        if terminated or truncated:
            break
    wall = time.perf_counter() - t0
    metrics = dict(info.get("episode_metrics", {}))
    if terminated:
        metrics["terminated"] = info.get("termination_reason", "terminated")
    return Episode(getattr(controller, "name", type(controller).__name__), "", metrics, np.array(t),
                   np.array(resp), np.array(force), np.array(vel), wall, total)


def evaluate_batch(make, scenario: Scenario, response: str, **env_options) -> list[Episode]:
    """One episode per seed of ``scenario`` in one vector environment, driven by ``make(venv)`` (a controller
    built on the vector environment: its predict takes the batch of observations)."""
    N = len(scenario.seeds)
    venv = gym.make_vec(scenario.env_id, num_envs=N, vectorization_mode="vector_entry_point",
                        **{**scenario.options, **env_options})
    ctrl = make(venv)
    layout = {n: sl for n, sl, *_ in venv.sensor_layout}
    rate = venv.roles.get("damper_velocity", "")

    def first(o, name):
        return float(o[layout[name]][0]) if name in layout else float("nan")

    obs, _ = venv.reset(seed=list(scenario.seeds))
    ctrl.reset()
    done = np.zeros(N, dtype=bool)
    returns = np.zeros(N)
    metrics: list[dict] = [{} for _ in range(N)]
    t, resp, force, vel = [], [], [], []
    t0 = time.perf_counter()
    while not done.all():
        action, _ = ctrl.predict(obs, deterministic=True)
        obs, r, term, trunc, info = venv.step(action)
        returns[~done] += r[~done]
        if not done[0]:
            t.append(float(info["t"][0]))
            resp.append(first(obs[0], response))
            force.append(first(obs[0], "damper_force"))
            vel.append(first(obs[0], rate))
        ended = (term | trunc) & ~done
        for b in np.flatnonzero(ended):
            metrics[b] = {k: float(v[b]) for k, v in info["episode_metrics"].items()}
            if term[b]:
                metrics[b]["terminated"] = str(info.get("termination_reason", [""] * N)[b] or "terminated")
        done |= ended
    wall = (time.perf_counter() - t0) / N
    venv.close()
    name = getattr(ctrl, "name", type(ctrl).__name__)
    return [Episode(name, scenario.label(seed), metrics[b], np.array(t) if b == 0 else np.zeros(0),
                    np.array(resp) if b == 0 else np.zeros(0), np.array(force) if b == 0 else np.zeros(0),
                    np.array(vel) if b == 0 else np.zeros(0), wall, float(returns[b]))
            for b, seed in enumerate(scenario.seeds)]


def run_benchmark(plant: str, controllers=None, scenarios=None, *, damper: str = "spencer_dyke",
                  out: Path | None = None, progress: bool = True, quick: bool = False,
                  reference_passive: bool = True, agents=()) -> list[Episode]:
    """Every controller on every scenario (all seeds of a scenario in one vector environment); for the quarter
    car also the conventional passive car (the MR damper replaced by the preset's reference dashpot, e.g.
    1500 N·s/m for set A) as a baseline."""
    import mrd_env  # noqa: F401  (registers the environments)
    from controllers import make_controller

    controllers = list(controllers or (QC_CONTROLLERS if plant == "quarter_car" else BUILDING_CONTROLLERS))
    scenarios = scenarios or default_scenarios(plant, quick=quick)
    sensors = QC_SENSORS if plant == "quarter_car" else BUILDING_SENSORS
    response = "sprung_acc" if plant == "quarter_car" else "drift"
    agents = [Path(a) for a in agents]
    jobs = [(s, c) for s in scenarios for c in list(controllers) + agents]
    from tqdm.auto import tqdm
    bar = tqdm(total=len(jobs), desc=f"benchmark {plant}", disable=not progress)
    by_scenario: dict[str, list[Episode]] = {}
    for sc in scenarios:
        eps = []
        for name in controllers:
            bar.set_postfix_str(f"{sc.name} / {name}")
            eps.append(evaluate_batch(lambda v, n=name: make_controller(n, v), sc, response, damper=damper,
                                      sensors=sensors))
            bar.update()
        for path in agents:
            eps.append(_agent_episodes(path, sc, damper, response))
            bar.update()
        if plant == "quarter_car" and reference_passive:
            eps.append(_reference_passive(sc, sensors, response))
        # rows: per seed, every controller (the table's order)
        for k in range(len(sc.seeds)):
            by_scenario.setdefault(sc.label(sc.seeds[k]), []).extend(e[k] for e in eps)
    bar.close()
    episodes = [e for group in by_scenario.values() for e in group]
    if out is not None:
        write_reports(plant, episodes, Path(out))
    return episodes


def _agent_episodes(path: Path, sc: Scenario, damper: str, response: str) -> list[Episode]:
    """A saved agent (``mrd-env train``) on the scenario, in the environment set-up it was trained in."""
    from controllers import AgentController

    from .train import NormalizedAgent

    agent = NormalizedAgent(path)
    kwargs = agent.meta["env_kwargs"]
    options = {k: v for k, v in sc.options.items() if k not in kwargs}
    scen = Scenario(sc.name, sc.env_id, {**options, **kwargs}, sc.seeds)
    eps = evaluate_batch(lambda v: AgentController(v, agent, name=f"agent:{path.stem}"), scen, response,
                         damper=damper)
    for e in eps:
        e.controller = f"agent:{path.stem}"
    return eps


def _reference_passive(sc: Scenario, sensors, response) -> list[Episode]:
    from controllers import PassiveOff
    from mrd_env.plants import quarter_car

    c = quarter_car(sc.options.get("plant_preset", "set_a")).passive_c
    eps = evaluate_batch(PassiveOff, sc, response, damper="bingham",
                         damper_params=dict(fc_a=0.0, fc_b=0.0, c0a=c, c0b=0.0, f0=0.0), sensors=sensors)
    for e in eps:
        e.controller = f"passive_ref (c={c:g})"
    return eps


def _rows(plant: str, episodes: list[Episode]) -> list[dict]:
    keys = QC_METRICS if plant == "quarter_car" else BUILDING_METRICS
    rows = []
    for ep in episodes:
        row = {"scenario": ep.scenario, "controller": ep.controller}
        for k in keys:
            row[k] = float(ep.metrics.get(k, float("nan")))
        if plant == "quarter_car":  # normalise by passive-off on the same scenario
            ref = next((e for e in episodes if e.scenario == ep.scenario and e.controller == "passive_off"), None)
            for k in ("acc_weighted_rms", "tyre_load_rms"):
                if ref is not None and ref.metrics.get(k):
                    row[f"{k}/off"] = row[k] / ref.metrics[k]
        row["terminated"] = ep.metrics.get("terminated", "")
        rows.append(row)
    return rows


def worst_case(rows: list[dict]) -> list[dict]:
    """Per controller, the maximum of every numeric column over the scenarios (benchmark convention)."""
    out = []
    for ctrl in dict.fromkeys(r["controller"] for r in rows):
        mine = [r for r in rows if r["controller"] == ctrl]
        row = {"scenario": "max over scenarios", "controller": ctrl}
        for k, v in mine[0].items():
            if isinstance(v, float):
                row[k] = float(np.nanmax([m[k] for m in mine]))
        out.append(row)
    return out


def write_reports(plant: str, episodes: list[Episode], out: Path) -> dict:
    from mrd_env.report import figure, save_figure

    out.mkdir(parents=True, exist_ok=True)
    rows = _rows(plant, episodes)
    worst = worst_case(rows)
    md, csv_path = write_table(rows + worst, out / f"{plant}_benchmark", floatfmt=".4g",
                               title=f"{plant}: controller × scenario")
    (out / f"{plant}_benchmark_worst.md").write_text(markdown_table(worst, floatfmt=".4g",
                                                                    title=f"{plant}: worst case over scenarios"))
    figs = []
    ylabel = "sprung acceleration (m/s²)" if plant == "quarter_car" else "first-storey drift (m)"
    for sc in dict.fromkeys(e.scenario for e in episodes):
        eps = [e for e in episodes if e.scenario == sc and e.t.size]  # histories: a scenario's first seed
        if not eps:
            continue
        fig, (a1, a2) = figure(2, 1, figsize=(10, 6), sharex=True)
        for e in eps:
            a1.plot(e.t, e.response, lw=0.8, label=e.controller)
            a2.plot(e.t, e.force / 1e3, lw=0.8, label=e.controller)
        a1.set_ylabel(ylabel)
        a2.set_ylabel("damper force (kN)")
        a2.set_xlabel("time (s)")
        a1.legend(fontsize=7, ncol=4)
        a1.set_title(sc)
        for a in (a1, a2):
            a.grid(alpha=0.3)
        figs.append(save_figure(fig, out / f"{plant}_history_{_slug(sc)}.png"))
        fig, ax = figure(figsize=(6, 4.5))
        for e in eps:
            ax.plot(e.velocity, e.force / 1e3, lw=0.6, label=e.controller)
        ax.set_xlabel("damper velocity (m/s)")
        ax.set_ylabel("damper force (kN)")
        ax.set_title(f"force–velocity: {sc}")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        figs.append(save_figure(fig, out / f"{plant}_loops_{_slug(sc)}.png"))
    keys = ([k for k in rows[0] if k.endswith("/off")] + ["travel_peak"]) if plant == "quarter_car" \
        else ["J1", "J2", "J3", "J4", "J5"]
    fig, ax = figure(figsize=(10, 4.5))
    ctrls = [r["controller"] for r in worst]
    width = 0.8 / max(len(keys), 1)
    for i, k in enumerate(keys):
        ax.bar(np.arange(len(ctrls)) + i * width, [r.get(k, np.nan) for r in worst], width, label=k)
    ax.set_xticks(np.arange(len(ctrls)) + 0.4 - width / 2, ctrls, rotation=20, fontsize=8)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylabel("normalised (worst case over scenarios)")
    ax.legend(fontsize=8)
    figs.append(save_figure(fig, out / f"{plant}_bars.png"))
    return {"markdown": md, "csv": csv_path, "figures": figs}


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in s).strip("_").lower()


# ---------------------------------------------------------------------------- CLI


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", choices=["building", "quarter_car", "both"], default="both")
    p.add_argument("--controllers", nargs="+", default=None, help="controller names (default: all that apply)")
    p.add_argument("--damper", default="spencer_dyke", help="damper model name")
    p.add_argument("--quick", action="store_true", help="short scenarios (a smoke run)")
    p.add_argument("--seeds", type=int, default=2, help="random scenarios per kind (roads, Kanai–Tajimi)")
    p.add_argument("--out", type=Path, default=Path("results/benchmark"))
    p.add_argument("--agent", type=Path, nargs="*", default=[], help="saved agents (mrd-env train) to score too")
    p.add_argument("--no-progress", action="store_true")


def scenario_rows(scenarios) -> list[dict]:
    """The settings of every scenario (environment, options, seed), printed and written with the tables."""
    return [{"scenario": sc.name, "environment": sc.env_id, "seeds": ", ".join(map(str, sc.seeds)),
             "options": ", ".join(f"{k}={v}" for k, v in sc.options.items()) or "defaults"} for sc in scenarios]


def run(args: argparse.Namespace) -> int:
    from .train import agent_metadata

    plants = ["building", "quarter_car"] if args.plant == "both" else [args.plant]
    agents = {path: agent_metadata(path)["plant"] for path in args.agent}  # ValueError for a bad path
    for path, plant in agents.items():
        if plant not in plants:
            raise ValueError(f"agent {path} was trained on the {plant} plant; add --plant {plant} (or both)")
    if args.seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {args.seeds}")
    # names checked before any episode runs: a typo must not cost a progress bar and a built environment
    from controllers import CONTROLLERS
    from mrd_env.dampers import damper_class

    unknown = [c for c in args.controllers or () if c not in CONTROLLERS]
    if unknown:
        raise ValueError(f"--controllers: unknown controller(s) {unknown}; available: {sorted(CONTROLLERS)}")
    damper_class(args.damper)
    for plant in plants:
        scen = default_scenarios(plant, quick=args.quick, seeds=args.seeds)
        eps = run_benchmark(plant, args.controllers, scen, damper=args.damper, out=args.out,
                            progress=not args.no_progress, agents=[p for p, pl in agents.items() if pl == plant])
        settings = markdown_table(scenario_rows(scen), title=f"{plant}: scenario settings")
        (args.out / f"{plant}_scenarios.md").write_text(settings)
        print(settings)
        print((args.out / f"{plant}_benchmark_worst.md").read_text())
        print(f"wrote {args.out}/{plant}_benchmark.md/.csv, {plant}_scenarios.md and figures ({len(eps)} episodes)")
    return 0
