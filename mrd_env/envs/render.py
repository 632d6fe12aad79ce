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


def zigzag(x: float, y0: float, y1: float, n: int = 6, width: float = 0.08):
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


class Renderer(ABC):
    """Figure with a schematic axis (left) and two trace axes (right); each plant's renderer (``mrd_env/plants/<plant>/render.py``) draws the
    schematic.

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
