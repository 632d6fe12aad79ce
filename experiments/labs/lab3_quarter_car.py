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
# # Lab 3 — Quarter car: comfort against road holding
#
# A car's suspension trades ride comfort (how much the body shakes the passengers) against road holding (how
# much the tyre load varies) and rattle space (how far the suspension travels). A passive damper picks one point
# of that trade-off; a semi-active MR damper changes its damping every millisecond and can leave the passive
# curve. Here the plant is the quarter car `set_a` (sprung 320 kg, unsprung 40 kg) with the automotive
# Spencer–Dyke damper (0–2 V), on ISO 8608 random roads at 20 m/s (`mrd_env/QuarterCarPhysical-v0`).
#
# **Learning objectives.** After this lab you can
# 1. score a suspension with the ISO 2631-1 frequency-weighted acceleration (Wk), the suspension travel and the
#    dynamic tyre load;
# 2. draw the passive trade-off curve by sweeping a constant command (soft → hard);
# 3. implement a control law behind the project's controller interface and compare skyhook, groundhook and
#    hybrid control with the passive dampers;
# 4. explain with the Wk weighting why a hard damper is harsh at highway speed.
#
# **Equations (recap).**
# - Quarter car: m_s z̈_s = −k_s (z_s − z_u) − F, m_u z̈_u = k_s (z_s − z_u) + F − k_t (z_u − z_r), with F the
#   damper force across the stroke x = z_s − z_u (Spencer–Dyke, review eq. (12)).
# - Road: ISO 8608 displacement PSD G_d(n) = G_d(n₀)(n/n₀)⁻², n₀ = 0.1 cycle/m; class C G_d(n₀) = 256·10⁻⁶ m³.
# - Comfort: a_w = Wk-weighted sprung acceleration (ISO 2631-1, W = H_h·H_l·H_t·H_s, most weight at 4–8 Hz);
#   the index is its r.m.s. value. Road holding: r.m.s. dynamic tyre load k_t (z_u − z_r) over the static load.
# - Laws (v_rel = ż_s − ż_u): skyhook on–off u = u_max if ż_s·v_rel ≥ 0 (Karnopp 1974), continuous skyhook
#   u ∝ c_sky |ż_s| under the same condition; groundhook u = u_max if −ż_u·v_rel ≥ 0; hybrid (Goncalves &
#   Ahmadian 2003) aims at G[α σ_sky + (1 − α) σ_gnd], σ_sky = ż_s where ż_s·v_rel ≥ 0, σ_gnd = −ż_u where
#   −ż_u·v_rel ≥ 0 (each term gated on its own: one switch on (α ż_s − (1 − α) ż_u)·v_rel would be on almost
#   always, since that product is α ż_s² − ż_s ż_u + (1 − α) ż_u²).

# %%
import gymnasium as gym
import numpy as np
from scipy.signal import welch

import mrd_env  # noqa: F401  (registers the environments)
from controllers import Controller, make_controller
from experiments.common.evaluation import evaluate_batch
from experiments.common.scenarios import held_out_scenarios
from experiments.labs.labkit import Lab
from mrd_env.metrics import weighting_magnitude
from mrd_env.plants.quarter_car.profile import PROFILE as QUARTER_CAR
from mrd_env.report import figure

lab = Lab("lab3_quarter_car")
roads = held_out_scenarios(QUARTER_CAR)[:2]  # ISO class C and D at 20 m/s, 10 s, three seeds each
env = gym.make(roads[0].env_id, **roads[0].options)
print("sensors:", [s[0] for s in env.unwrapped.sensor_layout])
print("command range:", env.unwrapped.command_spec)

# %% [markdown]
# ## Task 1 — A law of your own: the constant command
# Write a controller that holds a constant command v (a passive damper of adjustable hardness). Subclass
# `controllers.Controller` and implement `command(obs)`, which returns one command per row of the batch of
# observations.

# %%
class ConstantCommand(Controller):
    """A passive MR damper: the command held at ``level`` (V)."""

    name = "constant"

    def __init__(self, env, level: float):
        super().__init__(env)
        self.level = float(level)
        self.name = f"passive {level:g} V"

    def command(self, obs):
        return np.full((obs.shape[0], 1), self.level)


def mean_metrics(episodes):
    """The metrics of a scenario's episodes, averaged over its seeds."""
    return {k: float(np.mean([e.metrics[k] for e in episodes])) for k in
            ("acc_weighted_rms", "acc_rms", "travel_rms", "travel_peak", "tyre_load_rms", "tyre_load_ratio")}


# %% [markdown]
# ## Task 2 — The passive trade-off curve
# Sweep the constant command over 0, 0.5, 1, 1.5 and 2 V on the class-C road and record the Wk-weighted r.m.s.
# acceleration, the r.m.s. travel and the r.m.s. dynamic tyre load (`episode.metrics`).

# %%
levels = [0.0, 0.5, 1.0, 1.5, 2.0]
passive = {v: mean_metrics(evaluate_batch(lambda venv, v=v: ConstantCommand(venv, v), roads[0], "sprung_acc"))
           for v in levels}
for v, m in passive.items():
    print(f"{v:.1f} V: a_w {m['acc_weighted_rms']:.3f} m/s², travel {1e3 * m['travel_rms']:.1f} mm, "
          f"tyre load {m['tyre_load_rms']:.0f} N")

# %% [markdown]
# ## Task 3 — Semi-active laws
# Run skyhook (on–off and continuous), groundhook and hybrid (α = 0.6) on both roads, next to passive-off and
# passive-on. `make_controller(name, env)` builds a law of the project by name.

# %%
laws = ["passive_off", "passive_on", "skyhook_on_off", "skyhook_continuous", "groundhook", "hybrid"]
results, histories = {}, {}
for sc in roads:
    for law in laws:
        episodes = evaluate_batch(lambda venv, law=law: make_controller(law, venv), sc, "sprung_acc")
        results[sc.name, law] = mean_metrics(episodes)
        histories[sc.name, law] = episodes[0]
print(f"{'road':12s} {'law':20s} {'a_w m/s²':>9s} {'travel mm':>9s} {'tyre N':>8s}")
for (road, law), m in results.items():
    print(f"{road:12s} {law:20s} {m['acc_weighted_rms']:9.3f} {1e3 * m['travel_rms']:9.2f} {m['tyre_load_rms']:8.0f}")

# %% [markdown]
# ## Task 4 — The trade-off as plots
# Plot comfort (Wk r.m.s.) against road holding (r.m.s. tyre load) and against r.m.s. travel: the passive sweep
# as a curve, the laws as points.

# %%
fig, (ax_t, ax_x) = figure(1, 2, figsize=(11, 4.4))
c = roads[0].name
for ax, key, scale, label in ((ax_t, "tyre_load_rms", 1.0, "r.m.s. dynamic tyre load (N)"),
                              (ax_x, "travel_rms", 1e3, "r.m.s. suspension travel (mm)")):
    ax.plot([passive[v]["acc_weighted_rms"] for v in levels], [scale * passive[v][key] for v in levels], "k.-",
            label="passive, 0 → 2 V")
    for v in (levels[0], levels[-1]):
        ax.annotate(f"{v:g} V", (passive[v]["acc_weighted_rms"], scale * passive[v][key]), fontsize=8,
                    textcoords="offset points", xytext=(4, 4))
    for i, law in enumerate(laws[2:]):
        m = results[c, law]
        ax.plot(m["acc_weighted_rms"], scale * m[key], "o", color=f"C{i}", ms=8, label=law)
    ax.set_xlabel("Wk-weighted r.m.s. sprung acceleration (m/s²)  → less comfort")
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)
ax_t.legend(fontsize=8)
fig.suptitle(f"quarter car on {c}: comfort vs road holding and rattle space (mean of 3 roads)")
lab.save(fig, "tradeoff.png")

# %% [markdown]
# ## Task 5 — Why hard is harsh: the spectrum and the Wk weighting
# Compute the PSD of the sprung acceleration (Welch) for passive-off, passive-on and continuous skyhook on the
# class-C road and draw |Wk(f)| on top. Where does the hard damper add acceleration, and how much weight does
# Wk give that band?

# %%
fig, ax = figure(figsize=(8, 4.2))
for law in ("passive_off", "passive_on", "skyhook_continuous"):
    e = histories[c, law]
    f, psd = welch(e.response, fs=1.0 / np.median(np.diff(e.t)), nperseg=4096)
    ax.loglog(f[1:], psd[1:], label=law)
ax.set_xlim(0.5, 50)
ax.set_ylim(1e-4, None)
ax.set_xlabel("frequency (Hz)")
ax.set_ylabel("PSD of z̈_s ((m/s²)²/Hz)")
ax.grid(alpha=0.3, which="both")
ax.legend(loc="lower left", fontsize=8)
ax_w = ax.twinx()
fw = np.logspace(np.log10(0.5), np.log10(50), 200)
ax_w.semilogx(fw, weighting_magnitude("Wk", fw), "k--", lw=1)
ax_w.set_ylabel("|Wk(f)| (dashed)")
ax.set_title(f"sprung acceleration spectrum, {c}")
lab.save(fig, "spectrum_wk.png")

# %% [markdown]
# ## Questions
# 1. Along the passive curve, what does a harder damper buy and what does it cost? Is there a command that is
#    best for all three indices?
# 2. Skyhook "connects" the body to an inertial reference. Why can a semi-active damper only approximate it, and
#    when (sign of ż_s·v_rel) must it switch off?
# 3. On-off skyhook is worse for comfort than continuous skyhook here. Look at Lab 1's loops at 2 V: what does
#    switching to the on state do to the force at small velocities?
# 4. Groundhook aims at the wheel. Which index should it improve and does it, relative to passive-on?
# 5. Where are the body (≈ 1.3 Hz) and wheel-hop (≈ 11 Hz) modes in the spectrum? Which one does Wk weigh more?
# 6. Compare continuous skyhook with passive-off (not passive-on) on the Wk index, the travel and the tyre load.
#    Does any law beat the softest damper on comfort here? What does skyhook buy, and at what price?

# %% [markdown]
# ## Instructor's check

# %%
travel = [passive[v]["travel_rms"] for v in levels]
lab.check("a harder passive damper (higher constant command) always lowers the r.m.s. travel",
          np.all(np.diff(travel) < 0), ", ".join(f"{1e3 * t:.1f}" for t in travel) + " mm")
for sc in roads:
    r = {law: results[sc.name, law] for law in laws}
    lab.check(f"{sc.name}: passive-on is harsher than passive-off (Wk r.m.s.)",
              r["passive_on"]["acc_weighted_rms"] > r["passive_off"]["acc_weighted_rms"])
    for law in ("skyhook_on_off", "skyhook_continuous"):
        lab.check(f"{sc.name}: {law} lowers the Wk comfort index relative to passive-on",
                  r[law]["acc_weighted_rms"] < r["passive_on"]["acc_weighted_rms"],
                  f"{r[law]['acc_weighted_rms']:.3f} vs {r['passive_on']['acc_weighted_rms']:.3f} m/s²")
    lab.check(f"{sc.name}: groundhook lowers the dynamic tyre load relative to passive-on",
              r["groundhook"]["tyre_load_rms"] < r["passive_on"]["tyre_load_rms"],
              f"{r['groundhook']['tyre_load_rms']:.0f} vs {r['passive_on']['tyre_load_rms']:.0f} N")
    # (question 6: on these roads no law is more comfortable than passive-off; skyhook's gain is in travel and
    # tyre load at about passive-off's comfort, which the benchmark's return weighs)
    lab.check(f"{sc.name}: continuous skyhook is within 10 % of passive-off's Wk comfort index",
              r["skyhook_continuous"]["acc_weighted_rms"] < 1.1 * r["passive_off"]["acc_weighted_rms"],
              f"{r['skyhook_continuous']['acc_weighted_rms']:.3f} vs {r['passive_off']['acc_weighted_rms']:.3f} m/s²")
    lab.check(f"{sc.name}: continuous skyhook holds the road better than passive-off (lower tyre load) and "
              "uses less travel",
              r["skyhook_continuous"]["tyre_load_rms"] < r["passive_off"]["tyre_load_rms"]
              and r["skyhook_continuous"]["travel_rms"] < r["passive_off"]["travel_rms"])
e = histories[c, "passive_on"]
f, psd_on = welch(e.response, fs=1.0 / np.median(np.diff(e.t)), nperseg=4096)
_, psd_off = welch(histories[c, "passive_off"].response, fs=1.0 / np.median(np.diff(e.t)), nperseg=4096)
band = (f >= 4) & (f <= 8)
lab.check("the hard damper adds acceleration in the 4–8 Hz band where |Wk| ≈ 1",
          psd_on[band].sum() > psd_off[band].sum() and np.all(weighting_magnitude("Wk", f[band]) > 0.9),
          f"band power ratio on/off {psd_on[band].sum() / psd_off[band].sum():.2f}")
lab.finish()
