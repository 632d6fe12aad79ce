"""The quarter car's frame: road, tyre, wheel, suspension spring and MR damper, body. (:mod:`mrd_env.envs.render` draws the traces.)"""
from __future__ import annotations

from ...envs.render import Renderer, zigzag


class QuarterCarRenderer(Renderer):
    """Road, tyre spring, unsprung mass, suspension spring + MR damper, sprung mass; vertical motion ×GAIN."""

    response_label = "sprung acc. (m/s²)"
    response = ("sprung_acc", 0)
    GAIN = 10.0   # display units per m (masses are ~0.4-0.6 units tall)

    def _state(self) -> dict:
        env = self.env
        z_s, z_u = env.signal("_z")[-1]
        return {**super()._state(), "z_s": float(z_s), "z_u": float(z_u), "z_r": float(env.signal("road")[-1, 0])}

    def _build_schematic(self) -> None:
        from matplotlib.patches import Rectangle

        ax = self.ax_s
        ax.set_xlim(-1.0, 1.0)
        ax.set_ylim(-0.6, 3.4)
        ax.set_title(f"quarter car (motion x{self.GAIN:g})", fontsize=8)
        self.road, = ax.plot([-0.9, 0.9], [0, 0], color="k", lw=2)
        self.tyre, = ax.plot([], [], color="0.3", lw=1.2)
        self.spring, = ax.plot([], [], color="0.3", lw=1.2)
        self.m_u = Rectangle((-0.35, 0.0), 0.7, 0.35, fc="0.75", ec="k")
        self.m_s = Rectangle((-0.7, 0.0), 1.4, 0.6, fc="0.85", ec="k")
        self.cyl = Rectangle((0.12, 0.0), 0.16, 0.3, fc="C3", ec="k")
        ax.add_patch(self.m_u)
        ax.add_patch(self.m_s)
        ax.add_patch(self.cyl)
        self.rod, = ax.plot([], [], color="k", lw=2)
        self.lbl_u = ax.text(0, 0, "m_u", ha="center", va="center", fontsize=8)
        self.lbl_s = ax.text(0, 0, "m_s", ha="center", va="center", fontsize=9)
        self.lbl_d = ax.text(0, 0, "MR", ha="left", va="center", fontsize=7)
        self.lbl_f = ax.text(-0.95, -0.5, "", fontsize=7)

    def _update_schematic(self, s: dict) -> None:
        g = self.GAIN
        y_r = g * s["z_r"]
        y_u = 0.55 + g * s["z_u"]          # bottom of the unsprung mass
        y_s = 1.85 + g * s["z_s"]          # bottom of the sprung mass
        self.road.set_ydata([y_r, y_r])
        self.tyre.set_data(*zigzag(0.0, y_r, y_u, n=4))
        self.m_u.set_y(y_u)
        top_u = y_u + 0.35
        self.spring.set_data(*zigzag(-0.2, top_u, y_s, n=5))
        mid = 0.5 * (top_u + y_s)
        self.cyl.set_y(top_u)
        self.cyl.set_height(max(mid - top_u, 0.02))
        self.cyl.set_facecolor(self._color(s["command"][0]))
        self.rod.set_data([0.2, 0.2], [mid, y_s])
        self.m_s.set_y(y_s)
        self.lbl_u.set_position((0.0, y_u + 0.175))
        self.lbl_s.set_position((0.0, y_s + 0.3))
        self.lbl_d.set_position((0.3, mid))
        self.lbl_f.set_text(f"F = {s['force'][0]:.0f} N")
