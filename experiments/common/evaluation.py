"""One evaluation loop for every controller — classical laws and trained agents — and the statistics of the
results: mean and 95 % confidence interval over seeds and episodes.

A scenario's seeds run in one vector environment; the controller (built on that vector environment, so that
it reads the same sensors at the same control rate as any other) acts on the whole batch at once.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from mrd_env.envs.sensors import newest_layout
from mrd_env.report import figure, save_figure

from .scenarios import Scenario


def response_channel(layout: dict, response: str) -> tuple[slice | None, int]:
    """(slice of the sensor, channel) of a response ``"name"`` (its first channel) or ``"name[i]"``."""
    name, _, rest = response.partition("[")
    k = int(rest.rstrip("]")) if rest else 0
    return layout.get(name), k


@dataclass
class Episode:
    controller: str
    scenario: str
    metrics: dict
    t: np.ndarray
    response: np.ndarray   # key response history (sprung acceleration, or the drift of the damper's storey)
    force: np.ndarray
    velocity: np.ndarray   # damper velocity
    wall_time: float
    episode_return: float = float("nan")
    seed: int = 0


def evaluate(controller, env, seed: int, response: str) -> Episode:
    """Run one episode of a scalar environment with ``controller`` (classical laws and agents alike)."""
    base = env.unwrapped
    layout = newest_layout(base)
    rate = base.roles.get("damper_velocity", "")

    def first(o, name):
        sl, k = response_channel(layout, name)
        v = o[sl] if sl is not None else np.zeros(0)
        return float(v[k]) if v.size > k else float("nan")

    obs, _ = env.reset(seed=seed)
    controller.reset()
    t, resp, force, vel = [], [], [], []
    total = 0.0
    t0 = time.perf_counter()
    while True:
        action, _ = controller.predict(obs, deterministic=True)
        obs, r, terminated, truncated, info = env.step(action)
        total += r
        t.append(info["t"])
        resp.append(first(obs, response))
        force.append(float(base.damper_force[0]))
        vel.append(first(obs, rate))
        if terminated or truncated:
            break
    wall = time.perf_counter() - t0
    metrics = dict(info.get("episode_metrics", {}))
    if terminated:
        metrics["terminated"] = info.get("termination_reason", "terminated")
    return Episode(getattr(controller, "name", type(controller).__name__), "", metrics, np.array(t),
                   np.array(resp), np.array(force), np.array(vel), wall, total, seed)


def evaluate_batch(make, scenario: Scenario, response: str, name: str | None = None, **env_options) -> list[Episode]:
    """One episode per seed of ``scenario`` in one vector environment, driven by ``make(venv)`` (a controller
    built on the vector environment: its predict takes the batch of observations). The time histories are
    those of the first seed."""
    from mrd_env.envs.vector import env_info

    N = len(scenario.seeds)
    venv = gym.make_vec(scenario.env_id, num_envs=N, vectorization_mode="vector_entry_point",
                        **{**scenario.options, **env_options})
    try:  # closed whatever happens: a controller's error leaves no environment open
        ctrl = make(venv)
        layout = newest_layout(venv)
        rate = venv.roles.get("damper_velocity", "")

        def first(o, key):
            sl, k = response_channel(layout, key)
            return float(o[sl][k]) if sl is not None else float("nan")

        obs, _ = venv.reset(seed=list(scenario.seeds))
        ctrl.reset()
        done = np.zeros(N, dtype=bool)
        returns = np.zeros(N)
        metrics: list[dict] = [{} for _ in range(N)]
        t, resp, force, vel = [], [], [], []
        t0 = time.perf_counter()
        while not done.all():
            action, _ = ctrl.predict(obs, deterministic=True)
            obs, r, term, trunc, info = venv.step(action)
            returns[~done] += r[~done]
            if not done[0]:
                t.append(float(info["t"][0]))
                resp.append(first(obs[0], response))
                force.append(first(obs[0], "damper_force"))
                vel.append(first(obs[0], rate))
            ended = (term | trunc) & ~done
            for b in np.flatnonzero(ended):
                mine = env_info(info, b)  # Gymnasium's batched info: env b's own keys (masks dropped)
                metrics[b] = {k: float(v) for k, v in mine.get("episode_metrics", {}).items()}
                if term[b]:
                    metrics[b]["terminated"] = str(mine.get("termination_reason") or "terminated")
            done |= ended
        wall = (time.perf_counter() - t0) / N
    finally:
        venv.close()
    name = name or getattr(ctrl, "name", type(ctrl).__name__)
    empty = np.zeros(0)
    return [Episode(name, scenario.label(seed), metrics[b], np.array(t) if b == 0 else empty,
                    np.array(resp) if b == 0 else empty, np.array(force) if b == 0 else empty,
                    np.array(vel) if b == 0 else empty, wall, float(returns[b]), int(seed))
            for b, seed in enumerate(scenario.seeds)]


def controller_episodes(controller, scenario: Scenario, response: str = "", name: str | None = None,
                        **env_options) -> list[Episode]:
    """One episode per seed of ``scenario`` for ``controller``: a law's name (``controllers.CONTROLLERS``) or a
    pair (name, options), or an agent folder (a ``pathlib.Path``; evaluated with the observation options it was
    trained with, on the ``damper`` of ``env_options`` where one is given, as every other row); ``name``: the
    row's name (default: the law's or the agent's). A plain function of picklable inputs, so that sweeps run it on
    any backend (:mod:`mrd_env.executor`)."""
    import mrd_env  # noqa: F401  (registers the environments, also in a fresh worker)
    from pathlib import Path

    from controllers import load_agent, make_controller

    if isinstance(controller, Path):
        agent = load_agent(controller)
        options = {**env_options, **agent.observation_kwargs}
        if "damper" in env_options:  # the comparison's damper for every row (the agent keeps its own sensors)
            options["damper"] = env_options["damper"]
        return evaluate_batch(lambda v: agent.bind(v), scenario, response, name=name or agent.name, **options)
    law, options = controller if isinstance(controller, tuple) else (controller, {})
    return evaluate_batch(lambda v: make_controller(law, v, **options), scenario, response, name=name or law,
                          **env_options)


def laws_apply(env_id: str, env_kwargs: dict, laws, where: str, build, sep: str = " ") -> None:
    """Each law of ``laws`` ((option, law name) pairs) builds on the environment (``build(env, name)``: it finds
    the sensors and roles it reads), else ``ValueError`` "<option><sep><name> does not apply to <where>: ..."."""
    env = gym.make(env_id, **env_kwargs)
    try:
        for option, name in laws:
            try:
                build(env, name)
            except ValueError as exc:
                raise ValueError(f"{option}{sep}{name} does not apply to {where}: {exc}") from None
    finally:
        env.close()


def mean_ci(values, confidence: float = 0.95, upper: float = math.inf) -> tuple[float, float, float]:
    """(mean, lower, upper): Student-t interval of the mean. One value has no interval (NaN bounds, not a
    zero-width one); identical values give a zero-width interval. ``upper``: the largest value the quantity can
    take (returns are ≤ 0): the interval is truncated there rather than claim impossible values."""
    from scipy import stats

    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    m = float(x.mean())
    if x.size == 1:
        return m, math.nan, math.nan
    if np.all(x == x[0]):
        return m, m, m
    h = float(stats.sem(x) * stats.t.ppf(0.5 + confidence / 2, x.size - 1))
    return m, m - h, min(m + h, upper)


#: The most scenario panels :func:`grouped_bars` draws (the tables hold every scenario): a figure of hundreds of
#: panels that share an axis takes minutes to lay out (500 took 134 s) and shows nothing legible.
MAX_PANELS = 12
#: The most controllers (bars per panel) :func:`grouped_bars` draws: the first ones, in the order of ``rows`` (the
#: leaderboard's: best first); 40 bars are still legible, 100 took 10 s to draw and were not.
MAX_BARS = 40
#: :func:`grouped_bars`'s sizes, in inches (110 px each at :func:`mrd_env.report.save_figure`'s dpi): a bar's row
#: (room for an 8-point label, about 0.11 in, and a gap), a panel's width, and the widest figure (1 760 px).
BAR_PITCH = 0.2
PANEL_WIDTH = 3.2
MAX_WIDTH = 16.0
#: The most characters of a controller's name drawn (the tables hold it whole): beyond, cut with an ellipsis.
MAX_LABEL = 36
#: The most characters of a line of a panel's title, and its most lines.
PANEL_TITLE_CHARS, PANEL_TITLE_LINES = 44, 2
#: The width (inches) of a character of the figure's 8-point labels and 10-point title, on average and with a
#: margin (DejaVu Sans): what sizes the label column and wraps the title.
CHAR_8PT, CHAR_10PT = 0.068, 0.085


def _plain(text) -> str:
    """``text`` shown as itself in a figure: a ``$`` would start matplotlib's mathtext (a name such as ``$\\frac``
    fails to draw, or draws as a formula)."""
    return str(text).replace("$", r"\$")


def _ellipsis(text: str, n: int) -> str:
    """``text`` cut to ``n`` characters, the last an ellipsis where it was longer."""
    return text if len(text) <= n else text[:n - 1] + "…"


def _wrapped(text: str, chars: int, max_lines: int | None = None) -> list[str]:
    """The lines of ``text`` (its own line breaks kept) wrapped at ``chars`` characters, at most ``max_lines`` (the
    last cut with an ellipsis)."""
    import textwrap

    lines = [w for part in str(text).split("\n") for w in (textwrap.wrap(part, chars, break_long_words=True) or [""])]
    if max_lines is not None and len(lines) > max_lines:
        lines = lines[:max_lines - 1] + [_ellipsis(" ".join(lines[max_lines - 1:]), chars)]
    return lines


def grouped_bars(rows: list[dict], value: str, lo: str, hi: str, path: Path, *, xlabel: str, title: str,
                 refs: tuple[float, ...] = (), xlim: tuple[float, float] | None = None,
                 max_panels: int = MAX_PANELS, max_bars: int = MAX_BARS, metadata: dict | None = None,
                 apart: dict[str, str] | None = None) -> Path:
    """One panel per scenario, a horizontal bar of ``rows[value]`` per controller (one colour per law, its 1 ms row
    hatched) with the interval [lo, hi] where there is one (the axis label names it only where one is drawn);
    vertical lines at ``refs``. With ``xlim``, a bar beyond the axis is drawn to its edge and labelled with its
    value, so that one very poor controller does not squash the others. At most ``max_panels`` panels: beyond, the
    first ``max_panels - 1`` scenarios and the last one (where a pooled row such as "all scenarios" comes), the
    title saying how many are shown; likewise at most ``max_bars`` controllers, the first ones. ``apart``:
    {controller: note} drawn below a dotted line, pale, their label followed by the note (the leaderboard's partial
    results, never ranked). ``metadata``: the PNG's text entries (:func:`mrd_env.report.save_figure`).

    Sized from what it draws, so that nothing overlaps: :data:`BAR_PITCH` per bar (the height grows with the bars),
    room for each panel's title (wrapped, at most two lines) and axis label, the figure's title wrapped to its
    width; the width at most :data:`MAX_WIDTH` (fewer columns of panels where the labels are long), a controller's
    name cut at :data:`MAX_LABEL` characters with an ellipsis (in the figure only)."""
    import matplotlib

    if max_panels < 1 or max_bars < 1:
        raise ValueError(f"max_panels and max_bars must be at least 1, got {max_panels} and {max_bars}")
    apart = dict(apart or {})
    scen = list(dict.fromkeys(r["scenario"] for r in rows))
    ctrls = list(dict.fromkeys(r["controller"] for r in rows))
    left_out = []
    if len(scen) > max_panels:
        left_out.append(f"{max_panels} of {len(scen)} panels: the first and the last")
        scen = scen[:max_panels - 1] + scen[-1:]
    if len(ctrls) > max_bars:
        left_out.append(f"the first {max_bars} of {len(ctrls)} controllers")
        ctrls = ctrls[:max_bars]
    if left_out:
        title = f"{title}\n(drawn: {'; '.join(left_out)}; the tables hold them all)"
    # each bar's row found by a look-up, not a search of every row (quadratic in the scenarios)
    by_key = {}
    for r in rows:
        by_key.setdefault((r["scenario"], r["controller"]), r)
    ranked = [c for c in ctrls if c not in apart]
    below = [c for c in ctrls if c in apart]
    ctrls = ranked + below
    # top to bottom: the ranked bars, a free row where the two groups meet, the bars drawn apart
    slots = list(range(len(ranked))) + [len(ranked) + (1 if ranked else 0) + i for i in range(len(below))]
    n_slots = (slots[-1] + 1) if slots else 1
    y = (n_slots - 1 - np.array(slots, dtype=float)) if slots else np.zeros(0)
    labels = [_plain(_ellipsis(c, MAX_LABEL) + (f" · {apart[c]}" if c in apart else "")) for c in ctrls]
    # the sizes: a label column as wide as the longest label, panels of PANEL_WIDTH, at most MAX_WIDTH in all
    label_width = max((len(t) for t in labels), default=1) * CHAR_8PT + 0.3
    ncol = max(1, min(len(scen), 4, int((MAX_WIDTH - label_width - 0.2) // PANEL_WIDTH)))
    nrow = -(-len(scen) // ncol)
    width = label_width + ncol * PANEL_WIDTH + 0.2
    title_lines = [_plain(t) for t in _wrapped(title, max(20, int(width / CHAR_10PT)))]
    panel_titles = ["\n".join(map(_plain, _wrapped(s, PANEL_TITLE_CHARS, PANEL_TITLE_LINES))) for s in scen]
    lines = [max(t.count("\n") + 1 for t in panel_titles[i * ncol:(i + 1) * ncol]) for i in range(nrow)]
    # a row of panels: its title's lines, its bars, its tick labels and two lines of axis label, and gaps
    heights = [0.17 * k + 0.1 + n_slots * BAR_PITCH + 0.25 + 0.35 + 0.15 for k in lines]
    height = sum(heights) + 0.19 * len(title_lines) + 0.15
    fig, axes = figure(nrow, ncol, figsize=(width, height), sharey=True, squeeze=False,
                       gridspec_kw={"height_ratios": heights})
    fig.get_layout_engine().set(w_pad=4 / 72, h_pad=4 / 72, wspace=0.06, hspace=0.02)  # tick labels of neighbours
    bases = {b: i for i, b in enumerate(dict.fromkeys(c.split(" @ ")[0] for c in ctrls))}
    cmap = matplotlib.colormaps["tab20"]
    for k, s in enumerate(scen):
        ax = axes[k // ncol][k % ncol]
        intervals = False
        for i, c in enumerate(ctrls):
            r = by_key.get((s, c))
            if r is None:
                continue
            m = r[value]
            shown = m if xlim is None else min(max(m, xlim[0]), xlim[1])
            ax.barh(y[i], shown, 0.8, color=cmap(bases[c.split(" @ ")[0]] % 20), alpha=0.45 if c in apart else 1.0,
                    hatch="//" if c.endswith("@ 1 ms") else None, edgecolor="white", lw=0.3)
            if shown != m:
                ax.text(shown, y[i], f" {m:.2g} ", va="center", ha="left" if m < shown else "right", fontsize=7)
            elif np.isfinite(r[lo]) and np.isfinite(r[hi]):
                ax.errorbar(m, y[i], xerr=[[m - r[lo]], [r[hi] - m]], color="k", lw=0.8, capsize=2)
                intervals = True
        for j, ref in enumerate(refs):
            ax.axvline(ref, color="k", lw=0.8, ls="--" if j else "-")
        if ranked and below:
            ax.axhline(len(below), color="0.5", lw=0.8, ls=":")  # the free row between the groups
        if xlim is not None:
            ax.set_xlim(*xlim)
        ax.set_ylim(-0.6, n_slots - 0.4)
        ax.set_title(panel_titles[k], fontsize=9)
        # an interval is named only in a panel that draws one (one episode draws none)
        ax.set_xlabel(f"{xlabel}\n(mean; lines: 95 % interval)" if intervals else xlabel, fontsize=8)
        ax.tick_params(axis="x", labelsize=8)
        ax.grid(axis="x", alpha=0.3)
    for ax in axes.flat[len(scen):]:
        ax.set_visible(False)
    axes[0][0].set_yticks(y, labels, fontsize=8)
    for row in axes:  # the shared labels repeat on every row of panels, at the same size
        row[0].tick_params(axis="y", labelsize=8)
    fig.suptitle("\n".join(title_lines), fontsize=10)
    return save_figure(fig, path, metadata=metadata)
