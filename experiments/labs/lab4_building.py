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
# # Lab 4 — Structural control: the three-storey building under El Centro
#
# The Notre Dame lab model (three floors of 98.3 kg, an MR damper between the ground and the first floor) is
# shaken by the 1940 El Centro N-S record replayed five times faster (the model is small; `time_scale = 0.2`).
# You design a linear-quadratic regulator and a Kalman filter with python-control, then use them the way Dyke,
# Spencer, Sain & Carlson (1996) did: the optimal controller asks for a force, and the clipped-optimal law
# switches the damper's command so that the MR damper produces it when it can.
#
# **Learning objectives.** After this lab you can
# 1. write the building's state-space model and find its modes;
# 2. design an LQR (`control.lqr`) and a Kalman filter (`control.lqe`) and read the closed-loop poles;
# 3. simulate the linear model with `control.forced_response` — the uncontrolled building and the ideal active
#    controller;
# 4. compare the clipped-optimal semi-active law with the passive dampers on the nonlinear plant using the
#    benchmark criteria J1–J6.
#
# **Equations (recap).**
# - M q̈ + C q̇ + K q = −S F − M 1 ẍ_g (q floor displacements relative to the ground; S = [1, 0, 0] puts the
#   damper force F at the first floor; F from the Spencer–Dyke prototype, review eq. (12)). State x = [q, q̇]:
#   ẋ = A x + B_f F + B_w ẍ_g.
# - LQR: minimise J = ∫ (zᵀ z + Fᵀ R F) dt with z = C_z x the weighted drifts; F = −K x, K = R⁻¹ B_fᵀ P from the
#   Riccati equation AᵀP + PA − P B_f R⁻¹ B_fᵀ P + C_zᵀC_z = 0.
# - Kalman filter (LQG): x̂̇ = A x̂ + B_f F + L (y − C_y x̂ − D_y F), L from the dual Riccati equation with the
#   ground motion as process noise.
# - Clipped-optimal law (Dyke et al. 1996): v = v_max·H((f_c − f)·f), f_c = −K x̂ the desired force, f the
#   measured damper force, H the Heaviside step.
# - Benchmark criteria (normalised by the uncontrolled building): J1 peak interstorey drift, J2 peak absolute
#   floor acceleration, J3 peak base shear; J4–J6 the same with r.m.s. values.

# %%
import control
import gymnasium as gym
import numpy as np

import mrd_env  # noqa: F401  (registers the environments)
from controllers import ClippedOptimal, LinearDesign, make_controller
from experiments.common.evaluation import evaluate_batch
from experiments.common.scenarios import held_out_scenarios
from experiments.labs.labkit import Lab
from mrd_env.disturbances import el_centro
from mrd_env.plants.shear_building.profile import PROFILE as SHEAR_BUILDING
from mrd_env.report import figure

lab = Lab("lab4_building")
scenario = held_out_scenarios(SHEAR_BUILDING, plant_options={})[0]  # El Centro N-S, ×0.2 time; damper in storey 1
env = gym.make(scenario.env_id, **scenario.options).unwrapped
design = LinearDesign(env)  # the linear model the environment declares
A, Bf, Bw = design.A, design.Bf, design.Bw
plant = env.linear_plant
print("sensors:", [s[0] for s in env.sensor_layout])

# %% [markdown]
# ## Task 1 — The model and its modes
# Compute the natural frequencies and damping ratios from the eigenvalues of A (`control.damp` or
# `numpy.linalg.eigvals`), and the undamped frequencies from K φ = ω² M φ.

# %%
wn, zeta, _ = control.damp(control.ss(A, Bf, np.eye(6), 0), doprint=False)
modes = sorted(set(np.round(wn / (2 * np.pi), 6)))
zeta_open = {round(w / (2 * np.pi), 6): z for w, z in zip(wn, zeta)}
omega2 = np.sort(np.linalg.eigvals(np.linalg.solve(plant.M, plant.K)).real)
f_undamped = np.sqrt(omega2) / (2 * np.pi)
for f_d, f_u in zip(modes, f_undamped):
    print(f"mode: {f_d:.2f} Hz (undamped {f_u:.2f} Hz), damping ratio {100 * zeta_open[f_d]:.2f} %")

# %% [markdown]
# ## Task 2 — LQR and Kalman filter with python-control
# Weight the three interstorey drifts by 1/(5 mm)² and the damper force by R = 1/(3 kN)². Compute K with
# `control.lqr` and the closed-loop poles. Then design a Kalman filter on the measured floor accelerations
# (`env.signal_matrices("abs_acc")`), with unit process noise on ẍ_g and 0.05² measurement noise.

# %%
drift = env.signal_matrices("drift")["C"]
q_drift = 1 / 0.005 ** 2
Q = q_drift * drift.T @ drift
R = np.array([[1 / 3000.0 ** 2]])
K, P, poles = control.lqr(A, Bf, Q, R)
wn_c, zeta_c, _ = control.damp(control.ss(A - Bf @ K, Bf, np.eye(6), 0), doprint=False)
print("LQR gain K =", np.array2string(np.asarray(K), precision=1))
print("closed-loop damping ratios:", ", ".join(f"{w / 2 / np.pi:.2f} Hz {100 * z:.1f} %"
                                               for w, z in sorted(zip(wn_c, zeta_c))[::2]))
# the same design with a 4× heavier drift weight (question 2)
K4, _, poles4 = control.lqr(A, Bf, 4 * Q, R)
wn_4, zeta_4, _ = control.damp(control.ss(A - Bf @ K4, Bf, np.eye(6), 0), doprint=False)
print(f"4× drift weight: |K| {np.linalg.norm(K4):.3g} against {np.linalg.norm(K):.3g}; closed-loop damping ratios:",
      ", ".join(f"{w / 2 / np.pi:.2f} Hz {100 * z:.1f} %" for w, z in sorted(zip(wn_4, zeta_4))[::2]))

acc = env.signal_matrices("abs_acc")
Cy, Dy = acc["C"], acc["D_F"]
L, P_est, est_poles = control.lqe(A, Bw, Cy, np.eye(1), 0.05 ** 2 * np.eye(3))
print("Kalman filter poles (1/s):", np.array2string(np.sort_complex(est_poles), precision=0))

fig, ax = figure(figsize=(6.5, 4.5))
for p, marker, label in ((np.linalg.eigvals(A), "x", "open loop (building)"), (poles, "o", "LQR closed loop"),
                         (est_poles, "s", "Kalman filter")):
    ax.plot(np.real(p), np.imag(p) / (2 * np.pi), marker, ms=8, mfc="none", label=label)
ax.set_xlabel("real part (1/s)")
ax.set_ylabel("imaginary part / 2π (Hz)")
ax.axvline(0, color="k", lw=0.8)
ax.grid(alpha=0.3)
ax.legend(fontsize=8)
ax.set_title("poles of the building, the LQR loop and the Kalman filter")
lab.save(fig, "poles.png")

# %% [markdown]
# ## Task 3 — The linear building: uncontrolled and ideal active control
# Simulate the linear model under the El Centro record (`el_centro("NS", time_scale=0.2)`) with
# `control.forced_response`: without the damper (F = 0), and with an ideal actuator producing F = −K x. Plot the
# first-storey drift of both.

# %%
quake = el_centro("NS", time_scale=0.2)
t = quake.t
xg = np.asarray(quake.data)[:, 0]
uncontrolled = control.forced_response(control.ss(A, Bw, drift, 0), T=t, U=xg)
active = control.forced_response(control.ss(A - Bf @ K, Bw, np.vstack([drift, -np.asarray(K)]), 0), T=t, U=xg)
peak_unc = np.abs(uncontrolled.outputs).max()
peak_act = np.abs(active.outputs[:3]).max()
print(f"peak drift: uncontrolled {1e3 * peak_unc:.2f} mm, ideal active LQR {1e3 * peak_act:.2f} mm "
      f"(peak force {np.abs(active.outputs[3]).max():.0f} N)")
active4 = control.forced_response(control.ss(A - Bf @ K4, Bw, np.vstack([drift, -np.asarray(K4)]), 0), T=t, U=xg)
print(f"  with the 4× drift weight: {1e3 * np.abs(active4.outputs[:3]).max():.2f} mm "
      f"(peak force {np.abs(active4.outputs[3]).max():.0f} N)")

# %% [markdown]
# ## Task 4 — Semi-active: clipped-optimal against the passive dampers
# On the nonlinear plant (the environment: Spencer–Dyke damper, 1 ms steps) run passive-off, passive-on, the
# project's clipped-optimal law (`ClippedOptimal(env, weights=..., force_ref=...)` uses the same LQR and a Kalman
# filter on every usable sensor) and a clipped-optimal law with a heavier drift weight. Compare J1–J6.

# %%
controllers = {
    "passive_off": lambda venv: make_controller("passive_off", venv),
    "passive_on": lambda venv: make_controller("passive_on", venv),
    "clipped-optimal": lambda venv: ClippedOptimal(venv, weights={"drift": q_drift}, force_ref=3000.0),
    "clipped-optimal, 4× drift weight": lambda venv: ClippedOptimal(venv, weights={"drift": 4 * q_drift},
                                                                   force_ref=3000.0),
}
episodes = {name: evaluate_batch(make, scenario, "drift", name=name)[0] for name, make in controllers.items()}
J = {name: {f"J{i}": e.metrics[f"J{i}"] for i in range(1, 7)} for name, e in episodes.items()}
print(f"{'controller':34s} " + " ".join(f"{k:>6s}" for k in J["passive_off"]) + "  peak force N")
for name, js in J.items():
    print(f"{name:34s} " + " ".join(f"{v:6.3f}" for v in js.values())
          + f"  {episodes[name].metrics['damper_force_peak']:8.0f}")

fig, (ax_j, ax_d) = figure(1, 2, figsize=(12, 4.2), gridspec_kw={"width_ratios": [1, 1.3]})
width = 0.8 / len(J)
for i, (name, js) in enumerate(J.items()):
    ax_j.bar(np.arange(6) + (i - (len(J) - 1) / 2) * width, list(js.values()), width, label=name)
ax_j.axhline(1.0, color="k", lw=0.8)
ax_j.set_xticks(np.arange(6), list(J["passive_off"]))
ax_j.set_ylabel("criterion (uncontrolled = 1)")
ax_j.legend(fontsize=7)
ax_j.grid(alpha=0.3, axis="y")
ax_j.set_title("benchmark criteria, El Centro N-S (×0.2 time)")
ax_d.plot(t, 1e3 * uncontrolled.outputs[0], color="0.6", lw=0.8, label="uncontrolled (linear)")
ax_d.plot(t, 1e3 * active.outputs[0], "k", lw=0.8, label="ideal active LQR (linear)")
for name in ("passive_off", "clipped-optimal"):
    e = episodes[name]
    ax_d.plot(e.t, 1e3 * e.response, lw=0.8, label=name)
ax_d.set_xlim(0, 4)
ax_d.set_xlabel("time t (s)")
ax_d.set_ylabel("first-storey drift (mm)")
ax_d.legend(fontsize=7)
ax_d.grid(alpha=0.3)
lab.save(fig, "j_criteria.png")

# %% [markdown]
# ## Questions
# 1. Which mode dominates the drift response to El Centro at ×0.2 time, and why does the time scaling matter?
# 2. What does a 4× heavier drift weight do to K, to the closed-loop poles and to the peak force the ideal active
#    LQR asks for (Tasks 2 and 3)? And to the semi-active clipped-optimal law of Task 4: why can a design that
#    asks for more force do worse when the damper can only dissipate?
# 3. The clipped-optimal law can only switch the command. When can the MR damper not produce f_c? (Compare the
#    sign condition (f_c − f)·f > 0 with the passivity of the damper.)
# 4. Passive-on also cuts the drift a lot. What does clipped-optimal buy over it (look at J2 and J5)?
# 5. How far is the semi-active result from the ideal active LQR, and what limits it?

# %% [markdown]
# ## Instructor's check

# %%
lab.check("the damped modal frequencies of A match the undamped ones from K φ = ω² M φ (light damping, within 1 %)",
          np.allclose(modes, f_undamped, rtol=0.01), ", ".join(f"{f:.2f}" for f in modes) + " Hz")
lab.check("the LQR closed loop is stable and damps the first mode more than the open loop",
          np.all(np.real(poles) < 0) and sorted(zip(wn_c, zeta_c))[0][1] > zeta_open[modes[0]],
          f"first mode ζ {100 * zeta_open[modes[0]]:.2f} % → {100 * sorted(zip(wn_c, zeta_c))[0][1]:.2f} %")
lab.check("the Kalman filter is stable (all its poles in the left half-plane)", np.all(np.real(est_poles) < 0))
implied = episodes["passive_off"].metrics["drift_peak"] / J["passive_off"]["J1"]
lab.check("python-control's uncontrolled peak drift = the environment's uncontrolled reference (within 1 %)",
          abs(peak_unc / implied - 1) < 0.01, f"{1e3 * peak_unc:.3f} vs {1e3 * implied:.3f} mm")
lab.check("the ideal active LQR cuts the linear peak drift", peak_act < 0.5 * peak_unc,
          f"{1e3 * peak_act:.2f} vs {1e3 * peak_unc:.2f} mm")
lab.check("every damper beats the uncontrolled building on every criterion (all J < 1)",
          all(v < 1 for js in J.values() for v in js.values()))
lab.check("passive-on lowers the peak drift J1 below passive-off", J["passive_on"]["J1"] < J["passive_off"]["J1"])
lab.check("clipped-optimal has a lower J1 than passive-off", J["clipped-optimal"]["J1"] < J["passive_off"]["J1"],
          f"{J['clipped-optimal']['J1']:.3f} vs {J['passive_off']['J1']:.3f}")
lab.check("clipped-optimal reaches a lower peak acceleration J2 than passive-on (the lab ranking of Dyke 1996)",
          J["clipped-optimal"]["J2"] < J["passive_on"]["J2"],
          f"{J['clipped-optimal']['J2']:.3f} vs {J['passive_on']['J2']:.3f}")
lab.finish()
