"""The full car's frame: a side view (the left wheels: heave and pitch) above a rear view (the rear axle: heave and
roll), the struts coloured by their commands. (:mod:`mrd_env.envs.render` draws the traces.)"""
from __future__ import annotations

from ...envs.render import Renderer, zigzag


class FullCarRenderer(Renderer):
    """Side view (front left, rear left) and rear view (rear left, rear right): roads, tyres, wheels, struts and the
    body line between them; vertical motion ×GAIN."""

    response_label = "body heave acc. (m/s²)"
    response = ("body_acc", 0)
    GAIN = 10.0
    #: (corner index, x in display units, panel baseline) of the drawn wheels: side view above, rear view below
    VIEWS = ((0, -0.8, 1.9), (2, 0.8, 1.9), (2, -0.7, -0.4), (3, 0.7, -0.4))

    def _state(self) -> dict:
        env = self.env
        return {**super()._state(), "q": env.signal("_q")[-1].copy(), "road": env.signal("road")[-1].copy()}

    def _build_schematic(self) -> None:
        from matplotlib.patches import Rectangle

        ax = self.ax_s
        ax.set_xlim(-1.3, 1.3)
        ax.set_ylim(-0.7, 3.7)
        ax.set_title(f"full car: side (left wheels), rear (motion x{self.GAIN:g})", fontsize=8)
        n = len(self.VIEWS)
        self.roads = [ax.plot([], [], color="k", lw=2)[0] for _ in range(n)]
        self.tyres = [ax.plot([], [], color="0.3", lw=1.2)[0] for _ in range(n)]
        self.wheels = [Rectangle((0, 0), 0.3, 0.3, fc="0.75", ec="k") for _ in range(n)]
        self.struts = [ax.plot([], [], lw=5, solid_capstyle="butt")[0] for _ in range(n)]
        for w in self.wheels:
            ax.add_patch(w)
        self.bodies = [ax.plot([], [], color="0.4", lw=8, solid_capstyle="butt")[0] for _ in range(2)]
        self.lbl_f = ax.text(-1.25, -0.65, "", fontsize=7)

    def _update_schematic(self, s: dict) -> None:
        g = self.GAIN
        q = s["q"]
        body = self.env.plant_params.body_at_corners() @ q  # the body above each corner
        tops = []
        for j, (i, x, base) in enumerate(self.VIEWS):
            y_r = base + g * s["road"][i]
            y_w = base + 0.5 + g * q[3 + i]
            y_b = base + 1.3 + g * body[i]
            self.roads[j].set_data([x - 0.25, x + 0.25], [y_r, y_r])
            self.tyres[j].set_data(*zigzag(x, y_r, y_w, n=3))
            self.wheels[j].set_xy((x - 0.15, y_w))
            self.struts[j].set_data([x, x], [y_w + 0.3, y_b])
            self.struts[j].set_color(self._color(s["command"][i]))
            tops.append((x, y_b))
        for k in range(2):
            (x0, y0), (x1, y1) = tops[2 * k], tops[2 * k + 1]
            self.bodies[k].set_data([x0, x1], [y0, y1])
        self.lbl_f.set_text("F = " + ", ".join(f"{v:.0f}" for v in s["force"]) + " N")
