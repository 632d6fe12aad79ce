"""The quarter car's ride metrics from a record: ISO 2631-1 comfort, suspension working space, road holding (SI)."""
from __future__ import annotations

import numpy as np

from ...metrics import as_series, exceedance_share, mtvv, rms, sample_interval, vdv, weighted_acceleration
from ...validation import check_scalar


def quarter_car_metrics(dt, sprung_acc, suspension_travel, dynamic_tyre_load=None, *,
                        tyre_deflection=None, tyre_stiffness: float | None = None,
                        static_tyre_load: float | None = None, kind: str = "Wk",
                        method: str = "iir", tau: float = 1.0,
                        soft_stroke_limit: float | None = None) -> dict[str, float]:
    """Ride comfort, suspension working space and road holding of one quarter-car record.

    ``sprung_acc`` (m/s²), ``suspension_travel`` (m, from static equilibrium) and either
    ``dynamic_tyre_load`` (N, tyre force minus its static value) or ``tyre_deflection`` (m, from static)
    with ``tyre_stiffness`` (N/m) — all 1-D of the same length. Returns (floats):

    ``acc_weighted_rms`` — ISO 2631-1 ``kind``-weighted r.m.s. sprung acceleration, m/s²;
    ``acc_rms`` — unweighted r.m.s., m/s²; ``acc_vdv`` — weighted VDV, m/s^1.75;
    ``acc_mtvv`` — weighted MTVV over ``tau``, m/s²; ``travel_rms``, ``travel_peak`` — m;
    ``tyre_load_rms`` — N (if a tyre input is given); ``tyre_load_ratio`` — tyre_load_rms over
    ``static_tyre_load`` (N, > 0; if given), the road-holding index (below 1/3, a Gaussian dynamic load
    exceeds the static load — the tyre lifts off — less than 0.14 % of the time);
    ``stroke_exceedance_share`` — the share of the record's time |travel| is beyond ``soft_stroke_limit`` (m,
    > 0; if given: :func:`~mrd_env.metrics.exceedance_share`, what the environments report).
    """
    acc = as_series("sprung_acc", sprung_acc)
    n = acc.shape[0]
    travel = as_series("suspension_travel", suspension_travel, n)
    step = sample_interval(dt, n)
    a_w = weighted_acceleration(acc, step, kind, method)
    out = {
        "acc_weighted_rms": float(rms(a_w)),
        "acc_rms": float(rms(acc)),
        "acc_vdv": float(vdv(a_w, step)),
        "acc_mtvv": float(mtvv(a_w, step, tau)),
        "travel_rms": float(rms(travel)),
        "travel_peak": float(np.max(np.abs(travel))),
    }
    if soft_stroke_limit is not None:
        soft = check_scalar("soft_stroke_limit", soft_stroke_limit, 0.0, lo_open=True, unit="m")
        out["stroke_exceedance_share"] = exceedance_share(step, travel, soft)

    if dynamic_tyre_load is not None and tyre_deflection is not None:
        raise ValueError("give either dynamic_tyre_load or tyre_deflection, not both")
    if tyre_deflection is not None:
        if tyre_stiffness is None:
            raise ValueError("tyre_deflection needs tyre_stiffness (N/m, > 0)")
        k_t = check_scalar("tyre_stiffness", tyre_stiffness, 0.0, lo_open=True, unit="N/m")
        load = k_t * as_series("tyre_deflection", tyre_deflection, n)
    elif dynamic_tyre_load is not None:
        load = as_series("dynamic_tyre_load", dynamic_tyre_load, n)
    else:
        load = None
    if load is not None:
        out["tyre_load_rms"] = float(rms(load))
        if static_tyre_load is not None:
            static = check_scalar("static_tyre_load", static_tyre_load, 0.0, lo_open=True, unit="N")
            out["tyre_load_ratio"] = out["tyre_load_rms"] / static
    elif static_tyre_load is not None:
        raise ValueError("static_tyre_load needs dynamic_tyre_load or tyre_deflection")
    return out
