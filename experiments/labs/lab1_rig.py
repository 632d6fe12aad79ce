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
# # Lab 1 — The MR damper on the test rig
#
# A sinusoidal tester drives the damper's stroke x(t) = X sin(2π f t) at a constant command and records the
# force (the review's section 4). Here the tester is the project's virtual rig (`mrd_env.rig`) and the damper is
# the Spencer–Dyke model of the prototype damper of Spencer, Dyke, Sain & Carlson (1997), preset `spencer1997`.
#
# **Learning objectives.** After this lab you can
# 1. read force–displacement and force–velocity loops and say what the command and the frequency do to them
#    (the review's Figures 2 and 5: yield force, post-yield slope, pre-yield hysteresis), and read the Figure 5
#    parameters from a loop;
# 2. compute the energy dissipated per cycle, ∮ F dx, and relate it to an equivalent viscous damping;
# 3. check a simulation against a closed form (the Bingham model's energy per cycle) and published values;
# 4. measure the command lag — how long the damper takes to follow a step of its command.
#
# **Equations (recap; numbers are the review's).**
# - Bingham, eq. (2): F = f_c sgn(ẋ) + c₀ ẋ + f₀, with f_c and c₀ growing with the command u.
# - Bouc–Wen, eqs. (7)–(8): F = c₀ ẋ + k₀ x + α z, ż = −γ |ẋ| z |z|ⁿ⁻¹ − β ẋ |z|ⁿ + A ẋ.
# - Spencer–Dyke, eq. (12): a Bouc–Wen element with a dashpot c₁ in series (the roll-off at low velocity) and an
#   accumulator spring k₁; α, c₀, c₁ linear in u.
# - Command dynamics (driver and coil): u̇ = −η (u − v(t − τ)), v the command sent, τ an optional pure delay;
#   after a step of v, u covers 1 − e⁻¹ ≈ 63 % of the step in 1/η.
# - Energy per cycle: E = ∮ F dx = ∫ F ẋ dt over one period. For the Bingham model (sgn exact) and
#   x = X sin ωt: E = 4 f_c X + π c₀ ω X² — the friction part is a rectangle, the viscous part an ellipse.
#   An equivalent viscous damper dissipating the same energy has c_eq = E / (π ω X²).

# %%
import numpy as np

from experiments.labs.labkit import Lab
from mrd_env import make_damper
from mrd_env.report import figure
from mrd_env.rig import simulate, sinusoidal_test

lab = Lab("lab1_rig")
damper = make_damper("spencer_dyke", preset="spencer1997")
print(damper.params)
print(damper.command)

# %% [markdown]
# ## Task 1 — Loops against the command
# Run the rig at X = 1.5 cm, f = 2.5 Hz for the commands 0, 0.75, 1.5 and 2.25 V (three cycles; use the last one,
# when the loop has settled). Plot force against displacement and against velocity.
#
# *Hint:* `sinusoidal_test(damper, amplitude, frequency, commands, cycles=...)` returns one `DamperRecord` per
# command; `r.steady_cycles(f)` is the index slice of the last cycle.

# %%
X, f0 = 0.015, 2.5  # m, Hz
commands = [0.0, 0.75, 1.5, 2.25]  # V
by_command = sinusoidal_test(damper, amplitude=X, frequency=f0, commands=commands, cycles=3)
last = by_command[0].steady_cycles(f0)


def label_loops(ax_x, ax_v, legend_title):
    """Axis labels, grid and legend of a pair of loop plots (force–displacement, force–velocity)."""
    ax_x.set_xlabel("displacement x (mm)")
    ax_v.set_xlabel("velocity ẋ (m/s)")
    for ax in (ax_x, ax_v):
        ax.set_ylabel("force F (N)")
        ax.grid(alpha=0.3)
    ax_v.legend(title=legend_title)


fig, (ax_x, ax_v) = figure(1, 2, figsize=(10, 4))
for r in by_command:
    ax_x.plot(r.x[last] * 1e3, r.force[last], label=r.label)
    ax_v.plot(r.v[last], r.force[last], label=r.label)
label_loops(ax_x, ax_v, "command")
fig.suptitle(f"Spencer–Dyke prototype damper, X = {X * 1e3:g} mm, f = {f0:g} Hz: loops against the command")
lab.save(fig, "loops_command.png")

# %% [markdown]
# ## Task 1b — The parameters of the review's Figure 5, read from the loops
# Figure 5 of the review describes a force–velocity loop by a yield force F_yield, a post-yield damping c_ps,
# a pre-yield damping c_pre and a zero-force velocity v₀. Fit a straight line to the loop where |ẋ| > 0.6 ẋ_max:
# its slope is c_ps and its intercept F_yield (measure the force from the preload −k₁x₀). Compare with the large-
# velocity limit of eq. (12): there z saturates at z_s = (A/(β + γ))^(1/n) and the k₀ spring is negligible, so
# F + k₁x₀ ≈ c₁(α z_s + c₀ ẋ)/(c₀ + c₁): c_ps = c₀c₁/(c₀ + c₁), F_yield = α z_s c₁/(c₀ + c₁).

# %%
p = damper.params
z_s = (p.A / (p.beta + p.gamma)) ** (1 / p.n)
preload = -p.k1 * p.x0  # N
figure5 = {}  # command -> (c_ps, F_yield) read from the loop, and the large-velocity limit of eq. (12)
fig, ax = figure(figsize=(7, 4.2))
for r, v in zip(by_command, commands):
    vel, F = r.v[last], r.force[last] - preload
    fast = vel > 0.6 * vel.max()
    c_ps, F_yield = np.polyfit(vel[fast], F[fast], 1)
    c0, c1, alpha = p.c0a + p.c0b * v, p.c1a + p.c1b * v, p.alpha_a + p.alpha_b * v
    figure5[v] = {"c_ps": c_ps, "F_yield": F_yield, "c_ps eq. (12)": c0 * c1 / (c0 + c1),
                  "F_yield eq. (12)": alpha * z_s * c1 / (c0 + c1)}
    line = ax.plot(vel, F, lw=1, label=f"{v:g} V")[0]
    ax.plot([0, vel.max()], [F_yield, F_yield + c_ps * vel.max()], "--", color=line.get_color(), lw=1)
    print(f"{v:g} V: c_ps {c_ps:.0f} N·s/m (eq. 12 limit {figure5[v]['c_ps eq. (12)']:.0f}), "
          f"F_yield {F_yield:.0f} N (limit {figure5[v]['F_yield eq. (12)']:.0f})")
ax.axhline(0, color="k", lw=0.6)
ax.axvline(0, color="k", lw=0.6)
ax.set_xlabel("velocity ẋ (m/s)")
ax.set_ylabel("force above the preload F + k₁x₀ (N)")
ax.grid(alpha=0.3)
ax.legend(title="command", fontsize=8)
ax.set_title("post-yield lines (dashed): slope c_ps, intercept F_yield")
lab.save(fig, "figure5_parameters.png")

# %% [markdown]
# ## Task 2 — Loops against the frequency
# Keep X = 1.5 cm and the command at 1 V; run 1, 2.5 and 5 Hz. Which loop changes more with frequency, the
# force–displacement or the force–velocity one? Why?

# %%
frequencies = [1.0, 2.5, 5.0]  # Hz
by_frequency = [sinusoidal_test(damper, amplitude=X, frequency=f, commands=[1.0], cycles=3)[0] for f in frequencies]

fig, (ax_x, ax_v) = figure(1, 2, figsize=(10, 4))
for f, r in zip(frequencies, by_frequency):
    sl = r.steady_cycles(f)
    ax_x.plot(r.x[sl] * 1e3, r.force[sl], label=f"{f:g} Hz")
    ax_v.plot(r.v[sl], r.force[sl], label=f"{f:g} Hz")
label_loops(ax_x, ax_v, "frequency")
fig.suptitle("loops against the frequency at 1 V")
lab.save(fig, "loops_frequency.png")

# %% [markdown]
# ## Task 3 — Energy per cycle
# Compute E = ∫ F ẋ dt over the last cycle for every command at 1, 2.5 and 5 Hz (`r.dissipated_energy(sl)`),
# and the equivalent viscous damping c_eq = E / (π ω X²). Then check the simulation against the closed form:
# run the Bingham model (`make_damper("bingham", v_s=1e-4)`, nearly the exact sign) and compare its energy per
# cycle with 4 f_c X + π c₀ ω X².

# %%
energy = {}  # (frequency, command) -> J per cycle
for f in frequencies:
    for r, v in zip(sinusoidal_test(damper, amplitude=X, frequency=f, commands=commands, cycles=3), commands):
        energy[f, v] = r.dissipated_energy(r.steady_cycles(f))
c_eq = {k: e / (np.pi * (2 * np.pi * k[0]) * X ** 2) for k, e in energy.items()}

fig, (ax_e, ax_c) = figure(1, 2, figsize=(10, 3.8))
for f in frequencies:
    ax_e.plot(commands, [energy[f, v] for v in commands], "o-", label=f"{f:g} Hz")
    ax_c.plot(commands, [c_eq[f, v] / 1e3 for v in commands], "o-", label=f"{f:g} Hz")
ax_e.set_ylabel("energy per cycle E (J)")
ax_c.set_ylabel("equivalent damping c_eq (kN·s/m)")
for ax in (ax_e, ax_c):
    ax.set_xlabel("command v (V)")
    ax.grid(alpha=0.3)
    ax.legend()
fig.suptitle(f"energy dissipated per cycle, X = {X * 1e3:g} mm")
lab.save(fig, "energy_per_cycle.png")
for f in frequencies:
    print(f"{f:g} Hz: " + ", ".join(f"{v:g} V → {energy[f, v]:.2f} J" for v in commands))

bingham = make_damper("bingham", v_s=1e-4)
p = bingham.params
bingham_error = []
for v in commands:
    r = sinusoidal_test(bingham, amplitude=X, frequency=f0, commands=[v], cycles=2, dt=1e-4)[0]
    e_sim = r.dissipated_energy(r.steady_cycles(f0))
    e_closed = 4 * (p.fc_a + p.fc_b * v) * X + np.pi * (p.c0a + p.c0b * v) * (2 * np.pi * f0) * X ** 2
    bingham_error.append(abs(e_sim / e_closed - 1))
    print(f"Bingham {v:g} V: simulated {e_sim:.3f} J, closed form {e_closed:.3f} J")

# %% [markdown]
# ## Task 4 — The command lag
# Drive the stroke at a constant velocity (a ramp, 0.1 m/s) and step the command from 0 to 2.25 V at t = 0.1 s.
# Plot the effective command u (`r.u`) and the force, and measure the time each takes to cover 63 % of its
# step. Repeat with a pure delay τ = 5 ms added to the command channel
# (`make_damper("spencer_dyke", command={"eta": 190.0, "delay": 0.005})`).

# %%
dt = 1e-4
t = np.arange(0, 0.2, dt)
x_ramp = -0.01 + 0.1 * t  # m: 0.1 m/s, inside the stroke
step = np.where(t >= 0.1, 2.25, 0.0)
k_step = int(np.argmax(t >= 0.1))


def rise_time(signal, k0):
    """Time from sample k0 until ``signal`` first covers 63 % of its change from k0 to the end (s)."""
    s0, s1 = signal[k0 - 1], signal[-1]
    k = k0 + int(np.argmax((signal[k0:] - s0) / (s1 - s0) >= 1 - np.exp(-1)))
    return (k - k0) * dt


lagged = simulate(damper, x_ramp, step, dt, v=np.full_like(t, 0.1))[0]
delayed_damper = make_damper("spencer_dyke", preset="spencer1997", command={"eta": 190.0, "delay": 0.005})
delayed = simulate(delayed_damper, x_ramp, step, dt, v=np.full_like(t, 0.1))[0]
eta = damper.command.eta
t63 = {"u": rise_time(lagged.u, k_step), "F": rise_time(lagged.force, k_step),
       "u (τ = 5 ms)": rise_time(delayed.u, k_step), "F (τ = 5 ms)": rise_time(delayed.force, k_step)}
print(f"1/η = {1e3 / eta:.2f} ms; 63 % times: " + ", ".join(f"{k} {1e3 * v:.2f} ms" for k, v in t63.items()))

fig, (ax_u, ax_f) = figure(2, 1, figsize=(8, 6), sharex=True)
ax_u.plot(t * 1e3, step, "k--", lw=1, label="command v")
ax_u.plot(t * 1e3, lagged.u, label="u, no delay")
ax_u.plot(t * 1e3, delayed.u, label="u, τ = 5 ms")
ax_f.plot(t * 1e3, lagged.force, label="no delay")
ax_f.plot(t * 1e3, delayed.force, label="τ = 5 ms")
ax_u.set_ylabel("command (V)")
ax_f.set_ylabel("force F (N)")
ax_f.set_xlabel("time (ms)")
for ax in (ax_u, ax_f):
    ax.axvline(100 + 1e3 / eta, color="grey", lw=0.8, ls=":")
    ax.grid(alpha=0.3)
    ax.legend()
ax_u.set_title(f"command step at 0.1 m/s; dotted: 1/η = {1e3 / eta:.1f} ms after the step")
lab.save(fig, "command_lag.png")

# %% [markdown]
# ## Questions
# 1. Where on the force–velocity loop does the Bingham model fail, and what in eq. (12) fixes it?
# 2. The force–displacement loop of a pure viscous damper is an ellipse, of a pure friction damper a rectangle.
#    Which does the 0 V loop resemble, and the 2.25 V one?
# 3. c_eq falls with frequency at a high command. Explain with E = 4 f_c X + π c₀ ω X².
# 4. The force reaches 63 % of its step slightly later than u (the printed times: a fraction of a millisecond,
#    too little to see in the figure). What in eq. (12) adds that lag? Next to 1/η, what matters more for a
#    controller that switches every millisecond?
# 5. Why is c_ps smaller than c₀? What would the pre-yield slope c_pre be, and which parameters of eq. (12) set it?
# 6. The asymmetry of the loops (peak force in compression larger than in extension): where does it come from?

# %% [markdown]
# ## Instructor's check
# The physics the results must show (each check prints the numbers it saw).

# %%
published = {0.0: (478, -622), 0.75: (840, -984), 1.5: (1197, -1340), 2.25: (1548, -1691)}  # N, reference page
worst = max(max(abs(r.force[last].max() - published[v][0]), abs(r.force[last].min() - published[v][1]))
            for r, v in zip(by_command, commands))
lab.check("peak forces at 1.5 cm / 2.5 Hz reproduce the published Spencer–Dyke check values (within 5 N)",
          worst < 5.0, f"worst difference {worst:.2f} N")
worst_fig5 = max(max(abs(d["c_ps"] / d["c_ps eq. (12)"] - 1), abs(d["F_yield"] / d["F_yield eq. (12)"] - 1))
                 for d in figure5.values())
lab.check("c_ps and F_yield read from the loops match the large-velocity limit of eq. (12) (within 2 %)",
          worst_fig5 < 0.02, f"worst relative difference {100 * worst_fig5:.2f} %")
lab.check("F_yield grows with the command", np.all(np.diff([figure5[v]["F_yield"] for v in commands]) > 0))
for f in frequencies:
    e = [energy[f, v] for v in commands]
    lab.check(f"energy per cycle grows with the command at {f:g} Hz", np.all(np.diff(e) > 0),
              ", ".join(f"{x:.2f}" for x in e) + " J")
for v in commands:
    e = [energy[f, v] for f in frequencies]
    lab.check(f"energy per cycle grows with the frequency at {v:g} V", np.all(np.diff(e) > 0),
              ", ".join(f"{x:.2f}" for x in e) + " J")
lab.check("at 2.25 V the equivalent damping c_eq falls with frequency (friction-dominated)",
          np.all(np.diff([c_eq[f, 2.25] for f in frequencies]) < 0))
lab.check("Bingham energy per cycle = 4 f_c X + π c0 ω X² (within 0.5 %)", max(bingham_error) < 0.005,
          f"worst relative error {100 * max(bingham_error):.3f} %")
lab.check("the effective command covers 63 % of its step in 1/η (within one sample)",
          abs(t63["u"] - 1 / eta) <= dt, f"{1e3 * t63['u']:.2f} ms vs 1/η = {1e3 / eta:.2f} ms")
lab.check("the force lags the effective command (its 63 % time is longer than u's)", t63["F"] > t63["u"],
          f"F {1e3 * t63['F']:.2f} ms, u {1e3 * t63['u']:.2f} ms")
lab.check("a pure delay τ = 5 ms shifts the force response by τ (within 0.5 ms)",
          abs(t63["F (τ = 5 ms)"] - t63["F"] - 0.005) < 5e-4,
          f"shift {1e3 * (t63['F (τ = 5 ms)'] - t63['F']):.2f} ms")
lab.finish()
