"""The isolator's frame: base, spring and MR damper side by side, payload. (:mod:`mrd_env.envs.render` draws the
traces.)"""
from __future__ import annotations

from ...envs.render import Renderer, zigzag


class IsolatorRenderer(Renderer):
    """Base (moving), spring and MR damper (coloured by its command) side by side, payload; vertical motion ×GAIN."""

    response_label = "payload acc. (m/s²)"
    response = ("payload_acc", 0)
    GAIN = 10.0   # display units per m

    def _state(self) -> dict:
        env = self.env
        return {**super()._state(), "x": float(env.signal("_x")[-1, 0]), "z_b": float(env.signal("_base")[-1, 0])}

    def _build_schematic(self) -> None:
        from matplotlib.patches import Rectangle

        ax = self.ax_s
        ax.set_xlim(-1.0, 1.0)
        ax.set_ylim(-0.8, 2.6)
        ax.set_title(f"MR isolator (motion x{self.GAIN:g})", fontsize=8)
        self.base = Rectangle((-0.8, 0.0), 1.6, 0.2, fc="0.6", ec="k", hatch="//")
        self.mass = Rectangle((-0.6, 0.0), 1.2, 0.6, fc="0.85", ec="k")
        self.cyl = Rectangle((0.17, 0.0), 0.16, 0.3, fc="C3", ec="k")
        for patch in (self.base, self.mass, self.cyl):
            ax.add_patch(patch)
        self.spring, = ax.plot([], [], color="0.3", lw=1.2)
        self.rod, = ax.plot([], [], color="k", lw=2)
        self.lbl_m = ax.text(0, 0, "m", ha="center", va="center", fontsize=9)
        self.lbl_d = ax.text(0, 0, "MR", ha="left", va="center", fontsize=7)
        self.lbl_f = ax.text(-0.95, -0.7, "", fontsize=7)

    def _update_schematic(self, s: dict) -> None:
        g = self.GAIN
        y_b = g * s["z_b"]                 # bottom of the base
        top_b = y_b + 0.2
        y_m = 1.3 + g * s["x"]             # bottom of the payload
        self.base.set_y(y_b)
        self.spring.set_data(*zigzag(-0.25, top_b, y_m, n=5))
        mid = 0.5 * (top_b + y_m)
        self.cyl.set_y(top_b)
        self.cyl.set_height(max(mid - top_b, 0.02))
        self.cyl.set_facecolor(self._color(s["command"][0]))
        self.rod.set_data([0.25, 0.25], [mid, y_m])
        self.mass.set_y(y_m)
        self.lbl_m.set_position((0.0, y_m + 0.3))
        self.lbl_d.set_position((0.36, mid))
        self.lbl_f.set_text(f"F = {s['force'][0]:.0f} N")
