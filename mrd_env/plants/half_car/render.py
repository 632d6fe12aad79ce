"""The half car's frame: side view of the body pitching over two struts. (:mod:`mrd_env.envs.render` draws the traces.)"""
from __future__ import annotations

import numpy as np

from ...envs.render import Renderer, zigzag


class HalfCarRenderer(Renderer):
    """Side view: road under each axle, wheels, suspension struts (MR dampers coloured by their command) and the
    body pitching between them; vertical motion ×GAIN."""

    response_label = "body acc. (m/s²)"
    response = ("body_acc", 0)
    GAIN = 10.0

    def _state(self) -> dict:
        env = self.env
        q = env.signal("_q")[-1]
        return {**super()._state(), "q": q.copy(), "road": env.signal("_road")[-1].copy()}

    def _build_schematic(self) -> None:
        from matplotlib.patches import Rectangle

        p = self.env.plant_params
        span = p.a + p.b
        self.x = np.array([-p.a, p.b]) / span * 1.6  # front (left) and rear axles, display units
        ax = self.ax_s
        ax.set_xlim(-1.3, 1.3)
        ax.set_ylim(-0.6, 2.6)
        ax.set_title(f"half car (motion x{self.GAIN:g})", fontsize=8)
        self.roads = [ax.plot([], [], color="k", lw=2)[0] for _ in range(2)]
        self.tyres = [ax.plot([], [], color="0.3", lw=1.2)[0] for _ in range(2)]
        self.wheels = [Rectangle((0, 0), 0.3, 0.3, fc="0.75", ec="k") for _ in range(2)]
        self.struts = [ax.plot([], [], lw=5, solid_capstyle="butt")[0] for _ in range(2)]
        for w in self.wheels:
            ax.add_patch(w)
        self.body, = ax.plot([], [], color="0.4", lw=8, solid_capstyle="butt")
        self.lbl_f = ax.text(-1.25, -0.5, "", fontsize=7)

    def _update_schematic(self, s: dict) -> None:
        g = self.GAIN
        z_s, theta, z_uf, z_ur = s["q"]
        wheel = np.array([z_uf, z_ur])
        body = z_s + np.array([-self.env.plant_params.a, self.env.plant_params.b]) * theta  # above each axle
        for j in range(2):
            x, y_r = self.x[j], g * s["road"][j]
            y_w = 0.5 + g * wheel[j]
            self.roads[j].set_data([x - 0.3, x + 0.3], [y_r, y_r])
            self.tyres[j].set_data(*zigzag(x, y_r, y_w, n=3))
            self.wheels[j].set_xy((x - 0.15, y_w))
            self.struts[j].set_data([x, x], [y_w + 0.3, 1.6 + g * body[j]])
            self.struts[j].set_color(self._color(s["command"][j]))
        self.body.set_data(self.x, 1.6 + g * body)
        self.lbl_f.set_text("F = " + ", ".join(f"{v:.0f}" for v in s["force"]) + " N")
