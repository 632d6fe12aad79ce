"""Frames of the environments drawn with matplotlib: a schematic of the plant (masses displaced by their current,
exaggerated positions; the MR damper coloured by its command) next to scrolling traces of the key response and
of the damper force.

``rgb_array``: an Agg canvas owned by the renderer (no pyplot state), read back as an (H, W, 3) uint8 array.
``human``: the same figure as a pyplot window, refreshed without blocking (``plt.pause``) at most ``HUMAN_FPS``
times per simulated second and closed by ``env.close()``. The figure and its artists are built once; each frame
only updates them.

A renderer draws what its ``env`` exposes: ``signal(name)`` (the episode's history at ``dt``), ``dt``,
``n_dampers``, ``command_spec``, ``plant_params``, ``episode`` (the current episode) and ``title``, so that a
vector environment renders each of its environments through a view of it.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
import numpy as np

HUMAN_FPS = 30        # window refreshes per simulated second in "human" mode
WINDOW = 3.0          # s of history in the traces
MAX_POINTS = 600      # points per trace (decimated)
FIGSIZE = (8.0, 4.0)  # inches
DPI = 80              # -> 640 x 320 pixels


def _zigzag(x: float, y0: float, y1: float, n: int = 6, width: float = 0.08):
    """A spring drawn as a zigzag from (x, y0) to (x, y1)."""
    ys = np.linspace(y0, y1, 2 * n + 3)
    xs = np.full_like(ys, x)
    xs[2:-2:2] = x - width
    xs[3:-2:2] = x + width
    return xs, ys


def _interactive_backend() -> bool:
    """True if pyplot's backend can show windows (not Agg, PDF, ... as in tests and on servers)."""
    import matplotlib

    try:  # matplotlib >= 3.9
        from matplotlib.backends import BackendFilter, backend_registry

        non_interactive = backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE)
    except ImportError:
        non_interactive = matplotlib.rcsetup.non_interactive_bk
    return matplotlib.get_backend().lower() not in {b.lower() for b in non_interactive}


class _Renderer(ABC):
    """Figure with a schematic axis (left) and two trace axes (right); subclasses draw the schematic.

    Everything drawn comes from the environment's public signal history (``env.signal(name)``): the traces of
    ``response`` (signal name, channel) and of the damper force, and the state :meth:`_state` reads."""

    response_label = ""
    response: tuple[str, int] = ("", 0)

    def __init__(self, env, human: bool):
        import matplotlib

        self.env = env
        self.human = human
        if human:
            import matplotlib.pyplot as plt

            self._plt = plt
            self.fig = plt.figure(figsize=FIGSIZE, dpi=DPI)
            self._interactive = _interactive_backend()
            if self._interactive:
                plt.show(block=False)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=FIGSIZE, dpi=DPI)
            FigureCanvasAgg(self.fig)
        self.cmap = matplotlib.colormaps["plasma"]
        gs = self.fig.add_gridspec(2, 2, width_ratios=(1.0, 1.5), left=0.04, right=0.98, bottom=0.12, top=0.84,
                                   wspace=0.25, hspace=0.35)
        self.ax_s = self.fig.add_subplot(gs[:, 0])
        self.ax_r = self.fig.add_subplot(gs[0, 1])
        self.ax_f = self.fig.add_subplot(gs[1, 1], sharex=self.ax_r)
        self.ax_s.set_xticks([])
        self.ax_s.set_yticks([])
        self.ax_r.set_ylabel(self.response_label, fontsize=8)
        self.ax_f.set_ylabel("damper force (N)", fontsize=8)
        self.ax_f.set_xlabel("t (s)", fontsize=8)
        for ax in (self.ax_r, self.ax_f):
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
        self.line_r, = self.ax_r.plot([], [], lw=1.0, color="C0")
        nd = env.n_dampers
        self.lines_f = [self.ax_f.plot([], [], lw=1.0, color=f"C{1 + j}")[0] for j in range(nd)]
        self.title = self.fig.suptitle("", fontsize=9)
        self._build_schematic()

    # subclass API
    @abstractmethod
    def _build_schematic(self) -> None:
        """Create the schematic's artists."""

    @abstractmethod
    def _update_schematic(self, state: dict) -> None:
        """Move the schematic's artists to ``state`` (see :meth:`_state`)."""

    def _state(self) -> dict:
        """The last row of the history: time, damper forces and commands (subclasses add their positions)."""
        env = self.env
        return {"t": env.signal("damper_force").shape[0] * env.dt - env.dt,
                "force": env.signal("damper_force")[-1].copy(), "command": env.signal("command")[-1].copy()}

    def _traces(self, window: float):
        env = self.env
        name, channel = self.response
        resp = env.signal(name)[:, channel]
        force = env.signal("damper_force")
        i0 = max(0, resp.shape[0] - int(round(window / env.dt)))
        t = np.arange(i0, resp.shape[0]) * env.dt
        return t, resp[i0:], force[i0:]

    def _color(self, v: float):
        cs = self.env.command_spec
        return self.cmap(0.1 + 0.8 * float(np.clip((v - cs.v_min) / (cs.v_max - cs.v_min), 0.0, 1.0)))

    def _update(self) -> None:
        env = self.env
        state = self._state()
        self._update_schematic(state)
        t, resp, force = self._traces(WINDOW)
        step = max(1, t.size // MAX_POINTS)
        t, resp, force = t[::step], resp[::step], force[::step]
        self.line_r.set_data(t, resp)
        for j, line in enumerate(self.lines_f):
            line.set_data(t, force[:, j])
        t1 = max(state["t"], WINDOW)
        self.ax_r.set_xlim(t1 - WINDOW, t1)
        for ax, y in ((self.ax_r, resp), (self.ax_f, force)):
            lo, hi = (float(np.min(y)), float(np.max(y))) if y.size else (-1.0, 1.0)
            pad = 0.1 * (hi - lo) if hi > lo else max(abs(hi), 1e-6)
            ax.set_ylim(lo - pad, hi + pad)
        cs = env.command_spec
        cmd = ", ".join(f"{v:.2f}" for v in state["command"])
        f = ", ".join(f"{v:.0f}" for v in state["force"])
        self.title.set_text(f"{env.title}  t = {state['t']:.3f} s   command = {cmd} {cs.unit}   "
                            f"F = {f} N")

    def frame(self) -> np.ndarray:
        self._update()
        canvas = self.fig.canvas
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def show(self) -> None:
        self._update()
        if self._interactive:
            self.fig.canvas.draw_idle()
            self._plt.pause(0.001)
        else:  # e.g. the Agg backend in tests: draw, nothing to show
            self.fig.canvas.draw()

    def close(self) -> None:
        if self.human:
            self._plt.close(self.fig)
        self.fig = None


class QuarterCarRenderer(_Renderer):
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
        self.tyre.set_data(*_zigzag(0.0, y_r, y_u, n=4))
        self.m_u.set_y(y_u)
        top_u = y_u + 0.35
        self.spring.set_data(*_zigzag(-0.2, top_u, y_s, n=5))
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


class BuildingRenderer(_Renderer):
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


class HalfCarRenderer(_Renderer):
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
            self.tyres[j].set_data(*_zigzag(x, y_r, y_w, n=3))
            self.wheels[j].set_xy((x - 0.15, y_w))
            self.struts[j].set_data([x, x], [y_w + 0.3, 1.6 + g * body[j]])
            self.struts[j].set_color(self._color(s["command"][j]))
        self.body.set_data(self.x, 1.6 + g * body)
        self.lbl_f.set_text("F = " + ", ".join(f"{v:.0f}" for v in s["force"]) + " N")
