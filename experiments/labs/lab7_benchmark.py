# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab 7 — Enter the benchmark
#
# Labs 3 and 6 compared controllers with each other. A benchmark must also say how far the best of them is from
# the best possible, on episodes nobody tuned on, scored the same way for everyone. mrd-env's **suites** do that:
# a suite is a frozen, versioned list of test episodes (plant, damper, sensors, control step, scenarios and
# seeds) that ships with three **reference returns for every episode**, computed once. Here the suite is
# `car-comfort-v1`: the quarter car `set_a` with the automotive Spencer–Dyke damper (0–2 V) on ISO 8608 roads and
# a 5 cm bump, controlled every 10 ms. You write a controller against the project's protocol, score it, merge
# your result with two of the project's laws into a leaderboard and compare all of them with the clairvoyant
# optimum.
#
# **Learning objectives.** After this lab you can
# 1. read a suite: its scenarios, seeds, control step, sensors, criteria, and its references R_p, R_c and R_b;
# 2. write a controller against the protocol (a class built from the environment's *declarations*, with
#    Stable-Baselines3's `predict`) that reads its signals by role, so that it fits every plant declaring them;
# 3. tune it on roads that are not the suite's, score it with `score(...)`, write the result file and merge
#    results into a leaderboard (complete results ranked, partial ones shown apart);
# 4. explain the share of the achievable gain, why no controller captures more than all of it on average, and
#    what the active bound R_b adds.
#
# **Equations (recap).**
# - Plant (Lab 3): m_s z̈_s = −k_s (z_s − z_u) − F, m_u z̈_u = k_s (z_s − z_u) + F − k_t (z_u − z_r), with F the
#   Spencer–Dyke damper force (review eq. (12)), driven by the command u ∈ [0, 2] V through a first-order lag.
# - Return: R = −∫ Σ_j w_j s_j(t)² / ⟨s_j²⟩_ref dt, the signals s_j the Wk-weighted body acceleration (w = 0.5),
#   the suspension travel (0.25) and the dynamic tyre load (0.25), each per unit of a passive car's mean square
#   on the same road: R is dimensionless, about −1 per second for that passive car; higher is better.
# - References of an episode: R_p = max over constant commands u of R (a grid of 17 from 0 to 2 V, passive-off and
#   passive-on included); R_c = the clairvoyant optimum, the command sequence u(t) ∈ [0, 2] V, held over 1 ms,
#   that maximises R knowing the whole road in advance (Savaresi & Spelta 2007), found by a local optimiser and
#   re-simulated; R_b = the active bound, the dual objective of a convex problem in which an ideal actuator
#   gives any force |F| ≤ f_max at every 1 ms: an upper bound on any damper's return, so R_p ≤ R_c ≤ R_b.
# - Score: the share of the achievable gain, share = (R − R_p) / (R_c − R_p): 0 is the best constant command, 1
#   the clairvoyant, below 0 worse than the best fixed damper. The bracket (R_b − R_c) / (R_b − R_p) says how
#   much of the range above R_p is still uncertain (where between R_c and R_b the true optimum lies).
# - Over many episodes: the pooled share Σ(R − R_p) / Σ(R_c − R_p), the share of the gain achievable on all of
#   them together, each episode weighed by its range R_c − R_p (what is at stake on it), with a bootstrap 95 %
#   interval (episodes resampled within each scenario); the leaderboard ranks by it. The mean of the episodes'
#   shares weighs every episode alike, so an episode with a small range (the bump) can decide it.
# - Skyhook (Karnopp 1974): the damper aims at c_sky ż_s while ż_s·v_rel ≥ 0 (v_rel = ż_s − ż_u), and is as soft
#   as it can be otherwise (it can only dissipate).

# %%
import shutil

import gymnasium as gym
import numpy as np

import mrd_env  # noqa: F401  (registers the environments)
from controllers.protocol import DeclarationsOnly, declarations
from experiments.common.evaluation import evaluate_batch
from experiments.benchmark.ranking import leaderboard, read_result
from experiments.common.scenarios import Scenario
from experiments.benchmark.scoring import result_filename, score
from experiments.labs.labkit import Lab, in_notebook
from mrd_env.envs.sensors import newest_layout
from mrd_env.report import figure
from mrd_env.suites import suite

lab = Lab("lab7_benchmark")
bench = suite("car-comfort-v1")

# %% [markdown]
# ## Task 1 — Read the suite
# Print the suite's id, environment, control step, sensors and criteria, its scenarios with their seeds, and for
# every episode the stored references R_p (with its command), R_c and R_b (`bench.reference(label)`). How wide is
# the gap R_c − R_p a controller can capture, and how much room is left above R_c up to R_b (the bracket)?

# %%
print(f"{bench.id}: {bench.description}")
print(f"environment {bench.env_id}, control step {1e3 * bench.control_dt:g} ms, sensors {bench.options['sensors']}")
print("criteria:", ", ".join(bench.criteria))
for sc in bench.scenarios:
    print(f"  {sc.name:14s} {sc.options['road']:8s} {sc.options['road_params']}, {sc.options['episode_seconds']} s, "
          f"{len(sc.seeds)} seed(s) from {sc.seeds[0]}")
labels = bench.labels()
refs = {label: bench.reference(label) for label in labels}
print(f"\n{'episode':24s} {'R_p':>7s} {'u_p V':>6s} {'R_c':>7s} {'R_b':>7s} {'R_c − R_p':>9s} {'bracket':>7s}")
for label, r in refs.items():
    print(f"{label:24s} {r.passive:7.3f} {r.passive_command:6.3f} {r.clairvoyant:7.3f} {r.bound:7.3f} "
          f"{r.clairvoyant - r.passive:9.3f} {(r.bound - r.clairvoyant) / (r.bound - r.passive):7.2f}")
print("how R_c was found:", bench.procedure["clairvoyant"][:110], "...")

# %% [markdown]
# ## Task 2 — A controller against the protocol
# The scorer builds your controller once per scenario from a read-only **view** of the suite's vector environment
# (`controllers.protocol.declarations`): its declarations (sensors, roles, command range, control step, the plant's
# linear model, ...), never its state. Look at that view once — and see it refuse `reset`. Then write `MySkyhook`:
# find the body velocity ż_s and the travel rate v_rel by their **roles** (`env.roles`, `newest_layout(env)`), and
# command u = u_min + (u_max − u_min)·min(|ż_s| / v_sat, 1) while ż_s·v_rel ≥ 0, u_min otherwise: a continuous
# skyhook that needs no damper model, full command once the body moves at v_sat (m/s). `predict` takes the batch
# of observations, one row per episode, and returns one command per row in the action space's bounds; `reset`
# is optional (called before a scenario's first step).

# %%
sc0 = bench.scenarios[0]
venv = gym.make_vec(bench.env_id, num_envs=2, vectorization_mode="vector_entry_point",
                    **bench.episode_options(sc0, sc0.seeds[0]), control_dt=bench.control_dt)
view = declarations(venv)
print("roles:", view.roles)
print("command:", view.command_spec.unit, view.command_spec.v_min, "to", view.command_spec.v_max,
      "| action mode:", view.action_mode, "| control step:", view.control_dt, "s")
try:
    view.reset()
except DeclarationsOnly as exc:
    print("refused:", str(exc).split(":")[0])
venv.close()


class MySkyhook:
    """Continuous skyhook from the environment's declared roles: full command once |ż_s| reaches ``v_sat``."""

    def __init__(self, env, v_sat: float = 0.5):
        where = newest_layout(env)  # sensor name -> its slice of an observation
        self.body = where[env.roles["body_velocity"]]
        self.rate = where[env.roles["damper_velocity"]]
        self.low, self.high = env.single_action_space.low, env.single_action_space.high
        self.v_sat = float(v_sat)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        zs, v_rel = observation[:, self.body], observation[:, self.rate]  # (N episodes, n_dampers)
        level = np.clip(np.abs(zs) / self.v_sat, 0.0, 1.0)
        return np.where(zs * v_rel >= 0.0, self.low + level * (self.high - self.low), self.low), state

    def reset(self, mask=None):
        """Optional in the protocol (called before a scenario's first step): a memoryless law forgets nothing."""


# %% [markdown]
# ## Task 3 — Tune on roads that are not the suite's
# Choose v_sat by the mean return on the suite's ISO-C and ISO-D roads with *other* seeds (0–5: the suite's start
# at 1 000 000), driving `MySkyhook` through the same view. Tuning on the suite's own episodes would make its score
# optimistic: the suite is a test set.

# %%
tuning_roads = [Scenario(f"{sc.name} (tuning)", bench.env_id, {**bench.options, **sc.options}, tuple(range(6)))
                for sc in bench.scenarios if sc.options["road"] == "iso8608"
                and sc.options["road_params"]["road_class"] in ("C", "D")]
tuning = {}
for v_sat in (0.25, 0.5, 1.0, 2.0):
    returns = [e.episode_return for road in tuning_roads
               for e in evaluate_batch(lambda venv, v=v_sat: MySkyhook(declarations(venv), v), road, "",
                                       control_dt=bench.control_dt)]
    tuning[v_sat] = float(np.mean(returns))
    print(f"v_sat {v_sat:4.2f} m/s: mean return {tuning[v_sat]:.3f} on {len(returns)} tuning episodes")
V_SAT = max(tuning, key=tuning.get)
print(f"chosen v_sat = {V_SAT} m/s")

# %% [markdown]
# ## Task 4 — Score it, and two of the project's laws
# Score `MySkyhook` (at the chosen v_sat) on the whole suite with `score(bench, ..., name="my_skyhook",
# backend="serial")`, then `skyhook_continuous` and `passive_off` (a registered law is named by its name). Print
# your result's table. Then make a smoke run, `episodes=2` (the first two seeds of each scenario): its result says
# it is partial.

# %%
mine = score(bench, lambda env: MySkyhook(env, V_SAT), name="my_skyhook", backend="serial")
laws = {name: score(bench, name, backend="serial") for name in ("skyhook_continuous", "passive_off")}
smoke = score(bench, lambda env: MySkyhook(env, V_SAT), name="my_skyhook (smoke run)", episodes=2,
              backend="serial")
results = {"my_skyhook": mine, **laws}
print(mine.markdown())
for name, r in {**results, "smoke": smoke}.items():
    print(f"{name:20s} complete: {r.complete}, {len(r.episodes)} episodes, pooled share "
          f"{r.pooled_shares()['all scenarios'][0]:.3f}, mean share {r.shares()['all scenarios'][0]:.3f}")

# %% [markdown]
# ## Task 5 — Result files and the leaderboard
# Write each result (`result.write(path)`, named by `result_filename(suite id, controller)`), merge the four files
# with `leaderboard(paths, out=...)` and print the table (`board.markdown()`). Which results are ranked, and where
# does the smoke run go? Below the table, the paired verdicts compare each row with the next and with the best law
# on the same episodes: which differences are resolved, and which are ties?

# %%
folder = lab.out / "score"
shutil.rmtree(folder, ignore_errors=True)  # a rerun starts from no result files
paths = [r.write(folder / result_filename(bench.id, r.name)) for r in (*results.values(), smoke)]
board = leaderboard(paths, out=lab.out / "leaderboard")
print(board.markdown())
lab.add(lab.out / "leaderboard" / "leaderboard.png")
if in_notebook():  # the leaderboard's figure under the cell, as lab.save shows the lab's own
    from IPython.display import Image, display

    display(Image(filename=str(lab.out / "leaderboard" / "leaderboard.png")))

# %% [markdown]
# ## Task 6 — Against the clairvoyant
# For each controller and scenario, print the mean share; then plot (a) every episode's references and returns and
# (b) the gain each controller captures, R − R_p, against the gain available, R_c − R_p: the share is the slope
# from the origin, the clairvoyant lies on the diagonal and the bound above it. The pooled share is the slope of the
# sum of those points; the mean share is the mean of their slopes, however close to the origin a point lies.

# %%
scenarios = [sc.name for sc in bench.scenarios]
print(f"{'controller':20s}" + "".join(f"{s:>15s}" for s in scenarios) + f"{'all':>8s}")
for name, r in results.items():
    sh = r.shares()
    print(f"{name:20s}" + "".join(f"{sh[s][0]:15.3f}" for s in scenarios) + f"{sh['all scenarios'][0]:8.3f}")

x = np.arange(len(labels))
fig, (ax_r, ax_g) = figure(1, 2, figsize=(13, 4.6))
rp, rc, rb = (np.array([getattr(refs[k], f) for k in labels]) for f in ("passive", "clairvoyant", "bound"))
ax_r.fill_between(x, rp, rc, color="0.85", label="R_p → R_c: the achievable gain")
ax_r.plot(x, rb, "k^", ms=4, label="R_b, active bound")
ax_r.plot(x, rc, "k-", lw=1, label="R_c, clairvoyant")
ax_r.plot(x, rp, "k--", lw=1, label="R_p, best constant command")
for i, (name, r) in enumerate(results.items()):
    ax_r.plot(x, [e["return"] for e in r.episodes], "o", ms=4, color=f"C{i}", label=name)
    gain = np.array([e["return"] for e in r.episodes]) - rp
    ax_g.plot(rc - rp, gain, "o", ms=4, color=f"C{i}",
              label=f"{name} (pooled share {r.pooled_shares()['all scenarios'][0]:.2f}, "
                    f"mean share {r.shares()['all scenarios'][0]:.2f})")
ax_g.plot(rc - rp, rb - rp, "k^", ms=4, label="R_b − R_p, active bound")
top = float(np.max(rc - rp)) * 1.05
ax_g.plot([0, top], [0, top], "k-", lw=1, label="share 1: the clairvoyant")
ax_g.axhline(0.0, color="k", ls="--", lw=1, label="share 0: the best constant command")
starts = [labels.index(sc.label(sc.seeds[0])) for sc in bench.scenarios]
ax_r.set_xticks(starts, scenarios, fontsize=8)
ax_r.set_xlabel("episode (grouped by scenario)")
ax_r.set_ylabel("episode return R (dimensionless)")
ax_r.set_ylim(min(rp.min(), *(min(e["return"] for e in r.episodes) for r in results.values())) - 0.2,
              rb.max() + 0.8)  # room above the bound for the legend
ax_r.legend(fontsize=7, ncol=3, loc="upper center")
ax_r.set_title(f"{bench.id}: references and returns per episode")
ax_g.set_ylim(-1.0, float(np.max(rb - rp)) * 1.05)
ax_g.set_xlabel("achievable gain R_c − R_p (dimensionless)")
ax_g.set_ylabel("captured gain R − R_p (dimensionless)")
ax_g.legend(fontsize=7, loc="upper left")
ax_g.set_title("share of the achievable gain = slope from the origin")
for ax in (ax_r, ax_g):
    ax.grid(alpha=0.3)
lab.save(fig, "gain_captured.png")

# %% [markdown]
# ## Questions
# 1. R_p is chosen per episode among 17 constant commands. Why is passive-off's share at most 0 on every episode,
#    and why is it not exactly 0 everywhere? On which scenario is the softest damper nearly the best fixed one?
# 2. Why can no controller's mean share exceed 1, while a single episode's could (look at how R_c is found)? What
#    does the clairvoyant know that `predict` never sees?
# 3. R_b ≥ R_c on every episode. What does the bracket (R_b − R_c)/(R_b − R_p) say about how good R_c is, and why
#    can R_b not be reached by a damper?
# 4. On the 5 cm bump both skyhook laws score far below 0. What is special about one bump compared with a random
#    road, and why would a law tuned on random roads do badly there?
# 5. You chose v_sat on tuning roads, not on the suite. What would change in your score, and in what it means, if
#    you had swept v_sat on the suite itself and kept the best?
# 6. Compare each controller's pooled share with its mean share. On which episode does the mean share lose most,
#    and how large is that episode's range against a road's? Why does the leaderboard rank by the pooled share?
# 7. Your law reads its signals by role. Which roles does it need, and on which other plants of the project
#    (docs/your-controller.md's roles table) would it run unchanged?

# %% [markdown]
# ## Instructor's check

# %%
ordered = [refs[k] for k in labels]
lab.check("every stored reference is ordered R_p ≤ R_c ≤ R_b (R_b where the suite stores it): the clairvoyant is "
          "never below a constant command, and the active bound never below the clairvoyant",
          all(r.passive <= r.clairvoyant and (not np.isfinite(r.bound) or r.clairvoyant <= r.bound) for r in ordered),
          f"{len(ordered)} episodes, {sum(np.isfinite(r.bound) for r in ordered)} with R_b; smallest R_c − R_p "
          f"{min(r.clairvoyant - r.passive for r in ordered):.3f}, smallest R_b − R_c "
          f"{min(r.bound - r.clairvoyant for r in ordered if np.isfinite(r.bound)):.3f}")
back = read_result(paths[0])
lab.check("your result file is complete and each episode's return equals R_p + share·(R_c − R_p) of its stored "
          "references (the share is consistent)",
          back.complete and len(back.episodes) == len(labels) and all(
              np.isclose(e["return"], refs[e["label"]].passive + e["share"] * (refs[e["label"]].clairvoyant
                                                                               - refs[e["label"]].passive),
                         rtol=0, atol=1e-9) for e in back.episodes),
          f"{len(back.episodes)} of {len(labels)} episodes")
mean_share = {name: r.shares()["all scenarios"][0] for name, r in results.items()}
lab.check("passive-off is one of the constant commands R_p is the best of: its share is ≤ 0 on every episode",
          all(e["share"] <= 1e-9 for e in laws["passive_off"].episodes),
          f"largest {max(e['share'] for e in laws['passive_off'].episodes):.2e}")
lab.check("skyhook_continuous captures more of the achievable gain than passive_off (mean share)",
          mean_share["skyhook_continuous"] > mean_share["passive_off"],
          f"{mean_share['skyhook_continuous']:.3f} vs {mean_share['passive_off']:.3f}")
lab.check("your law beats doing nothing: its mean share is above passive_off's",
          mean_share["my_skyhook"] > mean_share["passive_off"],
          f"{mean_share['my_skyhook']:.3f} vs {mean_share['passive_off']:.3f}")
lab.check("no controller's mean share exceeds 1 (the clairvoyant knows the whole road)",
          all(m <= 1.0 for m in mean_share.values()), ", ".join(f"{k} {m:.3f}" for k, m in mean_share.items()))
lab.check("no controller's return exceeds the active bound R_b on any episode",
          all(e["return"] <= refs[e["label"]].bound for r in results.values() for e in r.episodes
              if np.isfinite(refs[e["label"]].bound)))
pooled_share = {name: r.pooled_shares()["all scenarios"][0] for name, r in results.items()}
ranked = [row["controller"] for row in board.table]
lab.check("the leaderboard ranks the complete results in the order of their pooled shares, and shows the smoke run "
          "apart, unranked",
          ranked == sorted(pooled_share, key=pooled_share.get, reverse=True)
          and [row["controller"] for row in board.partial] == [smoke.name]
          and all(row["rank"] == "" for row in board.partial),
          " > ".join(ranked))
lab.finish()
