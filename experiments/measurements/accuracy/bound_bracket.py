"""The yardstick's bracket with the active bound and with the passivity-aware bound (a script, not a test).

    python -m experiments.measurements.accuracy.bound_bracket [--scenario NAME ...] [--seeds N | --seed S ...] [--seconds S] \\
        [--no-clairvoyant] [--oracle] [--storage J] [--out results/bench/bound_bracket]
    python -m experiments.measurements.accuracy.bound_bracket --suite ID [ID ...] [--out results/bench/suite_bracket] \\
        [--resume]

``--suite`` (``all``: every shipped suite with its own references; a suite that copies another's, ``car-preview``,
``car-full-preview``, has that one's brackets): on **every episode of the suite**, the stored references R_p, R_c,
R_b and f_max (:mod:`mrd_env.suites`: nothing is re-solved but the passivity-aware bounds) beside R_d, the
passivity-aware bound with the stored f_max on the episode's plant (:meth:`~mrd_env.suites.Suite.reference_options`;
its ports referred to the dampers' static forces at their initial strokes, the full car's warped start), and R_d,c,
the same with the damper's viscous floor c_min (:func:`~mrd_env.optimal.dissipative.viscous_floor`); the three
brackets; whether R_c ≤ R_d ≤ R_b and R_c ≤ R_d,c ≤ R_d; how far each optimum is from semi-active (the share of its
rows giving energy back: 0 would make it tight); and the least energy that passive-on, passive-off and a seeded
random bang-bang sequence absorbed at any row, with c_min = 0 and with the floor (≥ 0: the runs lie in each class).
Then per suite and per scenario each bracket's smallest / median / largest and the wall times. ``--out`` writes
``<out>.json`` after every episode (``--resume`` keeps its episodes), the tables as Markdown and CSV, and
``<out>_docs.md``, the tables of docs/yardstick.md.

For each episode (default: the first seed of the held-out scenarios "ISO-C 20 m/s" and "bump 5 cm" of the quarter
car and "El Centro NS (×0.2 time)" of the building; ``--scenario all`` for every held-out scenario of both plants,
``--seeds 3`` for all their seeds, ``--seconds`` to shorten an episode) it prints

* R_p, the best constant command (9 from v_min to v_max, as the yardstick);
* R_c, the clairvoyant optimum warm-started from the plant's laws at 1 ms (:func:`mrd_env.optimal.clairvoyant`,
  cached), or with ``--no-clairvoyant`` the best law's return;
* f_max, the largest |F − F_static| of passive-on, the laws and the clairvoyant (the yardstick's rule);
* R_b, the active-actuator bound (:func:`mrd_env.optimal.active_bound`), and R_d, the passivity-aware bound
  (:func:`mrd_env.optimal.dissipative_bound`), both with that f_max, and each one's bracket (R − R_c)/(R − R_p);
* whether every law and the clairvoyant lie in R_d's class (the least energy any of them has absorbed at any row,
  ≥ −storage) and below it, and how far R_d's optimum is from semi-active: the share of rows where it pushes
  energy in ((F − F_static)·ẋ_d < 0) and the energy it gives back there (0 and 0 would make the relaxation tight);
* the wall times of each part and the machine's load average.

``--oracle`` adds a diagnostic that is **not a bound**: the active QP with the convex hull of
{(F − F_static)·ẋ_d ≥ 0, |F − F_static| ≤ f_max, ẋ_d ∈ [v_lo, v_hi]} at every row (the McCormick envelope where the
interval straddles 0, the sign of the force where it does not), with [v_lo, v_hi] the envelope of the stroke
velocities of the laws and the clairvoyant themselves, widened by 1 % of their peak: valid velocity bounds could
hardly be narrower, so its value says how much any per-row envelope could gain.
"""
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

#: the default episodes: scenarios of the published benchmark's plants, by name
DEFAULT = ("ISO-C 20 m/s", "bump 5 cm", "El Centro NS (×0.2 time)")


def episodes(names, seeds: int, seconds: float | None, only=None):
    """[(plant, env_id, label, seed, options)] of the held-out scenarios named (``("all",)``: every one), their
    first ``seeds`` seeds or those of them in ``only``."""
    from experiments.common.plants import chosen_plants
    from experiments.common.scenarios import held_out_scenarios

    out = []
    for plant in chosen_plants("both"):
        for sc in held_out_scenarios(plant):
            if names != ("all",) and sc.name not in names:
                continue
            opts = dict(sc.options)
            if seconds is not None:
                opts["episode_seconds"] = float(seconds)
            chosen = [s_ for s_ in sc.seeds if s_ in only] if only else sc.seeds[:seeds]
            for seed in chosen:
                out.append((plant, sc.env_id, sc.label(seed), int(seed), opts))
    return out


def bracket(bound: float, clairvoyant: float, passive: float) -> float:
    span = bound - passive
    return (bound - clairvoyant) / span if span > 0 else math.nan


def oracle_envelope(problem, f_max: float, v_lo: np.ndarray, v_hi: np.ndarray) -> float:
    """The active QP with the per-row convex hull of the semi-active set on [v_lo, v_hi] (see the module docstring;
    a diagnostic, not a bound). Its return (−primal objective)."""
    import scipy.sparse as sp

    from mrd_env.optimal.bound import clarabel_solve, normalise_rows, Rows, program

    p = problem
    prog = program(p, f_max, True)
    L = prog.L
    N = L.N
    r1 = np.arange(1, N + 1)
    Fs = p.F_static
    cv = p.Cv[0]
    jv = np.nonzero(cv)[0]
    lo_, hi_ = v_lo[1:], v_hi[1:]
    cuts, lo, hi = Rows(), [], []

    def row(rr, vcoef, low, high):   # low ≤ F_r + vcoef·ẋ_d,r ≤ high on rows rr
        st = cuts.new(rr.size)
        ri = st + np.arange(rr.size)
        cuts.i.append(ri)
        cuts.j.append(L.F(rr))
        cuts.v.append(np.ones(rr.size))
        for j in jv:
            cuts.i.append(ri)
            cuts.j.append(L.x(rr) + j)
            cuts.v.append(vcoef * cv[j])
        lo.append(low)
        hi.append(high)

    big = 1e12
    pos, neg = lo_ >= 0, hi_ <= 0
    mid = ~(pos | neg)
    z = np.zeros
    row(r1[pos], z(pos.sum()), np.full(pos.sum(), Fs), np.full(pos.sum(), big))
    row(r1[neg], z(neg.sum()), np.full(neg.sum(), -big), np.full(neg.sum(), Fs))
    m = mid.sum()
    row(r1[mid], -f_max / np.abs(lo_[mid]), np.full(m, -big), np.full(m, Fs + f_max))   # F ≤ f(1 + v/|v_lo|)
    row(r1[mid], -f_max / hi_[mid], np.full(m, Fs - f_max), np.full(m, big))           # F ≥ −f(1 − v/v_hi)
    st = cuts.new(N)   # the velocity interval itself
    for j in jv:
        cuts.i.append(st + np.arange(N))
        cuts.j.append(L.x(r1) + j)
        cuts.v.append(np.full(N, cv[j]))
    lo.append(lo_)
    hi.append(hi_)
    A_in = sp.vstack([prog.A_in, cuts.matrix(L.n)]).tocsc()
    Dm = sp.diags(prog.scale)
    A_eq_s, b_eq = normalise_rows((prog.A_eq @ Dm).tocsc(), prog.b_eq)
    A_in_s, lo_s, hi_s = normalise_rows((A_in @ Dm).tocsc(), np.concatenate([prog.lo, *lo]),
                                         np.concatenate([prog.hi, *hi]))
    Pd = np.zeros(L.n)
    Pd[prog.iy] = 2.0 * prog.scale[prog.iy] ** 2
    _, primal, _, _, _ = clarabel_solve(sp.diags(Pd).tocsc(), np.zeros(L.n), A_eq_s, b_eq, A_in_s, lo_s, hi_s, 1e-7,
                                   who="oracle envelope")
    return -primal


def run(plant, env_id, label, seed, options, *, clairvoyant: bool, oracle: bool, storage: float) -> dict:
    from experiments.common.plants import profile
    from experiments.benchmark.yardstick import best_passive, warm_starts
    from mrd_env.optimal import active_bound, dissipative_bound, episode_problem
    from mrd_env.optimal.dissipative import absorbed_energy

    t0 = time.perf_counter()
    p = episode_problem(env_id, seed=seed, control_dt=1e-3, **options)
    rp, _ = best_passive(p)
    starts = warm_starts(p, profile(plant).warm_laws)
    starts["passive_on"] = np.full((p.n_steps, p.nd), p.v_max)
    t_ref = time.perf_counter() - t0
    t_cv = math.nan
    if clairvoyant:
        from mrd_env.optimal import clairvoyant as solve

        cv = solve(p, warm_starts=starts, progress=False)
        t_cv = float(cv.wall_time)   # the solve's own wall time (also when the result comes from the cache)
        rc, source = float(cv.ret), f"clairvoyant ({cv.source})"
        starts["clairvoyant"] = cv.commands
    runs = {name: p.replay(U, states=True) for name, U in starts.items()}
    if not clairvoyant:   # the best return known: a law's or the best constant command's
        rc, source = max([(tr.ret, f"best law ({k})") for k, tr in runs.items()] + [(rp, "best constant")])
    f_max = max(float(np.nanmax(np.abs(tr.F - p.F_static))) for tr in runs.values())
    a = active_bound(p, f_max=f_max)
    t2 = time.perf_counter()
    d = dissipative_bound(p, f_max=f_max, storage=storage)
    t_d = time.perf_counter() - t2
    least = min(float(absorbed_energy(p, tr.F).min()) for tr in runs.values())
    best_run = max(tr.ret for tr in runs.values())
    v = d.X @ p.Cv.T
    power = np.sum((d.F - p.F_static) * v, axis=1)
    tolp = 1e-6 * np.max(np.abs(power))
    row = {"episode": f"{plant.name}: {label}", "seconds": p.duration, "R_p": rp, "R_c": rc, "R_c from": source,
           "f_max (N)": f_max, "R_b active": a.bound, "R_d passive": d.bound,
           "bracket active": bracket(a.bound, rc, rp), "bracket passive": bracket(d.bound, rc, rp),
           "least absorbed (J)": least, "all below R_d": bool(best_run <= d.bound and rc <= d.bound),
           "R_d rows giving energy": float(np.mean(power < -tolp)),
           "R_d energy given (J)": float(-np.sum(np.minimum(power, 0.0)) * p.dt),
           "R_d store used (J)": float(-d.absorbed.min()), "R_d status": d.status,
           "references (s)": t_ref, "clairvoyant (s)": t_cv, "active (s)": a.setup_seconds + a.solve_seconds,
           "passive (s)": t_d}
    if oracle:
        V = np.array([tr.X @ p.Cv[0] for tr in runs.values()])
        pad = 0.01 * np.max(np.abs(V))   # an interior for the solver where every run has the same velocity
        t3 = time.perf_counter()
        try:
            row["oracle envelope (not a bound)"] = oracle_envelope(p, f_max, V.min(axis=0) - pad, V.max(axis=0) + pad)
        except RuntimeError as e:
            print(e)
            row["oracle envelope (not a bound)"] = math.nan
        row["oracle (s)"] = time.perf_counter() - t3
    return row


def _solve_rd(p, f_max, storage, min_damping):
    """R_d at the default tolerance, then a looser one where Clarabel stalls (still a bound: the dual objective,
    certified by the solver). (result or None, tolerance, wall s)."""
    from mrd_env.optimal import dissipative_bound

    t0 = time.perf_counter()
    for tol in (1e-8, 1e-6):
        try:
            return dissipative_bound(p, f_max=f_max, storage=storage, tol=tol, min_damping=min_damping), tol, \
                time.perf_counter() - t0
        except RuntimeError as exc:
            print(f"  {p.episode_name}: c_min {np.max(min_damping):g}, tol {tol:g}: {exc}", flush=True)
    return None, None, time.perf_counter() - t0


def _class_check(p, c_min: float, seed: int) -> dict:
    """The least energy (J) that passive-on, passive-off and a seeded random bang-bang command sequence (held over
    the suite's control step) re-simulated in the environment have absorbed at any row, on the environment's own
    forces and states, with c_min = 0 and with the damper's viscous floor: ≥ 0 puts each run in R_d's (R_d,c's)
    class. The runs' largest |F − F_static| beside it (the stored f_max covers them where it is larger)."""
    from mrd_env.optimal.dissipative import absorbed_energy

    rng = np.random.default_rng(seed)
    hold = max(1, int(round(0.01 / p.control_dt)))
    bang = np.repeat(rng.choice([p.v_min, p.v_max], size=(-(-p.n_steps // hold), p.nd)), hold, axis=0)[:p.n_steps]
    runs = [np.full((p.n_steps, p.nd), p.v_max), np.full((p.n_steps, p.nd), p.v_min), bang]
    least0 = least_c = math.inf
    peak = 0.0
    for U in runs:
        tr = p.replay(U, states=True)
        ok = ~np.isnan(tr.F).any(axis=1)
        if not ok.all():   # an early end: the rows it reached
            continue
        least0 = min(least0, float(absorbed_energy(p, tr.F, tr.X).min()))
        least_c = min(least_c, float(absorbed_energy(p, tr.F, tr.X, min_damping=c_min).min()))
        peak = max(peak, float(np.max(np.abs(tr.F - p.F_static))))
    return {"least absorbed (J)": least0, "least absorbed beyond c_min (J)": least_c, "runs' peak |F − F_static| (N)": peak}


def suite_rows(suite, storage: float = 0.0, done: dict | None = None, save=None) -> list[dict]:
    """One row per episode of ``suite`` (see the module docstring, ``--suite``); episodes already in ``done``
    (keyed by suite and episode) are taken from it; ``save(rows)`` after each new one."""
    from mrd_env.optimal import episode_problem
    from mrd_env.optimal.dissipative import static_forces, viscous_floor

    rows = []
    for k, (sc, seed) in enumerate(suite.episodes()):
        label = sc.label(seed)
        if done and (suite.id, label) in done:
            rows.append(done[(suite.id, label)])
            continue
        ref = suite.reference(label)
        t0 = time.perf_counter()
        p = episode_problem(suite.env_id, seed=int(seed), control_dt=1e-3, **suite.reference_options(sc, seed))
        c_min = viscous_floor(p.damper)
        Fs = static_forces(p)
        out = {}
        for key, cm in (("R_d", 0.0), ("R_d,c", c_min)):
            d, tol, wall = _solve_rd(p, ref.f_max, storage, cm)
            rd, share_back, status, gap = math.nan, math.nan, "failed", math.nan
            if d is not None:
                power = np.sum((d.F - d.static_forces) * (d.X @ p.Cv.T), axis=1)
                tolp = 1e-6 * np.max(np.abs(power))
                rd, share_back, status = d.bound, float(np.mean(power < -tolp)), f"{d.status} (tol {tol:g})"
                gap = (d.bound - d.primal_return) / abs(d.bound)   # how much looser than its optimum the bound is
            out[key] = (rd, share_back, status, wall, gap)
        rd, rdc = out["R_d"][0], out["R_d,c"][0]
        row = {"suite": suite.id, "scenario": sc.name, "episode": label, "R_p": ref.passive,
               "R_c": ref.clairvoyant, "R_b active": ref.bound, "R_d passive": rd, "R_d,c passive + c_min": rdc,
               "f_max (N)": ref.f_max, "c_min (N·s/m)": c_min,
               "static forces − F_static (N, largest)": float(np.max(np.abs(Fs - p.F_static))),
               "bracket active": bracket(ref.bound, ref.clairvoyant, ref.passive),
               "bracket passive": bracket(rd, ref.clairvoyant, ref.passive),
               "bracket passive + c_min": bracket(rdc, ref.clairvoyant, ref.passive),
               # R_d ≤ R_b up to the solvers' tolerance (1e-6 of |R_b|)
               "R_c <= R_d <= R_b": bool(ref.clairvoyant <= rd <= ref.bound + 1e-6 * abs(ref.bound)),
               "R_c <= R_d,c <= R_d": bool(ref.clairvoyant <= rdc <= rd + 1e-6 * abs(rd)),
               "R_d rows giving energy": out["R_d"][1], "R_d,c rows giving energy": out["R_d,c"][1],
               "R_d status": out["R_d"][2], "R_d,c status": out["R_d,c"][2],
               "R_d relative gap": out["R_d"][4], "R_d,c relative gap": out["R_d,c"][4],
               **_class_check(p, c_min, seed=1000 + k),
               "R_d (s)": out["R_d"][3], "R_d,c (s)": out["R_d,c"][3], "episode (s)": time.perf_counter() - t0}
        rows.append(row)
        r = row
        print(f"{suite.id} {label}: R_p {r['R_p']:.4g}  R_c {r['R_c']:.4g}  R_b {r['R_b active']:.4g} "
              f"({r['bracket active']:.0%})  R_d {rd:.4g} ({r['bracket passive']:.1%})  R_d,c {rdc:.4g} "
              f"({r['bracket passive + c_min']:.1%})  least absorbed {r['least absorbed (J)']:.2g} / "
              f"{r['least absorbed beyond c_min (J)']:.2g} J  [{r['episode (s)']:.1f} s]", flush=True)
        if save is not None:
            save(rows)
    return rows


def _spread(values) -> str:
    v = np.asarray([x for x in values if math.isfinite(x)])
    if not v.size:
        return "n/a"
    return f"{v.min():.0%} / {np.median(v):.0%} / {v.max():.0%}"


def suite_summary(rows: list[dict], by_scenario: bool = False) -> list[dict]:
    """Per suite (and scenario): the episodes, each bracket's smallest / median / largest, the episodes under 10 %,
    whether every episode has R_c ≤ R_d ≤ R_b and R_c ≤ R_d,c, the least energy the check runs absorbed, and the
    wall time."""
    out = []
    key_of = (lambda r: (r["suite"], r["scenario"])) if by_scenario else (lambda r: (r["suite"],))
    for key in dict.fromkeys(key_of(r) for r in rows):
        mine = [r for r in rows if key_of(r) == key]
        solved = [r for r in mine if math.isfinite(r["R_d passive"])]
        solved_c = [r for r in mine if math.isfinite(r["R_d,c passive + c_min"])]
        head = {"suite": key[0]} if not by_scenario else {"suite": key[0], "scenario": key[1]}
        out.append({**head, "episodes": len(mine),
                    "bracket R_b min / median / max": _spread(r["bracket active"] for r in mine),
                    "bracket R_d min / median / max": _spread(r["bracket passive"] for r in solved),
                    "bracket R_d,c min / median / max": _spread(r["bracket passive + c_min"] for r in solved_c),
                    "R_d solved": f"{len(solved)}/{len(mine)}", "R_d,c solved": f"{len(solved_c)}/{len(mine)}",
                    "episodes under 10 % (R_d, R_d,c)":
                        f"{sum(r['bracket passive'] < 0.10 for r in solved)}, "
                        f"{sum(r['bracket passive + c_min'] < 0.10 for r in solved_c)}",
                    "R_c ≤ R_d ≤ R_b": f"{sum(r['R_c <= R_d <= R_b'] for r in solved)}/{len(solved)}",
                    "R_c ≤ R_d,c ≤ R_d": f"{sum(r['R_c <= R_d,c <= R_d'] for r in solved_c)}/{len(solved_c)}",
                    "least absorbed, beyond c_min (J)":
                        f"{min(r['least absorbed (J)'] for r in mine):.2g}, "
                        f"{min(r['least absorbed beyond c_min (J)'] for r in mine):.2g}",
                    "R_d + R_d,c s (mean)": float(np.mean([r["R_d (s)"] + r["R_d,c (s)"] for r in mine]))})
    return out


def docs_tables(rows: list[dict], copies: dict | None = None) -> str:
    """The docs' tables (docs/yardstick.md): per suite and per scenario each bracket's smallest / median / largest,
    then every episode in compact columns; ¹ marks a bound Clarabel solved only at tolerance 1e-6 or stopped short
    of its tolerance with a certified dual (the status column of the full table)."""
    from mrd_env.report import markdown_table

    def pct(x):
        return "–" if not math.isfinite(x) else f"{x:.0%}"

    def val(r, key, status):
        x = r[key]
        if not math.isfinite(x):
            return "failed"
        return f"{x:.4f}" + ("" if r[status].startswith("Solved (tol 1e-08") else " ¹")

    per_suite = [{"suite": r["suite"], "episodes": r["episodes"],
                  "bracket R_b min / median / max": r["bracket R_b min / median / max"],
                  "bracket R_d": r["bracket R_d min / median / max"],
                  "bracket R_d,c": r["bracket R_d,c min / median / max"],
                  "under 10 % (R_d, R_d,c)": r["episodes under 10 % (R_d, R_d,c)"],
                  "R_c ≤ R_d ≤ R_b": r["R_c ≤ R_d ≤ R_b"], "R_c ≤ R_d,c ≤ R_d": r["R_c ≤ R_d,c ≤ R_d"]}
                 for r in suite_summary(rows)]
    for k, v in (copies or {}).items():
        per_suite.append({"suite": k, "episodes": f"{v}'s references",
                          **{c: "(the same)" for c in list(per_suite[0])[2:]}})
    per_scenario = [{"suite": r["suite"], "scenario": r["scenario"], "episodes": r["episodes"],
                     "bracket R_b min / median / max": r["bracket R_b min / median / max"],
                     "bracket R_d": r["bracket R_d min / median / max"],
                     "bracket R_d,c": r["bracket R_d,c min / median / max"]}
                    for r in suite_summary(rows, by_scenario=True)]
    eps = [{"suite": r["suite"], "episode": r["episode"], "R_p": f"{r['R_p']:.4f}", "R_c": f"{r['R_c']:.4f}",
            "R_b": f"{r['R_b active']:.4f}", "R_d": val(r, "R_d passive", "R_d status"),
            "R_d,c": val(r, "R_d,c passive + c_min", "R_d,c status"), "bracket R_b": pct(r["bracket active"]),
            "bracket R_d": pct(r["bracket passive"]), "bracket R_d,c": f"**{pct(r['bracket passive + c_min'])}**",
            "R_d rows giving energy back": pct(r["R_d rows giving energy"]),
            "R_d, R_d,c (s)": f"{r['R_d (s)']:.0f}, {r['R_d,c (s)']:.0f}"} for r in rows]
    return markdown_table(per_suite) + "\n" + markdown_table(per_scenario) + "\n" + markdown_table(eps)


def main_suites(args) -> None:
    import json

    from mrd_env.report import markdown_table, write_table
    from mrd_env.storage import write_json, write_text
    from mrd_env.suites import suites

    shipped = suites()
    ids = [k for k, s in shipped.items() if not s.procedure.get("references_of")] if args.suite == ["all"] \
        else args.suite
    unknown = [k for k in ids if k not in shipped]
    if unknown:
        raise SystemExit(f"--suite: unknown {unknown}; shipped: {sorted(shipped)}")
    copies = {k: s.procedure["references_of"] for k, s in shipped.items()
              if s.procedure.get("references_of") in ids and k not in ids}
    done, rows_all, before = {}, [], {}
    if args.out and args.resume and os.path.exists(f"{args.out}.json"):
        with open(f"{args.out}.json", encoding="utf-8") as fh:
            before = json.load(fh)
        done = {(r["suite"], r["episode"]): r for r in before["episodes"]}
        print(f"resuming: {len(done)} episodes from {args.out}.json", flush=True)
    t0 = time.perf_counter()
    wall0 = float(before.get("wall_s", 0.0))           # the runs resumed from: their wall time and load
    loads = list(before.get("load average", [])) or [os.getloadavg()[0]]
    fresh = []                                          # episodes solved by this run

    def load_range():
        return [loads[0], os.getloadavg()[0]] if fresh or len(loads) < 2 else loads[:2]

    def record(rows, final=False):
        doc = {"what": "bound bracket on every shipped suite episode (experiments.measurements.accuracy."
                       "bound_bracket --suite)", "suites": ids, "copies (same references)": copies,
               "complete": final, "wall_s": wall0 + time.perf_counter() - t0, "cores": os.cpu_count(),
               "load average": load_range(), "episodes": rows}
        if args.out:
            write_json(f"{args.out}.json", doc, indent=1, ensure_ascii=False)

    def save(rows_all_so_far):
        fresh.append(1)
        record(rows_all_so_far)

    for k in ids:
        rows_all += suite_rows(shipped[k], args.storage, done, save=lambda rows: save(rows_all + rows))
    la = load_range()
    title = (f"bound bracket on every suite episode ({', '.join(ids)}): {len(rows_all)} episodes, "
             f"{wall0 + time.perf_counter() - t0:.0f} s, {os.cpu_count()} cores, load average {la[0]:.1f} → "
             f"{la[1]:.1f}")
    summary, per_scenario = suite_summary(rows_all), suite_summary(rows_all, by_scenario=True)
    print(markdown_table(summary, title=title))
    print(markdown_table(per_scenario, title="per scenario"))
    if copies:
        print("suites with another's references (the same brackets):",
              ", ".join(f"{k} = {v}" for k, v in copies.items()))
    if args.out:
        record(rows_all, final=True)
        print("wrote", write_text(f"{args.out}_docs.md", f"{title}\n\n" + docs_tables(rows_all, copies)))
        for path in [f"{args.out}.json", *write_table(rows_all, args.out, title=title),
                     *write_table(summary, f"{args.out}_summary", title=title),
                     *write_table(per_scenario, f"{args.out}_scenarios", title=title)]:
            print("wrote", path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", nargs="+", default=None,
                    help="held-out scenario names (default: ISO-C 20 m/s, bump 5 cm, El Centro NS); 'all': every one")
    ap.add_argument("--seeds", type=int, default=1, help="seeds per scenario (default 1: the first)")
    ap.add_argument("--seed", type=int, nargs="+", default=None, help="only these seeds of the scenarios")
    ap.add_argument("--seconds", type=float, default=None, help="episode length (default: the scenario's)")
    ap.add_argument("--no-clairvoyant", action="store_true", help="R_c = the best law's return (no optimiser)")
    ap.add_argument("--oracle", action="store_true", help="add the per-row envelope diagnostic (not a bound)")
    ap.add_argument("--storage", type=float, default=0.0, help="the passive bound's initial store E0 (J)")
    ap.add_argument("--suite", nargs="+", default=None,
                    help="every episode of these shipped suites, against their stored references ('all': every one)")
    ap.add_argument("--out", default=None, help="write <out>.md and <out>.csv (with --suite also <out>.json, "
                    "after every episode, and the summaries <out>_summary.*, <out>_scenarios.*)")
    ap.add_argument("--resume", action="store_true", help="with --suite and --out: keep the episodes already in "
                    "<out>.json")
    args = ap.parse_args(argv)

    import mrd_env  # noqa: F401

    if args.suite:
        return main_suites(args)
    from mrd_env.report import markdown_table, write_table

    names = DEFAULT if args.scenario is None else tuple(args.scenario)
    eps = episodes(names, args.seeds, args.seconds, args.seed)
    if not eps:
        raise SystemExit(f"no held-out scenario named {list(names)}")
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    rows = []
    for plant, env_id, label, seed, opts in eps:
        rows.append(run(plant, env_id, label, seed, opts, clairvoyant=not args.no_clairvoyant, oracle=args.oracle,
                        storage=args.storage))
        r = rows[-1]
        print(f"{r['episode']}: R_p {r['R_p']:.4g}  R_c {r['R_c']:.4g}  R_b {r['R_b active']:.4g} "
              f"({r['bracket active']:.0%})  R_d {r['R_d passive']:.4g} ({r['bracket passive']:.0%})  "
              f"[{r['passive (s)']:.1f} s]", flush=True)
    load1 = os.getloadavg()
    title = (f"bound bracket, {len(rows)} episodes, {time.perf_counter() - t0:.0f} s, {os.cpu_count()} cores, load "
             f"average {load0[0]:.1f} → {load1[0]:.1f}")
    print(markdown_table(rows, title=title))
    if args.out:
        for path in write_table(rows, args.out, title=title):
            print("wrote", path)


if __name__ == "__main__":
    main()
