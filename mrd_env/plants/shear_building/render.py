"""The shear building's frame: floors displaced by their drift, the MR dampers as braces. (:mod:`mrd_env.envs.render` draws the traces.)"""
from __future__ import annotations

import numpy as np

from ...envs.render import Renderer


class BuildingRenderer(Renderer):
    """Floors displaced horizontally by their drift from the ground (exaggerated), dampers as braces."""

    response_label = "roof disp. rel. ground (m)"
    response = ("floor_disp", -1)

    def _state(self) -> dict:
        return {**super()._state(), "disp": self.env.signal("floor_disp")[-1].copy()}

    def _gain(self) -> float:
        """Drift exaggeration: the uncontrolled roof moves 0.35 display units at its peak."""
        ep = self.env.episode
        peak = float(np.max(np.abs(ep.extras["uncontrolled"]["disp"]))) if ep is not None else 0.0
        return 0.35 / max(peak, 1e-9)

    def _build_schematic(self) -> None:
        from matplotlib.patches import Rectangle

        env = self.env
        n = env.plant_params.n_floors
        self.n = n
        ax = self.ax_s
        ax.set_xlim(-1.2, 1.2)
        ax.set_ylim(-0.4, n + 0.6)
        self.ax_title = ax.set_title("", fontsize=8)
        ax.plot([-1.1, 1.1], [0, 0], color="k", lw=2)
        ax.fill_between([-1.1, 1.1], [-0.3, -0.3], [0, 0], color="0.85", hatch="//", lw=0)
        self.floors, self.labels = [], []
        for i in range(n):
            r = Rectangle((-0.5, i + 1 - 0.08), 1.0, 0.16, fc="0.75", ec="k")
            ax.add_patch(r)
            self.floors.append(r)
            self.labels.append(ax.text(0, i + 1, f"m{i + 1}", ha="center", va="center", fontsize=7))
        self.cols_l, = ax.plot([], [], color="0.3", lw=1.2)
        self.cols_r, = ax.plot([], [], color="0.3", lw=1.2)
        self.braces = [ax.plot([], [], lw=4, solid_capstyle="butt")[0] for _ in env.plant_params.damper_floors]
        self.brace_lbl = [ax.text(0, 0, "MR", fontsize=7) for _ in env.plant_params.damper_floors]
        self.lbl_f = ax.text(-1.15, n + 0.35, "", fontsize=7)

    def _update_schematic(self, s: dict) -> None:
        env = self.env
        g = self._gain()
        self.ax_title.set_text(f"shear building (drift x{g:.0f})")
        xs = np.concatenate([[0.0], g * s["disp"]])
        ys = np.arange(self.n + 1, dtype=float)
        for i, r in enumerate(self.floors):
            r.set_x(xs[i + 1] - 0.5)
            self.labels[i].set_position((xs[i + 1], i + 1))
        # columns as polylines with a NaN break between storeys is unnecessary: one line per side
        self.cols_l.set_data(xs - 0.45, ys)
        self.cols_r.set_data(xs + 0.45, ys)
        for j, f in enumerate(env.plant_params.damper_floors):
            x0, x1 = xs[f - 1], xs[f]
            self.braces[j].set_data([x0 - 0.4, x1 + 0.1], [f - 1 + (0.08 if f > 1 else 0.0), f - 0.08])
            self.braces[j].set_color(self._color(s["command"][j]))
            self.brace_lbl[j].set_position((0.5 * (x0 + x1) - 0.05, f - 0.55))
        self.lbl_f.set_text("F = " + ", ".join(f"{v:.0f}" for v in s["force"]) + " N")
