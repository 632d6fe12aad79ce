"""Quarter car with an MR damper between the sprung and unsprung masses (``mrd_env/QuarterCar-v0``)."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..disturbances import Record, bump, iso8608_road, road_from_csv, sine_sweep
from ..metrics import quarter_car_metrics, weighting_sos
from ..plants import QuarterCarParams, quarter_car
from .base import MRDamperEnv, _check_options

#: Per road kind: accepted ``road_params`` keys and their defaults (None = required or generator default).
ROAD_PARAMS = {
    "iso8608": {"road_class": "C", "speed": 20.0, "method": "fft", "n_min": None, "n_max": None,
                "n_waves": None, "waviness": None},
    "bump": {"height": 0.05, "length": 1.0, "speed": 10.0, "t_start": 0.5, "duration": None},
    "sine_sweep": {"amplitude": 0.01, "f_start": 0.5, "f_end": 20.0, "kind": "log", "duration": None},
    "csv": {"path": None, "height_column": None, "distance_column": None, "time_column": None,
            "speed": None, "units": None},
    "record": {},
}

#: Reference scales of the quarter-car reward (SI).
A_REF = 1.0     # m/s², Wk-weighted sprung acceleration
X_REF = 0.05    # m, suspension travel


class QuarterCarEnv(MRDamperEnv):
    """Quarter car (sprung mass m_s, unsprung mass m_u, suspension spring k_s, tyre k_t/c_t) with an MR damper
    across the suspension, driven by a road profile; physics at ``dt`` = 1 ms.

    Options (keyword-only; every bad value raises ``ValueError`` naming the option):

    * ``plant_preset``: "set_a" (default), "set_b", "set_c" (reference parameter sets); ``plant_params``: a dict
      of :class:`~mrd_env.plants.QuarterCarParams` overrides, or a ``QuarterCarParams``.
    * ``damper`` (model name, default "spencer_dyke", or a ``DamperModel``), ``damper_preset`` (default
      "automotive", or the model's default preset if it has no "automotive" one), ``damper_params`` (overrides).
    * ``road``: "iso8608" (default; a new random road each episode from ``np_random``), "bump", "sine_sweep",
      "csv", or a :class:`~mrd_env.disturbances.Record` with channels z_r, zdot_r; ``road_params`` (dict):
      iso8608 — road_class "C", speed 20 m/s, method "fft" (n_min, n_max, n_waves, waviness as
      :func:`~mrd_env.disturbances.iso8608_road`); bump — height 0.05 m, length 1 m, speed 10 m/s, t_start
      0.5 s, duration (default: bump end + 2 s); sine_sweep — amplitude 0.01 m, f_start 0.5 Hz, f_end 20 Hz,
      kind "log", duration (default episode_seconds or 10 s); csv — path, height_column, distance_column +
      speed or time_column, units (see :func:`~mrd_env.disturbances.road_from_csv`).
    * ``episode_seconds``: default 10 s for generated roads (iso8608, sine_sweep), the record's length for
      bump, csv and Record roads (an episode never runs past its record's end).
    * ``dt`` 1e-3 s, ``control_dt`` 1e-3 s (integer multiple of dt), ``sensors``, ``sensor_noise``,
      ``sensor_delay``, ``action_mode``, ``reward_weights``, ``stroke_limit`` (default 0.1 m, on |z_s − z_u|),
      ``render_mode``: see :class:`~mrd_env.envs.base.MRDamperEnv`.

    Sensors (SI): ``sprung_acc`` z̈_s (m/s², gravity removed), ``unsprung_acc`` z̈_u, ``travel`` z_s − z_u (m),
    ``travel_rate`` (m/s), ``sprung_vel`` ż_s and ``unsprung_vel`` ż_u (m/s, absolute — on a car these come
    from integrated accelerometers), ``damper_force`` (N, load cell, includes the static preload), ``command``
    (applied, V or A), ``road`` z_r (m), ``damper_states`` (the model's internal states, hidden unless asked).
    Default: sprung_acc, unsprung_acc, travel, travel_rate, damper_force, command.

    Reward per control step, averaged over its physics sub-steps::

        r = −[w_comfort (a_w / 1 m/s²)² + w_travel (x / 0.05 m)² + w_tyre (F_t / ((m_s + m_u) g))²]

    a_w the ISO 2631-1 Wk-weighted sprung acceleration filtered online (causal IIR at 1/dt, state kept across
    steps), x the travel, F_t = k_t (z_r − z_u) + c_t (ż_r − ż_u) the dynamic tyre load (positive = more load
    than static). Default weights 1, 1, 1 (termination 1 per remaining step). Scale: on the default class-C road
    at 20 m/s the set-A car with the automotive Spencer–Dyke damper held at 0 V scores about −1.5 per step
    (a_w ≈ 1.1 m/s², travel ≈ 17 mm RMS, tyre load ≈ 0.26 of static), at 1 V about −3.2; comfort dominates.

    The car starts at rest in static equilibrium on the road's initial height (both masses at z_r(0), moving
    with ż_r(0)), so no artificial step hits the tyre. ``info["episode_metrics"]``:
    :func:`~mrd_env.metrics.quarter_car_metrics` (acc_weighted_rms, acc_rms, acc_vdv, acc_mtvv, travel_rms,
    travel_peak, tyre_load_rms, tyre_load_ratio) plus damper_force_rms, damper_force_peak (N) and duration (s).
    """

    SENSOR_UNITS = {"sprung_acc": "m/s^2", "unsprung_acc": "m/s^2", "travel": "m", "travel_rate": "m/s",
                    "sprung_vel": "m/s", "unsprung_vel": "m/s", "damper_force": "N", "command": "cmd",
                    "road": "m", "damper_states": "model"}
    DEFAULT_SENSORS = ("sprung_acc", "unsprung_acc", "travel", "travel_rate", "damper_force", "command")
    DEFAULT_REWARD_WEIGHTS = {"comfort": 1.0, "travel": 1.0, "tyre": 1.0, "termination": 1.0}
    DEFAULT_DAMPER_PRESET = "automotive"
    DEFAULT_STROKE_LIMIT = 0.1
    STROKE_SIGNAL = "travel"
    FILTER_SIGNAL = "sprung_acc"

    def __init__(self, *, plant_preset: str = "set_a", plant_params=None, road="iso8608",
                 road_params: Mapping | None = None, damper="spencer_dyke", damper_preset: str | None = None,
                 damper_params: Mapping[str, float] | None = None, dt: float = 1e-3, control_dt: float = 1e-3,
                 episode_seconds: float | None = None, sensors=None, sensor_noise: Mapping | None = None,
                 sensor_delay: int = 0, action_mode: str = "physical",
                 reward_weights: Mapping[str, float] | None = None, stroke_limit: float | None = None,
                 render_mode: str | None = None):
        self._plant_preset = plant_preset
        self._plant_overrides = plant_params
        self._road = road
        self._road_params = road_params
        super().__init__(damper=damper, damper_preset=damper_preset, damper_params=damper_params, dt=dt,
                         control_dt=control_dt, episode_seconds=episode_seconds, sensors=sensors,
                         sensor_noise=sensor_noise, sensor_delay=sensor_delay, action_mode=action_mode,
                         reward_weights=reward_weights, stroke_limit=stroke_limit, render_mode=render_mode)

    # --- plant and signals --------------------------------------------------------------------------------------
    def _build_plant(self):
        ov = self._plant_overrides
        if isinstance(ov, QuarterCarParams):
            params = ov
        else:
            if ov is not None and not isinstance(ov, Mapping):
                raise ValueError(f"plant_params must be a dict of QuarterCarParams overrides or a QuarterCarParams, "
                                 f"got {type(ov).__name__}")
            params = quarter_car(self._plant_preset, **dict(ov or {}))
        return params, params.plant()

    def _signal_defs(self, sb):
        p = self.plant_params
        sig = {
            "sprung_acc": sb.acc([1.0, 0.0]),
            "unsprung_acc": sb.acc([0.0, 1.0]),
            "travel": sb.disp([1.0, -1.0]),
            "travel_rate": sb.vel([1.0, -1.0]),
            "sprung_vel": sb.vel([1.0, 0.0]),
            "unsprung_vel": sb.vel([0.0, 1.0]),
            "damper_force": sb.force(),
            "road": sb.inp([[1.0, 0.0]]),
            "damper_states": sb.damper_states(),
            "_z": sb.disp(np.eye(2)),
        }
        # dynamic tyre load k_t (z_r − z_u) + c_t (ż_r − ż_u), positive = more load
        sig["_tyre_load"] = -p.k_t * sb.disp([0.0, 1.0]) - p.c_t * sb.vel([0.0, 1.0]) + sb.inp([[p.k_t, p.c_t]])
        return sig

    def _filter_sos(self):
        return weighting_sos("Wk", self.dt)

    def _setup_reward(self):
        w = self.reward_weights
        self.static_tyre_load = self.plant_params.static_tyre_load
        self._rcols = np.array([self._fout, self._sig_cols["travel"][0], self._sig_cols["_tyre_load"][0]],
                               dtype=np.int64)
        self._rscale = np.array([w["comfort"] / A_REF ** 2, w["travel"] / X_REF ** 2,
                                 w["tyre"] / self.static_tyre_load ** 2])

    # --- disturbance ------------------------------------------------------------------------------------------
    def _setup_disturbance(self):
        road = self._road
        if isinstance(road, Record):
            kind = "record"
        elif isinstance(road, str) and road in ROAD_PARAMS and road != "record":
            kind = road
        else:
            raise ValueError(f"road must be one of {[k for k in ROAD_PARAMS if k != 'record']} or a Record with "
                             f"channels ('z_r', 'zdot_r'), got {road!r}")
        self.road_kind = kind
        given = _check_options(f"road_params (road={kind!r})", self._road_params, ROAD_PARAMS[kind])
        params = {k: v for k, v in {**ROAD_PARAMS[kind], **given}.items() if v is not None}
        self.road_params = params
        self._fixed_record = None
        if kind == "iso8608":
            # validate now (a bad class or speed must fail at construction, not at the first reset)
            iso8608_road(duration=self._road_seconds(), dt=self.dt, rng=0, **params)
        elif kind == "sine_sweep":
            params.setdefault("duration", self.episode_seconds or 10.0)
            self._fixed_record = sine_sweep(dt=self.dt, **params)
        elif kind == "bump":
            self._fixed_record = bump(dt=self.dt, **params)
        elif kind == "csv":
            if "path" not in params or "height_column" not in params:
                raise ValueError("road='csv' needs road_params with 'path' and 'height_column' (and "
                                 "'distance_column' + 'speed', or 'time_column')")
            rest = {k: v for k, v in params.items() if k != "path"}
            self._fixed_record = road_from_csv(params["path"], dt=self.dt, **rest)
        else:
            self._fixed_record = self._road_record(road)

    def _road_record(self, rec: Record) -> Record:
        missing = [c for c in ("z_r", "zdot_r") if c not in rec.channels]
        if missing:
            raise ValueError(f"a road Record must have channels ('z_r', 'zdot_r') in m and m/s; {rec!r} "
                             f"lacks {missing}")
        data = np.column_stack([rec.channel("z_r"), rec.channel("zdot_r")])
        out = Record(rec.dt, data, ("z_r", "zdot_r"), ("m", "m/s"), rec.name)
        return out if abs(out.dt - self.dt) <= 1e-12 * self.dt else out.resample(self.dt)

    def _road_seconds(self) -> float:
        """Length of a generated random road: the episode (default 10 s), at least 2 s so that the FFT grid
        holds waves down to low spatial frequencies (a shorter episode uses the road's beginning)."""
        return max(self.episode_seconds or 10.0, 2.0)

    def _new_episode(self):
        if self._fixed_record is not None:
            rec = self._fixed_record
        else:
            rec = iso8608_road(duration=self._road_seconds(), dt=self.dt, rng=self.np_random, **self.road_params)
        zr0, zrd0 = rec.data[0]
        return rec, np.array([zr0, zr0, zrd0, zrd0])

    # --- metrics ---------------------------------------------------------------------------------------------
    def _episode_metrics(self, n_rows):
        acc = self.signal("sprung_acc", n_rows)[:, 0]
        travel = self.signal("travel", n_rows)[:, 0]
        tyre = self.signal("_tyre_load", n_rows)[:, 0]
        force = self.signal("damper_force", n_rows)[:, 0]
        out = quarter_car_metrics(self.dt, acc, travel, dynamic_tyre_load=tyre,
                                  static_tyre_load=self.static_tyre_load)
        out["damper_force_rms"] = float(np.sqrt(np.mean(force ** 2)))
        out["damper_force_peak"] = float(np.max(np.abs(force)))
        out["duration"] = (n_rows - 1) * self.dt
        return out

    # --- rendering -------------------------------------------------------------------------------------------
    def _make_renderer(self, human):
        from .render import QuarterCarRenderer

        return QuarterCarRenderer(self, human)

    def _render_state(self) -> dict:
        """Current displacements (m), force, command and the traces' histories (for :mod:`.render`)."""
        r = self._row - 1
        H = self._H
        c = self._sig_cols
        z_s, z_u = H[r, c["_z"]]
        return {"t": r * self.dt, "z_s": float(z_s), "z_u": float(z_u), "z_r": float(H[r, c["road"][0]]),
                "force": H[r, c["damper_force"]].copy(), "command": H[r, c["command"]].copy()}

    def _render_traces(self, window: float):
        r = self._row
        i0 = max(0, r - int(round(window / self.dt)))
        t = np.arange(i0, r) * self.dt
        return t, self._H[i0:r, self._sig_cols["sprung_acc"][0]], self._H[i0:r, self._sig_cols["damper_force"]]

