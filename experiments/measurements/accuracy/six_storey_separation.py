"""Does the six-storey building of the v2 suites (preset ``six_storey_v2``, issue 51) separate passive-on, the best
law and the clairvoyant? Two steps, each a command:

    python -m experiments.measurements.accuracy.six_storey_separation tune [--seeds 16] [--seconds 4] [--out DIR]
    python -m experiments.measurements.accuracy.six_storey_separation separate --spec SPEC [--per-scenario 3] \\
        [--clairvoyant LABEL ...] [--gains FILE] [--out DIR]

``tune``: the laws' gains on **training records only** — the plant's training distribution (``profile.training``:
Kanai–Tajimi with random ω_g, ζ_g, PGA and the PEER records of Loma Prieta, San Fernando and Northridge scaled to a
random PGA) on seeds 0 … N−1, far below every suite's (10⁶ and up), never El Centro nor a pulse — on the
``six_storey_v2`` building, at the suites' 10 ms control step. Per law a grid of its gain (clipped-optimal's force
scale ``force_ref``, modulated friction's ``gain``); the best of each law's grid by its mean training return, and the
best law overall, are written to ``tuned_gains.json``.

``separate``: on held-out episodes of a suite spec (the first ``--per-scenario`` seeds of each scenario; the
episodes the suite would hold), passive-on, the best constant command R_p (the builder's grid of 17 at the control
step), every law with its tuned gains, and on the episodes named by ``--clairvoyant`` the certified clairvoyant R_c by
the builder's own procedure 2 (``experiments.benchmark.references.episode_references``: both solution paths at
the control step), with its wall time per episode. Paired over the same episodes: best law − passive-on, best law
− R_p, and (where solved) R_c − best law, each a mean with its 95 % interval and the episodes won. The best law is
the one ``tune`` chose on training records, never the best on these episodes.

``--gradient SCENARIO``: the gradient path's first round of the spec's own procedure (3 or more: the scenario's
episodes solved together, :func:`experiments.benchmark.references.batched_round_1`) on every episode of that
scenario — a lower bound R_g ≤ R_c on each (its command sequence replayed in the environment is a clairvoyant's),
far cheaper than certifying. It is kept where the suite's build keeps it (``--keep-for``, default
``results/suites/<suite id>.json``), under the build's own keys, so that the build uses it again. Paired: R_g − best
law, R_g − R_p; R_g − best law > 0 shows the clairvoyant separated from the best law (R_c can only be higher).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from mrd_env.report import write_table
from mrd_env.storage import write_json

from experiments.common.evaluation import controller_episodes, mean_ci
from experiments.common.scenarios import Scenario

ENV_ID = "mrd_env/ShearBuildingPhysical-v0"
CONTROL_DT = 0.01
#: The building: the v2 preset with its own damper storeys (the profile's options put one damper in storey 2).
BUILDING = {"plant_preset": "six_storey_v2", "damper_floors": [2, 2, 2, 2]}
#: Laws without a gain, and each tuned law's grid {option: values} (``modulated_friction``'s gain as multiples of its
#: default, the largest diagonal entry of K over 10).
FIXED_LAWS = ("passive_off", "passive_on", "lyapunov", "max_energy_dissipation", "decentralized_bang_bang")
GRIDS = {"clipped_optimal": ("force_ref", (1000.0, 2000.0, 3000.0, 5000.0, 10000.0, 30000.0)),
         "clipped_optimal_reward": ("force_ref", (1000.0, 2000.0, 3000.0, 5000.0, 10000.0, 30000.0)),
         "modulated_friction": ("gain", (0.25, 0.5, 1.0, 2.0, 4.0))}
PASSIVE = ("passive_off", "passive_on")


def _returns(law: str, options: dict, scenario: Scenario) -> np.ndarray:
    return np.array([e.episode_return for e in controller_episodes((law, options), scenario, control_dt=CONTROL_DT)])


def _gain_options(law: str, value: float) -> dict:
    """The controller options of ``law`` at grid value ``value`` (modulated friction's gain in N/m from its multiple
    of the default)."""
    key, _ = GRIDS[law]
    if law == "modulated_friction":
        from mrd_env.plants.shear_building import shear_building

        k = shear_building(BUILDING["plant_preset"]).K
        return {key: float(value * np.max(np.diag(k)) / 10.0)}
    return {key: float(value)}


def tune(seeds: int, seconds: float) -> tuple[list[dict], dict]:
    """(rows, tuned): every law and grid value's mean training return with its interval; the tuned options of each
    law and the best law by mean training return."""
    from mrd_env.plants import plant
    from mrd_env.suites import suite

    name = suite("building-six-storey-v1").plant  # the building's plant, named by its shipped suite
    training = dict(plant(name).profile.training)
    sc = Scenario("training", ENV_ID, {**training, **BUILDING, "episode_seconds": seconds}, tuple(range(seeds)))
    rows, best = [], {}
    for law in (*FIXED_LAWS, *GRIDS):
        grid = [None] if law in FIXED_LAWS else list(GRIDS[law][1])
        for value in grid:
            options = {} if value is None else _gain_options(law, value)
            t0 = time.perf_counter()
            r = _returns(law, options, sc)
            m, lo, hi = mean_ci(r)
            rows.append({"law": law, "options": json.dumps(options), "episodes": r.size, "return": m,
                         "return_lo95": lo, "return_hi95": hi, "wall_s": round(time.perf_counter() - t0, 1)})
            if law not in best or m > best[law][0]:
                best[law] = (m, options)
    laws = {k: v for k, v in best.items() if k not in PASSIVE}
    chosen = max(laws, key=lambda k: laws[k][0])
    tuned = {"plant_options": BUILDING, "training": {"seeds": [0, seeds - 1], "episode_seconds": seconds,
                                                "distribution": f"profile.training of {name}"},
             "control_dt": CONTROL_DT, "options": {k: v[1] for k, v in best.items()},
             "training_return": {k: round(v[0], 6) for k, v in best.items()}, "best_law": chosen}
    return rows, tuned


def _gradient_bounds(name: str, env_id: str, definition, scenarios: list[str], keep_for: Path | None,
                     say=print) -> dict:
    """{label: R_g}: the gradient path's round 1 of ``definition``'s procedure on every episode of ``scenarios``,
    kept where the suite's build keeps it, under its keys (see the module docstring)."""
    from mrd_env.plants import plant
    from mrd_env.suites import draws

    from experiments.benchmark.references import batched_round_1, partial_folder, suite_keys

    if definition.procedure < 3:
        raise ValueError(f"--gradient: the spec's procedure {definition.procedure} has no batched round 1 (3 or more)")
    suite = definition.suite(name, env_id, draws(definition, env_id))
    names = [sc.name for sc in suite.scenarios]
    unknown = [n for n in scenarios if n not in names]
    if unknown:
        raise ValueError(f"--gradient: no scenario {unknown[0]!r} in the spec (scenarios: {names})")
    warm = tuple(plant(name).profile.warm_laws)
    keep = partial_folder(keep_for or Path("results/suites") / f"{suite.id}.json")
    keep.mkdir(parents=True, exist_ok=True)
    chosen = [(sc, seed) for sc, seed in suite.episodes() if sc.name in scenarios]
    keys = suite_keys(suite, env_id, warm, definition.procedure, chosen)
    episodes = [(sc.label(seed), suite.reference_options(sc, seed), seed, sc.name) for sc, seed in chosen]
    paths = batched_round_1(env_id, episodes, warm, suite.control_dt, say=say, keep=keep, keys=keys,
                            limit_penalty=definition.procedure >= 5)
    return {label: float(r.ret) for label, r in paths.items()}


def separate(spec: Path, per_scenario: int, clairvoyant: list[str], tuned: dict, say=print,
             gradient: list[str] = (), keep_for: Path | None = None) -> tuple[list, list]:
    """(episode rows, paired rows) on the held-out episodes of ``spec`` (see the module docstring); the clairvoyant
    on the episodes labelled in ``clairvoyant``, solved after every law has run; the gradient path's lower bound
    R_g on every episode of the scenarios named in ``gradient`` (each then held out whole)."""
    from mrd_env.plants import plant, suite_spec

    from experiments.benchmark.references import best_constant, episode_problem, episode_references

    name, env_id, definition = suite_spec(spec)
    suite = definition.suite(name, env_id)
    warm = tuple(plant(name).profile.warm_laws)
    best_law = tuned["best_law"]
    laws = [k for k in tuned["options"] if k not in PASSIVE]
    bounds = _gradient_bounds(name, env_id, definition, list(gradient), keep_for, say) if gradient else {}
    rows, where = [], {}
    for sc in suite.scenarios:
        for seed in (sc.seeds if sc.name in gradient else sc.seeds[:per_scenario]):
            label, options = sc.label(seed), suite.episode_options(sc, seed)
            one = Scenario(label, env_id, options, (seed,))
            row = {"episode": label, "passive_on": float(_returns("passive_on", {}, one)[0]),
                   "passive_off": float(_returns("passive_off", {}, one)[0])}
            for law in laws:
                row[law] = float(_returns(law, tuned["options"][law], one)[0])
            problem = episode_problem(env_id, suite.reference_options(sc, seed), seed, suite.control_dt)
            row["R_p"], row["R_p_command"] = best_constant(problem)
            row["best_law"] = row[best_law]
            row["R_c"] = row["clairvoyant_s"] = row["clairvoyant_cpu_s"] = math.nan
            row["R_g"] = bounds.get(label, math.nan)
            rows.append(row)
            where[label] = (sc, seed)
            say(json.dumps({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()}))
    unknown = [lb for lb in clairvoyant if lb not in where]
    if unknown:
        raise ValueError(f"--clairvoyant: no held-out episode {unknown[0]!r} (episodes: {list(where)})")
    for row in rows:
        if row["episode"] not in clairvoyant:
            continue
        sc, seed = where[row["episode"]]
        t0, c0 = time.perf_counter(), time.process_time()
        ref = episode_references(env_id, suite.reference_options(sc, seed), row["episode"], seed, warm, procedure=2,
                                 control_dt=suite.control_dt)
        row["R_c"] = ref["reference"]["clairvoyant"]
        row["clairvoyant_s"] = round(time.perf_counter() - t0, 1)
        row["clairvoyant_cpu_s"] = round(time.process_time() - c0, 1)  # the load-independent figure
        row["wall"] = json.dumps(ref["wall"])
        row["certificate"] = json.dumps(ref.get("certificate", {}))
        row["load"] = json.dumps(ref["load_average"])
        say(json.dumps({k: row[k] for k in ("episode", "R_p", "best_law", "R_c", "clairvoyant_s", "clairvoyant_cpu_s",
                                            "wall", "load")}))
    for row in rows:
        rng = row["R_c"] - row["R_p"]
        row["share_best_law"] = (row["best_law"] - row["R_p"]) / rng if rng > 0 else math.nan
        row["share_passive_on"] = (row["passive_on"] - row["R_p"]) / rng if rng > 0 else math.nan
    paired = []
    for a, b in ((best_law, "passive_on"), (best_law, "R_p"), ("R_c", best_law), ("R_c", "R_p"), ("R_g", best_law),
                 ("R_g", "R_p")):
        d = np.array([r[a] - r[b] for r in rows if math.isfinite(r[a]) and math.isfinite(r[b])])
        m, lo, hi = mean_ci(d)
        paired.append({"difference": f"{a} − {b}", "episodes": d.size, "mean": m, "lo95": lo, "hi95": hi,
                       "won": int((d > 0).sum())})
    return rows, paired


def main(argv=None) -> int:
    from mrd_env.stepping.first_use import set_mode

    set_mode("wait")
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="step", required=True)
    t = sub.add_parser("tune", help="the laws' gains on training records")
    t.add_argument("--seeds", type=int, default=16)
    t.add_argument("--seconds", type=float, default=4.0)
    s = sub.add_parser("separate", help="passive-on, the best law and the clairvoyant on a spec's episodes")
    s.add_argument("--spec", type=Path, required=True)
    s.add_argument("--per-scenario", type=int, default=3)
    s.add_argument("--clairvoyant", nargs="*", default=[], metavar="LABEL",
                   help="the episodes whose clairvoyant is solved (labels, e.g. 'Kanai–Tajimi s1000000')")
    s.add_argument("--gains", type=Path, default=None, help="tune's tuned_gains.json (default: in --out)")
    s.add_argument("--gradient", nargs="*", default=[], metavar="SCENARIO",
                   help="scenarios whose episodes get the gradient path's round 1 (a lower bound on R_c)")
    s.add_argument("--keep-for", type=Path, default=None,
                   help="the suite file whose build keeps that round 1 (default results/suites/<suite id>.json)")
    for q in (t, s):
        q.add_argument("--out", type=Path, default=Path("results/six_storey_separation"))
    args = p.parse_args(argv)
    import mrd_env  # noqa: F401

    load = [round(x, 2) for x in os.getloadavg()]
    if args.step == "tune":
        rows, tuned = tune(args.seeds, args.seconds)
        tuned["load_average"] = {"start": load, "end": [round(x, 2) for x in os.getloadavg()]}
        write_json(args.out / "tuned_gains.json", tuned, indent=1)
        md, _ = write_table(rows, args.out / "tuning", floatfmt=".4g",
                            title=f"six_storey_v2: the laws' training returns ({args.seeds} training records of "
                                  f"{args.seconds:g} s, 10 ms control); load {load}")
        print(md.read_text())
        print(json.dumps(tuned, indent=1))
        return 0
    tuned = json.loads((args.gains or args.out / "tuned_gains.json").read_text())
    rows, paired = separate(args.spec, args.per_scenario, list(args.clairvoyant), tuned, gradient=args.gradient,
                            keep_for=args.keep_for)
    end = [round(x, 2) for x in os.getloadavg()]
    write_table([{k: v for k, v in r.items() if k not in ("certificate", "wall", "load")} for r in rows],
                args.out / "episodes",
                floatfmt=".4g", title=f"{args.spec.name}: returns per held-out episode; load {load} -> {end}")
    md, _ = write_table(paired, args.out / "paired", floatfmt=".4g",
                        title=f"{args.spec.name}: paired differences (best law by training: {tuned['best_law']})")
    write_json(args.out / "separation.json", {"rows": rows, "paired": paired, "tuned": tuned,
                                              "load_average": {"start": load, "end": end}}, indent=1)
    print(md.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
